#include "common/json_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace hc {

namespace {

constexpr std::size_t kMaxQuotedJsonChars = 40;

std::string member_path(const std::string& path, std::string_view key) {
  if (path.empty()) return std::string(key);
  std::string p;
  p.reserve(path.size() + key.size() + 1);
  p += path;
  p += '.';
  p += key;
  return p;
}

std::string element_path(const std::string& path, std::size_t i) {
  return fmt::format("{}[{}]", path, i);
}

}  // namespace

std::string describe_json(const Json& v) {
  switch (v.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::boolean:
      return v.get<bool>() ? "true" : "false";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
    case Json::value_t::number_float:
      return v.dump();
    case Json::value_t::string: {
      const std::string& s = v.get_ref<const std::string&>();
      if (s.size() <= kMaxQuotedJsonChars)
        return Json(s).dump(-1, ' ', false, Json::error_handler_t::replace);
      return Json(s.substr(0, kMaxQuotedJsonChars) + "...")
          .dump(-1, ' ', false, Json::error_handler_t::replace);
    }
    case Json::value_t::array:
      return "an array";
    case Json::value_t::object:
      return "an object";
    default:
      return v.type_name();
  }
}

JsonNode::JsonNode(const Json& root, std::string_view document)
    : value_(&root), document_(std::make_shared<const std::string>(document)) {}

Status JsonNode::error(std::string_view what) const {
  if (path_.empty()) return invalid_argument(fmt::format("{}: {}", *document_, what));
  return invalid_argument(fmt::format("{}: {}: {}", *document_, path_, what));
}

Status JsonNode::expect_object() const {
  if (!value_->is_object())
    return error(fmt::format("expected an object, got {}", describe_json(*value_)));
  return {};
}

Status JsonNode::expect_array(std::size_t min_size) const {
  if (!value_->is_array())
    return error(fmt::format("expected an array, got {}", describe_json(*value_)));
  if (value_->size() < min_size)
    return error(fmt::format("expected at least {} entries, got {}", min_size, value_->size()));
  return {};
}

Status JsonNode::expect_array_of(std::size_t n, std::string_view what) const {
  if (!value_->is_array())
    return error(
        fmt::format("expected an array of {} {}, got {}", n, what, describe_json(*value_)));
  if (value_->size() != n)
    return error(fmt::format("expected an array of {} {}, got {}", n, what, value_->size()));
  return {};
}

bool JsonNode::has(std::string_view key) const {
  return value_->is_object() && value_->find(key) != value_->end();
}

Result<JsonNode> JsonNode::member(std::string_view key) const {
  HC_RETURN_IF_ERROR(expect_object());
  const auto it = value_->find(key);
  if (it == value_->end()) return error(fmt::format("missing key '{}'", key));
  return JsonNode(*it, document_, member_path(path_, key));
}

std::optional<JsonNode> JsonNode::find(std::string_view key) const {
  if (!value_->is_object()) return std::nullopt;
  const auto it = value_->find(key);
  if (it == value_->end()) return std::nullopt;
  return JsonNode(*it, document_, member_path(path_, key));
}

Status JsonNode::only_keys(std::initializer_list<std::string_view> keys) const {
  HC_RETURN_IF_ERROR(expect_object());
  for (auto it = value_->begin(); it != value_->end(); ++it)
    if (std::find(keys.begin(), keys.end(), it.key()) == keys.end())
      return error(fmt::format("unknown key '{}'", it.key()));
  return {};
}

Result<std::vector<std::pair<std::string, JsonNode>>> JsonNode::entries() const {
  HC_RETURN_IF_ERROR(expect_object());
  std::vector<std::pair<std::string, JsonNode>> out;
  out.reserve(value_->size());
  for (auto it = value_->begin(); it != value_->end(); ++it)
    out.emplace_back(it.key(), JsonNode(it.value(), document_, member_path(path_, it.key())));
  return out;
}

JsonNode JsonNode::operator[](std::size_t i) const {
  return JsonNode((*value_)[i], document_, element_path(path_, i));
}

Result<double> JsonNode::number(const Bounds& bounds) const {
  if (!value_->is_number())
    return error(
        fmt::format("expected {}, got {}", bounds.describe("a number"), describe_json(*value_)));
  const double v = value_->get<double>();
  if (!std::isfinite(v)) return error("expected a finite number");
  if (!bounds.contains(v))
    return error(fmt::format("expected {}, got {}", bounds.describe("a number"), v));
  return v;
}

