// YAML configuration files read into Options structs, with every problem in a file reported at
// once, each naming the file, the line and the full key path:
//   rig.yaml:12: cameras[2].exposure_s: expected a number > 0, got 'fast'
//   rig.yaml:14: cameras[2]: unknown key 'exposre_s' (did you mean 'exposure_s'?)
//
// A struct becomes readable by giving it `hc::Status read(hc::ConfigNode node)`:
//
//   struct CameraOptions {
//     std::string name;
//     double exposure_s = 0.01;
//     Trigger trigger = Trigger::kHardware;
//     std::array<double, 3> position_m{};
//     hc::Status read(hc::ConfigNode node) {
//       node.required("name", name);
//       node.optional("exposure_s", exposure_s, hc::Bounds::positive());
//       node.optional("trigger", trigger, {{"hardware", Trigger::kHardware},
//                                          {"software", Trigger::kSoftware}});
//       node.optional("position_m", position_m);
//       return node.status();
//     }
//   };
//   struct RigOptions {
//     std::vector<CameraOptions> cameras;
//     hc::Status read(hc::ConfigNode node) {
//       node.required("cameras", cameras);
//       return node.status();
//     }
//   };
//
//   HC_ASSIGN_OR_RETURN(hc::Config config, hc::load_config("rig.yaml"));
//   HC_ASSIGN_OR_RETURN(RigOptions rig, hc::read_config<RigOptions>(config));
//
// Getters record problems and carry on, so one run reports them all; a getter returns true when it
// stored a value. After reading, every key of a map that no getter asked for is reported as
// unknown (unless allow_unknown_keys()). If the struct also has `Status validate() const`, it runs
// after a clean read and its message is reported at the struct's line. yaml-cpp's exceptions never
// leave this library.
#pragma once

#include <array>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/bounds.h"
#include "common/status.h"

namespace hc {

namespace detail {
struct ConfigDocument;
struct ConfigContext;
struct ConfigNodeState;
}  // namespace detail

class ConfigNode;

// Configs are hand-written and small; anything bigger is a mistake (or an attack on the parser).
inline constexpr std::size_t kMaxConfigBytes = std::size_t{16} << 20;  // 16 MiB

// A parsed YAML document and the name its messages use (the path, or what the caller chose).
class Config {
 public:
  // The file name (or the caller's name for the text) that starts every message.
  const std::string& name() const;

 private:
  friend Result<Config> parse_config(std::string_view text, std::string_view name);
  friend Status read_config(const Config& config, const std::function<Status(ConfigNode)>&);
  explicit Config(std::shared_ptr<const detail::ConfigDocument> doc) : doc_(std::move(doc)) {}
  std::shared_ptr<const detail::ConfigDocument> doc_;
};

// Parses one YAML document. An empty text is a valid, empty config (every key takes its default).
// Fails with kInvalidArgument "NAME:LINE: invalid YAML: ..." on a syntax error, or when the text
// holds more than one document.
Result<Config> parse_config(std::string_view text, std::string_view name);

// Reads and parses the file; messages name it by `path`. Fails with kNotFound, kIoError, or
// kInvalidArgument (syntax, or larger than kMaxConfigBytes).
Result<Config> load_config(const std::filesystem::path& path);

// One allowed spelling of an enum value.
template <typename E>
struct Choice {
  std::string_view name;
  E value;
};

namespace detail {
// Integers read through int64 and then checked against the type's own limits.
template <typename T>
concept NarrowedInteger =
    std::integral<T> && !std::same_as<T, bool> && !std::same_as<T, std::int64_t>;
}  // namespace detail

// A type a ConfigNode can read by calling its `Status read(ConfigNode)`.
template <typename T>
concept ConfigReadable = requires(T& t, ConfigNode node) {
  { t.read(node) } -> std::same_as<Status>;
};

// One place in a document (a map, a sequence, a scalar or an empty value) with its key path.
// Cheap to copy; copies share what was read, so a node may be passed by value.
class ConfigNode {
 public:
  // ---- Members of this node as a map. A null (empty) node acts as an empty map. ----

