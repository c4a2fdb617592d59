// Checked reading of JSON documents (samples, materials, scenes, session records, calibration
// files), the JSON counterpart of common/config.h's ConfigNode. Every failure is kInvalidArgument
// "DOCUMENT: PATH: what was expected, got what":
//   samples.json: examples[3].forces[2].node: expected an integer >= 0, got -1
//   hardcopy.WrenchSample: counts[5]: expected an integer in [-2147483648, 2147483647], got 1e10
// DOCUMENT is the file name (or the record type of a message); PATH is the key path, absent for
// the document itself. nlohmann's own accessors throw on a type mismatch; readers go through
// JsonNode instead, so no exception leaves them and every message says where and what.
//
//   HC_ASSIGN_OR_RETURN(Json doc, parse_json(text, name));
//   const JsonNode root(doc, name);
//   HC_RETURN_IF_ERROR(root.only_keys({"version", "probe", "forces"}));
//   HC_RETURN_IF_ERROR(root.get("version", version, Bounds::between(1, 1)));
//   HC_RETURN_IF_ERROR(root.optional("radius_m", radius_m, Bounds::positive()));
//   HC_ASSIGN_OR_RETURN(JsonNode forces, root.member("forces"));
//   HC_RETURN_IF_ERROR(forces.expect_array(1));
//   for (std::size_t i = 0; i < forces.size(); ++i) { const JsonNode f = forces[i]; ... }
//
// Reading stops at the first problem (a JSON document is written by a program, not by hand, so
// one message is enough). A node refers to its value in the parsed document, which must outlive it.
#pragma once

#include <Eigen/Core>

#include <array>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/bounds.h"
#include "common/json.h"
#include "common/status.h"

namespace hc {

class JsonNode {
 public:
  // The root of a document that messages call `document`.
  JsonNode(const Json& root, std::string_view document);

  const Json& json() const { return *value_; }
  // "examples[3].forces"; empty for the root.
  const std::string& path() const { return path_; }
  const std::string& document() const { return *document_; }
  // kInvalidArgument "DOCUMENT: PATH: what" (or "DOCUMENT: what" at the root).
  Status error(std::string_view what) const;

  // ---- Shape ----
  Status expect_object() const;
  // An array with at least `min_size` elements.
  Status expect_array(std::size_t min_size = 0) const;
  // An array with exactly `size` elements; `what` names them in the message ("node indices").
  Status expect_array_of(std::size_t size, std::string_view what = "entries") const;

  // ---- Members (this node must be an object) ----
  // True when this is an object with member `key` (null counts as present).
  bool has(std::string_view key) const;
  // The member `key`; "missing key 'KEY'" when absent, an error when this is not an object.
  Result<JsonNode> member(std::string_view key) const;
  // The member `key`, or nullopt when it is absent or this is not an object.
  std::optional<JsonNode> find(std::string_view key) const;
  // Refuses any key not in `keys`, so that a typo ("fixed_node") is not silently ignored.
  Status only_keys(std::initializer_list<std::string_view> keys) const;
  // Every member in document order (maps keyed by name); an error when this is not an object.
  Result<std::vector<std::pair<std::string, JsonNode>>> entries() const;

  // ---- Elements (this node must be an array; check with expect_array first) ----
  std::size_t size() const { return value_->is_array() ? value_->size() : 0; }
  // Element i < size().
  JsonNode operator[](std::size_t i) const;

  // ---- This node as a value ----
  // A finite number within `bounds`.
  Result<double> number(const Bounds& bounds = {}) const;
  // A number, or null read as NaN: how a writer that stores non-finite values as null
  // (finite_or_null, common/json.h) records a measurement that was not finite.
  Result<double> number_or_null() const;
  // A JSON integer (not 1.0) within T's limits and `bounds`.
  template <std::integral T>
  requires(!std::same_as<T, bool>) Result<T> integer(const Bounds& bounds = {})
  const {
    HC_ASSIGN_OR_RETURN(const Whole w, whole());
    const Bounds limits = integer_bounds<T>(bounds);
    const bool fits = w.negative ? std::in_range<T>(w.value) : std::in_range<T>(w.magnitude);
    if (!fits || !limits.contains(w.as_double())) return out_of_range(limits);
    return w.negative ? static_cast<T>(w.value) : static_cast<T>(w.magnitude);
  }
  // An index into something with `count` entries: an integer in [0, count).
  Result<std::size_t> index(std::size_t count) const;
  Result<bool> boolean() const;
  Result<std::string> string() const;
  // One of `choices`.
  Result<std::string> string(std::initializer_list<std::string_view> choices) const;
  // An array of exactly N finite numbers.
  template <int N>
  Result<Eigen::Matrix<double, N, 1>> vector() const {
    HC_RETURN_IF_ERROR(numbers_of_size(N));
    Eigen::Matrix<double, N, 1> v;
    for (int i = 0; i < N; ++i)
      v(i) = (*value_)[static_cast<std::size_t>(i)].template get<double>();
    return v;
  }
  // An array of finite numbers (any length).
  Result<std::vector<double>> numbers() const;

