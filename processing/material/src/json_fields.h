// Checked access to JSON fields for the samples and material readers: every getter names the key
// path ("examples[3].forces[2].node") and what was expected. nlohmann's own accessors throw, so the
// readers go through these instead.
#pragma once

#include <fmt/format.h>

#include <Eigen/Core>
#include <limits>
#include <string>
#include <string_view>

#include "common/json.h"
#include "common/status.h"

namespace hc::material::detail {

inline std::string type_name(const Json& j) { return j.type_name(); }

inline std::string join(std::string_view path, std::string_view key) {
  return path.empty() ? std::string(key) : fmt::format("{}.{}", path, key);
}
inline std::string index(std::string_view path, std::size_t i) {
  return fmt::format("{}[{}]", path, i);
}

// Prefixes messages with the document name.
class FieldReader {
 public:
  explicit FieldReader(std::string_view name) : name_(name) {}

  Status error(std::string_view path, std::string_view what) const {
    return invalid_argument(fmt::format("{}: {}: {}", name_, path.empty() ? "<root>" : path, what));
  }

  Status object(const Json& j, std::string_view path) const {
    if (!j.is_object()) return error(path, fmt::format("expected an object, got {}", type_name(j)));
    return {};
  }
  Status array(const Json& j, std::string_view path, std::size_t min_size = 0) const {
    if (!j.is_array()) return error(path, fmt::format("expected an array, got {}", type_name(j)));
    if (j.size() < min_size)
      return error(path, fmt::format("expected at least {} entries, got {}", min_size, j.size()));
    return {};
  }
  // The member `key` of object `j` (which must be an object), or an error when it is missing.
  Result<const Json*> member(const Json& j, std::string_view path, std::string_view key) const {
    HC_RETURN_IF_ERROR(object(j, path));
    auto it = j.find(key);
    if (it == j.end()) return error(path, fmt::format("missing key '{}'", key));
    return &*it;
  }
  // nullptr when absent.
  const Json* optional(const Json& j, std::string_view key) const {
    if (!j.is_object()) return nullptr;
    auto it = j.find(key);
    return it == j.end() ? nullptr : &*it;
  }
  // Unknown keys are refused so that a typo ("fixed_node") is not silently ignored.
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
    if (!j.is_number())
      return error(path, fmt::format("expected a finite number, got {}", type_name(j)));
    const double v = j.get<double>();
    if (!std::isfinite(v)) return error(path, "expected a finite number");
    *out = v;
    return {};
  }
  Status integer(const Json& j, std::string_view path, long long lo, long long hi,
                 long long* out) const {
    if (!j.is_number_integer())
      return error(path, fmt::format("expected an integer, got {}", type_name(j)));
    const long long v =
        j.is_number_unsigned()
            ? (j.get<unsigned long long>() >
                       static_cast<unsigned long long>(std::numeric_limits<long long>::max())
                   ? std::numeric_limits<long long>::max()
                   : static_cast<long long>(j.get<unsigned long long>()))
            : j.get<long long>();
    if (v < lo || v > hi) return error(path, fmt::format("{} is out of range [{}, {}]", v, lo, hi));
    *out = v;
    return {};
  }
  Status index_in(const Json& j, std::string_view path, long long count, int* out) const {
    long long v = 0;
    if (!j.is_number_integer())
      return error(path, fmt::format("expected a node index, got {}", type_name(j)));
    if (j.is_number_unsigned() || j.get<long long>() >= 0) {
      if (j.get<unsigned long long>() >= static_cast<unsigned long long>(count))
        return error(path, fmt::format("{} is out of range (mesh has {} nodes)",
                                       j.get<unsigned long long>(), count));
      v = j.get<long long>();
    } else {
      return error(path, fmt::format("{} is negative", j.get<long long>()));
    }
    *out = static_cast<int>(v);
    return {};
  }
  Status string(const Json& j, std::string_view path, std::string* out) const {
    if (!j.is_string()) return error(path, fmt::format("expected a string, got {}", type_name(j)));
    *out = j.get<std::string>();
    return {};
  }
  template <int N>
  Status vector(const Json& j, std::string_view path, Eigen::Matrix<double, N, 1>* out) const {
    if (!j.is_array() || j.size() != static_cast<std::size_t>(N))
      return error(path, fmt::format("expected an array of {} numbers", N));
    for (int i = 0; i < N; ++i)
      HC_RETURN_IF_ERROR(number(j[static_cast<std::size_t>(i)],
                                index(path, static_cast<std::size_t>(i)), &(*out)(i)));
    return {};
  }

 private:
  std::string name_;
};

}  // namespace hc::material::detail