  // Reads the member `key` into `out` with get(out, args...); a missing key is an error.
  template <typename T, typename... Args>
  bool required(std::string_view key, T& out, const Args&... args) {
    std::optional<ConfigNode> value = find(key);
    if (!value) {
      missing(key);
      return false;
    }
    return value->get(out, args...);
  }
  // As required(), but a missing key leaves `out` (its default) untouched and returns false.
  template <typename T, typename... Args>
  bool optional(std::string_view key, T& out, const Args&... args) {
    std::optional<ConfigNode> value = find(key);
    return value && value->get(out, args...);
  }
  // String and enum choices (braced lists cannot pass through the templates above).
  bool required(std::string_view key, std::string& out,
                std::initializer_list<std::string_view> choices);
  bool optional(std::string_view key, std::string& out,
                std::initializer_list<std::string_view> choices);
  template <typename E>
  requires std::is_enum_v<E>
  bool required(std::string_view key, E& out, std::initializer_list<Choice<E>> choices) {
    std::optional<ConfigNode> value = find(key);
    if (!value) {
      missing(key);
      return false;
    }
    return value->get(out, choices);
  }
  template <typename E>
  requires std::is_enum_v<E>
  bool optional(std::string_view key, E& out, std::initializer_list<Choice<E>> choices) {
    std::optional<ConfigNode> value = find(key);
    return value && value->get(out, choices);
  }

  // True when the map has `key`. Asking counts as knowing the key (it is not reported unknown).
  bool has(std::string_view key);
  // The member `key`, or nullopt when absent. Records an error if this node is not a map.
  std::optional<ConfigNode> find(std::string_view key);
  // Every member in file order, for maps keyed by name (devices, materials). All keys are known.
  // nullopt (error recorded) when this node is not a map.
  std::optional<std::vector<std::pair<std::string, ConfigNode>>> entries();
  // Every element of this node as a sequence (a null node is an empty one); nullopt (error
  // recorded) when it is not a sequence.
  std::optional<std::vector<ConfigNode>> elements();

  // ---- This node as a value. On failure `out` keeps its value and an error is recorded. ----

  // A finite number within `bounds`.
  bool get(double& out, const Bounds& bounds = {});
  // A decimal (or 0x hexadecimal) integer within `bounds`.
  bool get(std::int64_t& out, const Bounds& bounds = {});
  // int, std::uint16_t, std::size_t, ...: also within the type's own limits.
  template <detail::NarrowedInteger T>
  bool get(T& out, const Bounds& bounds = {}) {
    std::int64_t value = 0;
    if (!get(value, within_limits_of<T>(bounds))) return false;
    out = static_cast<T>(value);
    return true;
  }
  // true/false (also yes/no and on/off, as YAML 1.1 and yaml-cpp spell them).
  bool get(bool& out);
  // Any scalar, as written.
  bool get(std::string& out);
  bool get(std::string& out, std::initializer_list<std::string_view> choices);
  template <typename E>
  requires std::is_enum_v<E>
  bool get(E& out, std::initializer_list<Choice<E>> choices) {
    std::vector<std::string_view> names;
    for (const Choice<E>& c : choices) names.push_back(c.name);
    const std::optional<std::size_t> index = choose(names);
    if (!index) return false;
    out = (choices.begin() + *index)->value;
    return true;
  }
  // A sequence; every element is read with get(element, args...).
  template <typename T, typename... Args>
  bool get(std::vector<T>& out, const Args&... args) {
    std::optional<std::vector<ConfigNode>> items = elements();
    if (!items) return false;
    std::vector<T> values(items->size());
    bool ok = true;
    for (std::size_t i = 0; i < values.size(); ++i) ok = (*items)[i].get(values[i], args...) && ok;
    if (ok) out = std::move(values);
    return ok;
  }
  // A sequence of exactly N elements (a position [x, y, z], a 3x3 matrix row).
  template <typename T, std::size_t N, typename... Args>
  bool get(std::array<T, N>& out, const Args&... args) {
    std::optional<std::vector<ConfigNode>> items = elements();
    if (!items) return false;
    if (items->size() != N) {
      wrong_size(N, items->size());
      return false;
    }
    std::array<T, N> values = out;
    bool ok = true;
    for (std::size_t i = 0; i < N; ++i) ok = (*items)[i].get(values[i], args...) && ok;
    if (ok) out = std::move(values);
    return ok;
  }
  // A value that may be absent: optional("gain", gain) leaves an empty std::optional when the
  // key is missing.
  template <typename T, typename... Args>
  bool get(std::optional<T>& out, const Args&... args) {
    T value{};
    if (!get(value, args...)) return false;
    out = std::move(value);
    return true;
  }
  // A map from names to values, in key order.
  template <typename T, typename... Args>
  bool get(std::map<std::string, T>& out, const Args&... args) {
    auto items = entries();
    if (!items) return false;
    std::map<std::string, T> values;
    bool ok = true;
    for (auto& [key, node] : *items) ok = node.get(values[key], args...) && ok;
    if (ok) out = std::move(values);
    return ok;
  }
  // A nested struct: calls out.read(*this), then out.validate() if it has one and the read was
  // clean. On failure `out` may be partly filled.
  template <ConfigReadable T>
  bool get(T& out) {
    const std::size_t before = begin_struct();
    Status status = out.read(*this);
    if (!end_struct(before, status)) return false;
    if constexpr (requires(const T& t) {
                    { t.validate() } -> std::same_as<Status>;
                  }) {
      return end_struct(before, out.validate());
    }
    return true;
  }

