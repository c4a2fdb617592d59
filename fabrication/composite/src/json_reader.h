// Checked access to JSON for the composite readers (base material, library, design): every error
// names the document, the key path ("materials[2].file") and what was expected. nlohmann's own
// accessors throw, so the readers go through these. (processing/material keeps a private reader of
// the same kind; the rooms issue merges them into one checked-JSON reader in common/.)
#pragma once

#include <fmt/format.h>

#include <Eigen/Core>
#include <cmath>
#include <initializer_list>
#include <string>
#include <string_view>

#include "common/json.h"
#include "common/status.h"

namespace hc::composite::detail {

inline std::string key_path(std::string_view path, std::string_view key) {
  return path.empty() ? std::string(key) : fmt::format("{}.{}", path, key);
}
inline std::string item_path(std::string_view path, std::size_t i) {
  return fmt::format("{}[{}]", path, i);
}

class JsonReader {
 public:
  explicit JsonReader(std::string_view name) : name_(name) {}

  Status error(std::string_view path, std::string_view what) const {
    return invalid_argument(fmt::format("{}: {}: {}", name_, path.empty() ? "<root>" : path, what));
  }
  Status object(const Json& j, std::string_view path) const {
    if (!j.is_object()) return error(path, fmt::format("expected an object, got {}", j.type_name()));
    return {};
  }
  Status array(const Json& j, std::string_view path, std::size_t min_size = 0) const {
    if (!j.is_array()) return error(path, fmt::format("expected an array, got {}", j.type_name()));
    if (j.size() < min_size)
      return error(path, fmt::format("expected at least {} entries, got {}", min_size, j.size()));
    return {};
  }
  Result<const Json*> member(const Json& j, std::string_view path, std::string_view key) const {
    HC_RETURN_IF_ERROR(object(j, path));
    const auto it = j.find(key);
    if (it == j.end()) return error(path, fmt::format("missing key '{}'", key));
    return &*it;
  }
  const Json* optional(const Json& j, std::string_view key) const {
    if (!j.is_object()) return nullptr;
    const auto it = j.find(key);
    return it == j.end() ? nullptr : &*it;
  }
  // Unknown keys are refused so that a typo is not silently ignored.
  Status only_keys(const Json& j, std::string_view path,
                   std::initializer_list<std::string_view> keys) const {
    for (auto it = j.begin(); it != j.end(); ++it) {
      bool known = false;
      for (std::string_view k : keys) known = known || it.key() == k;
      if (!known) return error(path, fmt::format("unknown key '{}'", it.key()));
    }
    return {};
  }
  Status number(const Json& j, std::string_view path, double* out) const {
    if (!j.is_number()) return error(path, fmt::format("expected a number, got {}", j.type_name()));
    const double v = j.get<double>();
    if (!std::isfinite(v)) return error(path, "expected a finite number");
    *out = v;
    return {};
  }
  Status integer(const Json& j, std::string_view path, long long lo, long long hi,
                 long long* out) const {
    if (!j.is_number_integer())
      return error(path, fmt::format("expected an integer, got {}", j.type_name()));
    if (j.is_number_unsigned() && j.get<unsigned long long>() > static_cast<unsigned long long>(hi))
      return error(path, fmt::format("{} is out of range [{}, {}]", j.get<unsigned long long>(), lo, hi));
    const long long v = j.get<long long>();
    if (v < lo || v > hi) return error(path, fmt::format("{} is out of range [{}, {}]", v, lo, hi));
    *out = v;
    return {};
  }
  Status string(const Json& j, std::string_view path, std::string* out) const {
    if (!j.is_string()) return error(path, fmt::format("expected a string, got {}", j.type_name()));
    *out = j.get<std::string>();
    return {};
  }
  // An array of `rows` arrays (rows >= min_rows) of exactly `cols` finite numbers.
  Status matrix(const Json& j, std::string_view path, Eigen::Index cols, std::size_t min_rows,
                Eigen::MatrixXd* out) const {
    HC_RETURN_IF_ERROR(array(j, path, min_rows));
    out->resize(static_cast<Eigen::Index>(j.size()), cols);
    for (std::size_t r = 0; r < j.size(); ++r) {
      const std::string rp = item_path(path, r);
      if (!j[r].is_array() || j[r].size() != static_cast<std::size_t>(cols))
        return error(rp, fmt::format("expected an array of {} numbers", cols));
      for (Eigen::Index c = 0; c < cols; ++c)
        HC_RETURN_IF_ERROR(number(j[r][static_cast<std::size_t>(c)],
                                  item_path(rp, static_cast<std::size_t>(c)),
                                  &(*out)(static_cast<Eigen::Index>(r), c)));
    }
    return {};
  }
  // Checks "format" and "version".
  Status header(const Json& j, std::string_view format, int version) const {
    HC_ASSIGN_OR_RETURN(const Json* f, member(j, "", "format"));
    std::string fs;
    HC_RETURN_IF_ERROR(string(*f, "format", &fs));
    if (fs != format) return error("format", fmt::format("expected \"{}\", got \"{}\"", format, fs));
    HC_ASSIGN_OR_RETURN(const Json* v, member(j, "", "version"));
    long long vi = 0;
    HC_RETURN_IF_ERROR(integer(*v, "version", 0, 1 << 20, &vi));
    if (vi != version)
      return error("version", fmt::format("unsupported version {} (this build reads {})", vi, version));
    return {};
  }

 private:
  std::string name_;
};

}  // namespace hc::composite::detail
