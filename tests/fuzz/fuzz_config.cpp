// libFuzzer target for the configuration and JSON readers: arbitrary bytes are parsed as a YAML
// config and read through a schema that uses every kind of getter (a recursive one, to exercise
// the depth and size limits against aliases), walked generically, and parsed (then printed) as
// JSON. Errors are the expected outcome; crashes, hangs, leaks and sanitizer reports are bugs.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/config.h"
#include "common/json.h"

namespace {

enum class Mode { kSim, kReal, kReplay };

struct Part {
  std::string name;
  double weight_kg = 1.0;
  std::int64_t count = 0;
  std::uint16_t port = 0;
  int level = 0;
  bool enabled = true;
  Mode mode = Mode::kSim;
  std::string kind = "box";
  std::array<double, 3> position_m{};
  std::vector<double> values;
  std::vector<std::string> tags;
  std::optional<double> gain;
  std::map<std::string, std::int64_t> ids;
  std::vector<Part> children;

  hc::Status read(hc::ConfigNode node) {
    node.required("name", name);
    node.optional("weight_kg", weight_kg, hc::Bounds::positive());
    node.optional("count", count, hc::Bounds::non_negative());
    node.optional("port", port);
    node.optional("level", level, hc::Bounds::between(-5, 5));
    node.optional("enabled", enabled);
    node.optional("mode", mode,
                  {{"sim", Mode::kSim}, {"real", Mode::kReal}, {"replay", Mode::kReplay}});
    node.optional("kind", kind, {"box", "sphere", "mesh"});
    node.optional("position_m", position_m);
    node.optional("values", values, hc::Bounds::between(-1e3, 1e3));
    node.optional("tags", tags);
    node.optional("gain", gain);
    node.optional("ids", ids);
    node.optional("children", children);
    if (std::optional<hc::ConfigNode> meta = node.find("meta")) meta->allow_unknown_keys();
    if (node.has("min") && node.has("max")) {
      double lo = 0, hi = 0;
      if (node.required("min", lo) && node.required("max", hi) && hi < lo)
        node.error("max", "must not be less than min");
    }
    return node.status();
  }

  hc::Status validate() const {
    if (children.size() > 100) return hc::invalid_argument("too many children");
    return {};
  }
};

// A successful read must have checked every bound and run validate(), at every level.
void check_invariants(const Part& part) {
  if (!(part.weight_kg > 0) || part.count < 0 || part.level < -5 || part.level > 5 ||
      part.children.size() > 100)
    __builtin_trap();
  for (double v : part.values)
    if (!(v >= -1e3 && v <= 1e3)) __builtin_trap();
  for (const Part& child : part.children) check_invariants(child);
}

// Visits every map, sequence and scalar below `node` without a schema.
void walk(hc::ConfigNode node, int depth) {
  constexpr int kMaxWalkDepth = 16;
  if (depth > kMaxWalkDepth) return;
  if (auto entries = node.entries()) {
    for (auto& [key, child] : *entries) walk(child, depth + 1);
    return;
  }
  if (auto elements = node.elements()) {
    for (hc::ConfigNode& child : *elements) walk(child, depth + 1);
    return;
  }
  std::string text;
  double number = 0;
  bool flag = false;
  node.get(text);
  node.get(number);
  node.get(flag);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);

  if (hc::Result<hc::Config> config = hc::parse_config(text, "fuzz.yaml"); config.ok()) {
    if (hc::Result<Part> part = hc::read_config<Part>(*config); part.ok()) check_invariants(*part);
    (void)hc::read_config(*config, [](hc::ConfigNode root) {
      walk(root, 0);
      return root.status();
    });
  }

  if (hc::Result<hc::Json> json = hc::parse_json(text, "fuzz.json"); json.ok())
    (void)hc::dump_json(*json);
  return 0;
}