  // ---- Errors and bookkeeping ----

  // Records "FILE:LINE: PATH: message" at this node.
  void error(std::string_view message);
  // Records the error at member `key` (its line if present, else this node's), e.g. for checks
  // that involve several keys: node.error("max_n", "must be greater than min_n").
  void error(std::string_view key, std::string_view message);
  // This map holds free-form keys (metadata): none is reported unknown.
  void allow_unknown_keys();

  // "cameras[2].exposure_s"; empty for the document root.
  std::string path() const;
  // 1-based line in the file; 0 when unknown.
  std::size_t line() const;
  // OK when nothing below this node has failed so far; otherwise kInvalidArgument with the first
  // message. The usual return value of a read().
  Status status() const;

 private:
  friend Status read_config(const Config& config, const std::function<Status(ConfigNode)>&);
  ConfigNode(std::shared_ptr<detail::ConfigContext> context,
             std::shared_ptr<detail::ConfigNodeState> state)
      : context_(std::move(context)), state_(std::move(state)) {}

  // Adds T's own limits where they are tighter than int64's (unsigned: >= 0; int: 32 bits), so
  // that a value which would not fit is an error, never a silent wrap.
  template <std::integral T>
  static Bounds within_limits_of(Bounds bounds) {
    using Limits = std::numeric_limits<T>;
    using Int64Limits = std::numeric_limits<std::int64_t>;
    if (std::cmp_greater(Limits::min(), Int64Limits::min())) {
      const auto lo = static_cast<double>(Limits::min());
      if (!bounds.min || *bounds.min < lo) {
        bounds.min = lo;
        bounds.min_exclusive = false;
      }
    }
    if (std::cmp_less(Limits::max(), Int64Limits::max())) {
      const auto hi = static_cast<double>(Limits::max());
      if (!bounds.max || *bounds.max > hi) {
        bounds.max = hi;
        bounds.max_exclusive = false;
      }
    }
    return bounds;
  }

  void missing(std::string_view key);
  void wrong_size(std::size_t expected, std::size_t got);
  // False (error recorded once) when reading the children would pass the depth or work limits.
  bool can_descend(std::size_t children);
  std::optional<std::size_t> choose(std::span<const std::string_view> names);
  std::size_t begin_struct();
  bool end_struct(std::size_t errors_before, const Status& status);

  std::shared_ptr<detail::ConfigContext> context_;
  std::shared_ptr<detail::ConfigNodeState> state_;
};

// Runs `read` on the document's root, then reports unknown keys. Returns OK, or kInvalidArgument
// listing every problem, one "FILE:LINE: PATH: what" per line, in line order (the first 50).
// Reading stops with an error past 64 levels of nesting or about a million values, since aliases
// can make a small file stand for a huge tree. Read one Config from one thread at a time: yaml-cpp
// does not promise that concurrent reads of a document are safe.
Status read_config(const Config& config, const std::function<Status(ConfigNode)>& read);

// Reads the whole document into `out` (see ConfigNode::get for structs).
template <ConfigReadable T>
Status read_config(const Config& config, T& out) {
  return read_config(config, [&out](ConfigNode root) {
    root.get(out);
    return Status{};  // problems are already recorded in the reader
  });
}

// As above, into a default-constructed T.
template <ConfigReadable T>
Result<T> read_config(const Config& config) {
  T out{};
  HC_RETURN_IF_ERROR(read_config(config, out));
  return out;
}

}  // namespace hc