Result<double> JsonNode::number_or_null() const {
  if (value_->is_null()) return std::numeric_limits<double>::quiet_NaN();
  if (!value_->is_number())
    return error(fmt::format("expected a number or null, got {}", describe_json(*value_)));
  return value_->get<double>();
}

Result<JsonNode::Whole> JsonNode::whole() const {
  Whole w;
  if (value_->is_number_unsigned()) {
    w.magnitude = value_->get<std::uint64_t>();
  } else if (value_->is_number_integer()) {
    const auto v = value_->get<std::int64_t>();
    w.negative = v < 0;
    if (w.negative)
      w.value = v;
    else
      w.magnitude = static_cast<std::uint64_t>(v);
  } else {
    return error(fmt::format("expected an integer, got {}", describe_json(*value_)));
  }
  return w;
}

Status JsonNode::out_of_range(const Bounds& limits) const {
  return error(
      fmt::format("expected {}, got {}", limits.describe("an integer"), describe_json(*value_)));
}

Result<std::size_t> JsonNode::index(std::size_t count) const {
  HC_ASSIGN_OR_RETURN(const Whole w, whole());
  if (w.negative) return error(fmt::format("index {} is negative", w.value));
  if (w.magnitude >= count)
    return error(fmt::format("index {} is out of range (there are {})", w.magnitude, count));
  return static_cast<std::size_t>(w.magnitude);
}

Result<bool> JsonNode::boolean() const {
  if (!value_->is_boolean())
    return error(fmt::format("expected true or false, got {}", describe_json(*value_)));
  return value_->get<bool>();
}

Result<std::string> JsonNode::string() const {
  if (!value_->is_string())
    return error(fmt::format("expected a string, got {}", describe_json(*value_)));
  return value_->get<std::string>();
}

Result<std::string> JsonNode::string(std::initializer_list<std::string_view> choices) const {
  std::string names;
  for (std::string_view c : choices) names += fmt::format("{}\"{}\"", names.empty() ? "" : ", ", c);
  if (!value_->is_string())
    return error(fmt::format("expected one of {}, got {}", names, describe_json(*value_)));
  const std::string& s = value_->get_ref<const std::string&>();
  if (std::find(choices.begin(), choices.end(), s) == choices.end())
    return error(fmt::format("expected one of {}, got {}", names, describe_json(*value_)));
  return s;
}

Status JsonNode::numbers_of_size(std::size_t n) const {
  HC_RETURN_IF_ERROR(expect_array_of(n, "numbers"));
  for (std::size_t i = 0; i < n; ++i) {
    const Json& v = (*value_)[i];
    if (!v.is_number() || !std::isfinite(v.get<double>())) return (*this)[i].number().status();
  }
  return {};
}

Result<std::vector<double>> JsonNode::numbers() const {
  HC_RETURN_IF_ERROR(expect_array());
  std::vector<double> out;
  out.reserve(value_->size());
  for (std::size_t i = 0; i < value_->size(); ++i) {
    const Json& v = (*value_)[i];
    if (!v.is_number() || !std::isfinite(v.get<double>())) return (*this)[i].number().status();
    out.push_back(v.get<double>());
  }
  return out;
}

Status JsonNode::read(double& out, const Bounds& bounds) const {
  HC_ASSIGN_OR_RETURN(out, number(bounds));
  return {};
}

Status JsonNode::read(bool& out) const {
  HC_ASSIGN_OR_RETURN(out, boolean());
  return {};
}

Status JsonNode::read(std::string& out) const {
  HC_ASSIGN_OR_RETURN(out, string());
  return {};
}

Status JsonNode::read(std::string& out, std::initializer_list<std::string_view> choices) const {
  HC_ASSIGN_OR_RETURN(out, string(choices));
  return {};
}

Status JsonNode::get(std::string_view key, std::string& out,
                     std::initializer_list<std::string_view> choices) const {
  HC_ASSIGN_OR_RETURN(const JsonNode m, member(key));
  return m.read(out, choices);
}

Status JsonNode::optional(std::string_view key, std::string& out,
                          std::initializer_list<std::string_view> choices) const {
  const std::optional<JsonNode> m = find(key);
  if (!m || m->json().is_null()) return {};
  return m->read(out, choices);
}

}  // namespace hc