  // ---- Typed reading: read(out, args...) reads this node into `out` (untouched on failure) ----
  Status read(double& out, const Bounds& bounds = {}) const;
  template <std::integral T>
  requires(!std::same_as<T, bool>) Status read(T& out, const Bounds& bounds = {})
  const {
    HC_ASSIGN_OR_RETURN(out, integer<T>(bounds));
    return {};
  }
  Status read(bool& out) const;
  Status read(std::string& out) const;
  Status read(std::string& out, std::initializer_list<std::string_view> choices) const;
  template <int N>
  Status read(Eigen::Matrix<double, N, 1>& out) const {
    HC_ASSIGN_OR_RETURN(out, vector<N>());
    return {};
  }
  // An array of exactly N elements, each read with read(element, args...).
  template <typename T, std::size_t N, typename... Args>
  Status read(std::array<T, N>& out, const Args&... args) const {
    HC_RETURN_IF_ERROR(expect_array_of(N));
    std::array<T, N> values = out;
    for (std::size_t i = 0; i < N; ++i) HC_RETURN_IF_ERROR((*this)[i].read(values[i], args...));
    out = std::move(values);
    return {};
  }
  // An array; each element read with read(element, args...).
  template <typename T, typename... Args>
  Status read(std::vector<T>& out, const Args&... args) const {
    HC_RETURN_IF_ERROR(expect_array());
    std::vector<T> values(size());
    for (std::size_t i = 0; i < values.size(); ++i)
      HC_RETURN_IF_ERROR((*this)[i].read(values[i], args...));
    out = std::move(values);
    return {};
  }
  // A value that may be null: nullopt then.
  template <typename T, typename... Args>
  Status read(std::optional<T>& out, const Args&... args) const {
    if (value_->is_null()) {
      out.reset();
      return {};
    }
    T value{};
    HC_RETURN_IF_ERROR(read(value, args...));
    out = std::move(value);
    return {};
  }

  // The member `key` read into `out` with read(out, args...); a missing key is an error.
  template <typename T, typename... Args>
  Status get(std::string_view key, T& out, const Args&... args) const {
    HC_ASSIGN_OR_RETURN(const JsonNode m, member(key));
    return m.read(out, args...);
  }
  // As get(), but an absent or null member leaves `out` (its default) untouched.
  template <typename T, typename... Args>
  Status optional(std::string_view key, T& out, const Args&... args) const {
    const std::optional<JsonNode> m = find(key);
    if (!m || m->json().is_null()) return {};
    return m->read(out, args...);
  }
  Status get(std::string_view key, std::string& out,
             std::initializer_list<std::string_view> choices) const;
  Status optional(std::string_view key, std::string& out,
                  std::initializer_list<std::string_view> choices) const;

 private:
  JsonNode(const Json& value, std::shared_ptr<const std::string> document, std::string path)
      : value_(&value), document_(std::move(document)), path_(std::move(path)) {}
  // A JSON integer as sign and magnitude (uint64 values above int64's range stay exact).
  struct Whole {
    bool negative = false;
    std::int64_t value = 0;       // when negative
    std::uint64_t magnitude = 0;  // when not negative
    double as_double() const {
      return negative ? static_cast<double>(value) : static_cast<double>(magnitude);
    }
  };
  Result<Whole> whole() const;
  Status out_of_range(const Bounds& limits) const;
  Status numbers_of_size(std::size_t n) const;
  // `b` narrowed to T's own limits (unsigned: >= 0; narrower than 64 bits: its range).
  template <std::integral T>
  static Bounds integer_bounds(Bounds b) {
    using Limits = std::numeric_limits<T>;
    if constexpr (std::is_unsigned_v<T> || sizeof(T) < sizeof(std::int64_t)) {
      const auto lo = static_cast<double>(Limits::min());
      if (!b.min || *b.min < lo) b = Bounds{lo, b.max, false, b.max_exclusive};
    }
    if constexpr (sizeof(T) < sizeof(std::int64_t)) {
      const auto hi = static_cast<double>(Limits::max());
      if (!b.max || *b.max > hi) b = Bounds{b.min, hi, b.min_exclusive, false};
    }
    return b;
  }

  const Json* value_;
  std::shared_ptr<const std::string> document_;
  std::string path_;
};

// "null", "true", "3.5", "\"fast\"", "an array", "an object": a value as messages quote it.
std::string describe_json(const Json& value);

}  // namespace hc
