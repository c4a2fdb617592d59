#include "common/config.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <array>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "test_data.h"

namespace hc {
namespace {

enum class Trigger { kHardware, kSoftware };

struct CameraOptions {
  std::string name;
  double exposure_s = 0.01;
  int gain = 0;
  bool enabled = true;
  Trigger trigger = Trigger::kHardware;
  std::array<double, 3> position_m{};

  Status read(ConfigNode node) {
    node.required("name", name);
    node.optional("exposure_s", exposure_s, Bounds::positive());
    node.optional("gain", gain, Bounds::between(0, 48));
    node.optional("enabled", enabled);
    node.optional("trigger", trigger,
                  {{"hardware", Trigger::kHardware}, {"software", Trigger::kSoftware}});
    node.optional("position_m", position_m);
    return node.status();
  }
};

struct RigOptions {
  std::string name;
  double rate_hz = 30.0;
  std::int64_t seed = 7;
  std::string mode = "sim";
  std::optional<double> timeout_s;
  std::vector<CameraOptions> cameras;
  std::vector<std::string> tags;
  std::map<std::string, double> limits_n;
  std::size_t max_cameras = 8;

  Status read(ConfigNode node) {
    node.required("name", name);
    node.optional("rate_hz", rate_hz, Bounds::positive());
    node.optional("seed", seed);
    node.optional("mode", mode, {"sim", "real", "replay"});
    node.optional("timeout_s", timeout_s, Bounds::positive());
    node.optional("cameras", cameras);
    node.optional("tags", tags);
    node.optional("limits_n", limits_n, Bounds::non_negative());
    node.optional("max_cameras", max_cameras, Bounds::at_least(1));
    if (std::optional<ConfigNode> metadata = node.find("metadata")) metadata->allow_unknown_keys();
    return node.status();
  }

  Status validate() const {
    if (cameras.size() > max_cameras) return invalid_argument("more cameras than max_cameras");
    return {};
  }
};

// Parses `text` as "rig.yaml" and reads it into a RigOptions; the Status carries every problem.
Result<RigOptions> read_rig(std::string_view text) {
  HC_ASSIGN_OR_RETURN(Config config, parse_config(text, "rig.yaml"));
  return read_config<RigOptions>(config);
}

// The message of a failed read, for exact comparisons.
std::string rig_errors(std::string_view text) {
  Result<RigOptions> rig = read_rig(text);
  EXPECT_FALSE(rig.ok()) << "expected a failed read of:\n" << text;
  if (rig.ok()) return "";
  EXPECT_EQ(rig.status().code(), StatusCode::kInvalidArgument);
  return rig.status().message();
}

TEST(Config, ReadsAGoodFile) {
  const Result<RigOptions> rig = read_rig(R"(name: bench rig
rate_hz: 60
seed: -3
mode: real
timeout_s: 2.5
tags: [soft, "fast"]
limits_n: {probe: 20, arm: 0}
max_cameras: 2
metadata: {operator: ada, anything: [1, 2]}
cameras:
  - name: left
    exposure_s: 0.002
    gain: 12
    enabled: false
    trigger: software
    position_m: [0.1, -0.2, 1e-1]
  - name: right
)");
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  EXPECT_EQ(rig->name, "bench rig");
  EXPECT_EQ(rig->rate_hz, 60.0);
  EXPECT_EQ(rig->seed, -3);
  EXPECT_EQ(rig->mode, "real");
  ASSERT_TRUE(rig->timeout_s.has_value());
  EXPECT_EQ(*rig->timeout_s, 2.5);
  EXPECT_EQ(rig->tags, (std::vector<std::string>{"soft", "fast"}));
  EXPECT_EQ(rig->limits_n, (std::map<std::string, double>{{"arm", 0.0}, {"probe", 20.0}}));
  EXPECT_EQ(rig->max_cameras, 2u);
  ASSERT_EQ(rig->cameras.size(), 2u);
  const CameraOptions& left = rig->cameras[0];
  EXPECT_EQ(left.name, "left");
  EXPECT_EQ(left.exposure_s, 0.002);
  EXPECT_EQ(left.gain, 12);
  EXPECT_FALSE(left.enabled);
  EXPECT_EQ(left.trigger, Trigger::kSoftware);
  EXPECT_EQ(left.position_m, (std::array<double, 3>{0.1, -0.2, 0.1}));
  // Keys left out keep the struct's defaults.
  const CameraOptions& right = rig->cameras[1];
  EXPECT_EQ(right.name, "right");
  EXPECT_EQ(right.exposure_s, 0.01);
  EXPECT_EQ(right.gain, 0);
  EXPECT_TRUE(right.enabled);
  EXPECT_EQ(right.trigger, Trigger::kHardware);
}

TEST(Config, OptionalKeysKeepDefaults) {
  const Result<RigOptions> rig = read_rig("name: minimal\n");
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  EXPECT_EQ(rig->rate_hz, 30.0);
  EXPECT_EQ(rig->seed, 7);
  EXPECT_EQ(rig->mode, "sim");
  EXPECT_FALSE(rig->timeout_s.has_value());
  EXPECT_TRUE(rig->cameras.empty());
}

TEST(Config, NumbersInYamlSpellings) {
  const Result<RigOptions> rig = read_rig("name: n\nrate_hz: +1.5e2\nseed: 0x1F\n");
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  EXPECT_EQ(rig->rate_hz, 150.0);
  EXPECT_EQ(rig->seed, 31);
}

TEST(Config, WrongTypeNamesFileLinePathAndExpectation) {
  EXPECT_EQ(rig_errors(R"(name: r
cameras:
  - name: a
  - name: b
  - name: c
    exposure_s: fast
)"),
            "rig.yaml:6: cameras[2].exposure_s: expected a number > 0, got 'fast'");
}

TEST(Config, OutOfRangeValues) {
  EXPECT_EQ(rig_errors("name: r\nrate_hz: -1\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got -1");
  EXPECT_EQ(rig_errors("name: r\nrate_hz: 0\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got 0");
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n    gain: 49\n"),
            "rig.yaml:4: cameras[0].gain: expected an integer in [0, 48], got 49");
  EXPECT_EQ(rig_errors("name: r\nlimits_n: {probe: -0.5}\n"),
            "rig.yaml:2: limits_n.probe: expected a number >= 0, got -0.5");
  EXPECT_EQ(rig_errors("name: r\nmax_cameras: 0\n"),
            "rig.yaml:2: max_cameras: expected an integer >= 1, got 0");
}

TEST(Config, IntegersRejectFractionsAndOverflow) {
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n    gain: 2.5\n"),
            "rig.yaml:4: cameras[0].gain: expected an integer in [0, 48], got '2.5'");
  EXPECT_EQ(rig_errors("name: r\nseed: 1e3\n"), "rig.yaml:2: seed: expected an integer, got '1e3'");
  EXPECT_EQ(rig_errors("name: r\nseed: 99999999999999999999\n"),
            "rig.yaml:2: seed: expected an integer, got '99999999999999999999'");
  EXPECT_EQ(rig_errors("name: r\nseed: 0x-5\n"),
            "rig.yaml:2: seed: expected an integer, got '0x-5'");
}

TEST(Config, NonFiniteNumbersAreRejected) {
  EXPECT_EQ(rig_errors("name: r\nrate_hz: .inf\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got '.inf'");
  EXPECT_EQ(rig_errors("name: r\nrate_hz: nan\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got 'nan'");
  EXPECT_EQ(rig_errors("name: r\nrate_hz: 1e999\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got '1e999'");
}

TEST(Config, BooleansAndChoices) {
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n    enabled: maybe\n"),
            "rig.yaml:4: cameras[0].enabled: expected true or false, got 'maybe'");
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n    trigger: hardwre\n"),
            "rig.yaml:4: cameras[0].trigger: expected one of hardware, software, got 'hardwre' "
            "(did you mean 'hardware'?)");
  EXPECT_EQ(rig_errors("name: r\nmode: simulation\n"),
            "rig.yaml:2: mode: expected one of sim, real, replay, got 'simulation'");
}

TEST(Config, WrongShapes) {
  EXPECT_EQ(rig_errors("name: r\ncameras: 5\n"),
            "rig.yaml:2: cameras: expected a sequence, got '5'");
  EXPECT_EQ(rig_errors("name: [a, b]\n"), "rig.yaml:1: name: expected a string, got a sequence");
  EXPECT_EQ(rig_errors("name: r\nrate_hz: {a: 1}\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got a map");
  // One message for an element that is not a map, not one "missing" per required key.
  EXPECT_EQ(rig_errors("name: r\ncameras: [5]\n"),
            "rig.yaml:2: cameras[0]: expected a map, got '5'");
  EXPECT_EQ(rig_errors("- a\n- b\n"), "rig.yaml:1: expected a map, got a sequence");
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n    position_m: [1, 2]\n"),
            "rig.yaml:4: cameras[0].position_m: expected a sequence of 3 elements, got 2");
}

TEST(Config, EmptyValueIsReportedAtItsKey) {
  // yaml-cpp marks an empty value on the following line; the key's line is the useful one.
  EXPECT_EQ(rig_errors("name: r\nrate_hz:\nseed: 1\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got an empty value");
}

TEST(Config, MissingRequiredKeyNamesTheFullPath) {
  EXPECT_EQ(rig_errors("rate_hz: 5\n"), "rig.yaml:1: name: required key is missing");
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n  - exposure_s: 0.1\n"),
            "rig.yaml:4: cameras[1].name: required key is missing");
}

TEST(Config, UnknownKeysWithSuggestions) {
  EXPECT_EQ(rig_errors("name: r\ncameras:\n  - name: a\n    exposre_s: 0.1\n"),
            "rig.yaml:4: cameras[0]: unknown key 'exposre_s' (did you mean 'exposure_s'?)");
  EXPECT_EQ(rig_errors("name: r\ncolour: blue\n"), "rig.yaml:2: unknown key 'colour'");
  EXPECT_EQ(rig_errors("name: r\nRate_Hz: 1\n"),
            "rig.yaml:2: unknown key 'Rate_Hz' (did you mean 'rate_hz'?)");
}

TEST(Config, DuplicateAndNonTextKeys) {
  EXPECT_EQ(rig_errors("name: r\nseed: 1\nseed: 2\n"),
            "rig.yaml:3: duplicate key 'seed' (first at line 2)");
  EXPECT_EQ(rig_errors("name: r\n? [a, b]\n: 1\n"),
            "rig.yaml:2: keys must be plain text, got a sequence");
}

TEST(Config, AllProblemsAreReportedInLineOrder) {
  const std::string errors = rig_errors(R"(rate_hz: fast
cameras:
  - name: a
    gain: -1
    exposre_s: 2
  - name: b
    trigger: manual
mode: sim
)");
  EXPECT_EQ(errors,
            "rig.yaml:1: name: required key is missing\n"
            "rig.yaml:1: rate_hz: expected a number > 0, got 'fast'\n"
            "rig.yaml:4: cameras[0].gain: expected an integer in [0, 48], got -1\n"
            "rig.yaml:5: cameras[0]: unknown key 'exposre_s' (did you mean 'exposure_s'?)\n"
            "rig.yaml:7: cameras[1].trigger: expected one of hardware, software, got 'manual'");
}

TEST(Config, ValidateRunsAfterACleanReadAndReportsAtTheStruct) {
  EXPECT_EQ(rig_errors("name: r\nmax_cameras: 1\ncameras:\n  - name: a\n  - name: b\n"),
            "rig.yaml:1: more cameras than max_cameras");
  // With a read error, validate() does not run (its fields may be half-read).
  EXPECT_EQ(rig_errors("name: r\nmax_cameras: 1\ncameras:\n  - name: a\n  - name: [b]\n"),
            "rig.yaml:5: cameras[1].name: expected a string, got a sequence");
}

TEST(Config, CallbackReadsWithCrossKeyChecks) {
  Result<Config> config = parse_config("min_n: 5\nmax_n: 2\n", "limits.yaml");
  ASSERT_TRUE(config.ok());
  double min_n = 0, max_n = 0;
  const Status status = read_config(*config, [&](ConfigNode node) {
    node.required("min_n", min_n);
    node.required("max_n", max_n);
    if (max_n < min_n) node.error("max_n", "must not be less than min_n");
    return node.status();
  });
  EXPECT_EQ(status.message(), "limits.yaml:2: max_n: must not be less than min_n");
}

TEST(Config, ReadReturningItsOwnStatusIsRecordedAtTheNode) {
  Result<Config> config = parse_config("a: 1\n", "c.yaml");
  ASSERT_TRUE(config.ok());
  const Status status = read_config(*config, [](ConfigNode node) {
    std::int64_t a = 0;
    node.required("a", a);
    return failed_precondition("a is not supported yet");
  });
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(), "c.yaml:1: a is not supported yet");
}

TEST(Config, NodeStatusCountsOnlyProblemsBelowIt) {
  Result<Config> config = parse_config("a: x\nb: {c: 1, d: 2}\n", "s.yaml");
  ASSERT_TRUE(config.ok());
  const Status status = read_config(*config, [](ConfigNode root) {
    double a = 0;
    root.required("a", a);
    std::optional<ConfigNode> b = root.find("b");
    EXPECT_TRUE(b.has_value());
    if (!b) return root.status();
    EXPECT_EQ(b->path(), "b");
    EXPECT_EQ(b->line(), 2u);
    std::int64_t c = 0, d = 0;
    b->required("c", c);
    b->required("d", d);
    EXPECT_TRUE(b->status().ok());
    b->required("e", d);
    EXPECT_EQ(b->status().message(), "s.yaml:2: b.e: required key is missing");
    EXPECT_EQ(root.status().message(), "s.yaml:1: a: expected a number, got 'x' (and 1 more)");
    return root.status();
  });
  EXPECT_FALSE(status.ok());
}

TEST(Config, EntriesAndHas) {
  Result<Config> config = parse_config("devices:\n  cam0: 1\n  cam1: 2\n", "d.yaml");
  ASSERT_TRUE(config.ok());
  std::vector<std::string> names;
  const Status status = read_config(*config, [&](ConfigNode root) {
    EXPECT_TRUE(root.has("devices"));
    EXPECT_FALSE(root.has("arms"));
    std::optional<ConfigNode> devices = root.find("devices");
    if (!devices) return root.status();
    auto entries = devices->entries();
    EXPECT_TRUE(entries.has_value());
    if (entries)
      for (auto& [name, node] : *entries) {
        names.push_back(name);
        EXPECT_EQ(node.path(), "devices." + name);
      }
    return root.status();
  });
  EXPECT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(names, (std::vector<std::string>{"cam0", "cam1"}));
}

TEST(Config, NarrowIntegersAreCheckedAgainstTheirType) {
  Result<Config> config = parse_config("n: 3000000000\n", "n.yaml");
  ASSERT_TRUE(config.ok());
  int n = 1;
  const Status status = read_config(*config, [&](ConfigNode root) {
    root.required("n", n);
    return root.status();
  });
  EXPECT_EQ(status.message(),
            "n.yaml:1: n: expected an integer in [-2147483648, 2147483647], got 3000000000");
  EXPECT_EQ(n, 1);
}

TEST(Config, FailedSequenceLeavesTheOutputUntouched) {
  Result<Config> config = parse_config("v: [1, x, 3]\n", "v.yaml");
  ASSERT_TRUE(config.ok());
  std::vector<double> v{9.0};
  const Status status = read_config(*config, [&](ConfigNode root) {
    root.required("v", v);
    return root.status();
  });
  EXPECT_EQ(status.message(), "v.yaml:1: v[1]: expected a number, got 'x'");
  EXPECT_EQ(v, std::vector<double>{9.0});
}

// A recursive schema: every node may list child nodes.
struct Tree {
  std::vector<Tree> children;
  Status read(ConfigNode node) {
    node.optional("children", children);
    return node.status();
  }
};

TEST(Config, RecursiveAliasesStopAtTheDepthLimit) {
  // &a [*a] is a sequence that contains itself; a recursive schema must not follow it forever.
  Result<Config> config = parse_config("&a {children: [*a]}\n", "tree.yaml");
  ASSERT_TRUE(config.ok()) << config.status().to_string();
  Tree tree;
  const Status status = read_config(*config, tree);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("nested deeper than 64 levels"), std::string::npos)
      << status.message();
}

TEST(Config, AliasBombsStopAtTheWorkLimit) {
  // Each level lists the previous one 32 times: 32^5 (33 million) numbers in a few hundred bytes.
  std::string text = "l0: &l0 [1";
  for (int i = 1; i < 32; ++i) text += ", 1";
  text += "]\n";
  for (int level = 1; level <= 4; ++level) {
    text += fmt::format("l{}: &l{} [*l{}", level, level, level - 1);
    for (int i = 1; i < 32; ++i) text += fmt::format(", *l{}", level - 1);
    text += "]\n";
  }
  Result<Config> config = parse_config(text, "bomb.yaml");
  ASSERT_TRUE(config.ok()) << config.status().to_string();
  std::vector<std::vector<std::vector<std::vector<std::vector<double>>>>> values;
  const Status status = read_config(*config, [&](ConfigNode root) {
    root.allow_unknown_keys();
    root.required("l4", values);
    return root.status();
  });
  EXPECT_EQ(status.message(),
            "bomb.yaml: document too large to read (over 1048576 values, or 65536 maps and "
            "sequences): do aliases repeat a large part of it?");
  EXPECT_TRUE(values.empty());
}

TEST(Config, RecursiveSchemaOverBranchingAliasesStops) {
  // A recursive schema over a self-referencing, branching document.
  Result<Config> tree_config = parse_config("&a {children: [*a, *a, *a]}\n", "tree.yaml");
  ASSERT_TRUE(tree_config.ok());
  Tree tree;
  const Status tree_status = read_config(*tree_config, tree);
  EXPECT_EQ(tree_status.message().rfind("tree.yaml: document too large to read", 0), 0u)
      << tree_status.message();
}

TEST(Config, ManyProblemsAreCutShort) {
  std::string text = "name: r\n";
  for (int i = 0; i < 80; ++i) text += "unknown_" + std::to_string(i) + ": 1\n";
  const std::string errors = rig_errors(text);
  EXPECT_EQ(std::count(errors.begin(), errors.end(), '\n'), 50);
  EXPECT_NE(errors.find("rig.yaml: and 30 more problems"), std::string::npos);
}

TEST(Config, MalformedYamlNamesTheLine) {
  const Result<Config> config = parse_config("name: r\ncameras: [a,\n  b\nseed: 1\n", "bad.yaml");
  ASSERT_FALSE(config.ok());
  EXPECT_EQ(config.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(config.status().message().rfind("bad.yaml:", 0), 0u) << config.status().message();
  EXPECT_NE(config.status().message().find("invalid YAML: "), std::string::npos);

  const Result<Config> tab = parse_config("a:\n\t- 1\n", "tab.yaml");
  ASSERT_FALSE(tab.ok());
  EXPECT_EQ(tab.status().message().rfind("tab.yaml:2: invalid YAML: ", 0), 0u)
      << tab.status().message();
}

TEST(Config, MoreThanOneDocumentIsAnError) {
  const Result<Config> config = parse_config("a: 1\n---\nb: 2\n", "two.yaml");
  ASSERT_FALSE(config.ok());
  EXPECT_EQ(config.status().message(),
            "two.yaml:2: expected one YAML document, but another starts here");
}

TEST(Config, StrayTokensAreErrorsNotEndlessDocuments) {
  // yaml-cpp 0.7 turns these into an endless stream of empty documents (upstream PR #1319).
  const Result<Config> comma = parse_config(",", "c.yaml");
  ASSERT_FALSE(comma.ok());
  EXPECT_EQ(comma.status().message(), "c.yaml:1: invalid YAML: unexpected ','");
  const Result<Config> anchor = parse_config("&a, chiltri]}\n", "a.yaml");
  ASSERT_FALSE(anchor.ok());
  EXPECT_EQ(anchor.status().message(), "a.yaml:1: invalid YAML: unexpected ','");
}

TEST(Config, EmptyTextIsAnEmptyConfig) {
  for (const char* text : {"", "\n", "# only a comment\n", "---\n"}) {
    Result<Config> config = parse_config(text, "empty.yaml");
    ASSERT_TRUE(config.ok()) << config.status().to_string();
    CameraOptions camera;
    // Every key of an empty document is missing: required ones are errors, optional defaults.
    EXPECT_EQ(read_config(*config, camera).message(), "empty.yaml:1: name: required key is missing")
        << "text: " << text;
    std::optional<double> x;
    const Status status = read_config(*config, [&](ConfigNode root) {
      root.optional("x", x);
      return root.status();
    });
    EXPECT_TRUE(status.ok());
    EXPECT_FALSE(x.has_value());
  }
}

TEST(Config, LoadsFilesAndReportsMissingOnes) {
  testing::ScratchDir dir;
  const auto path = dir / "rig.yaml";
  std::ofstream(path) << "name: from disk\ncameras:\n  - name: a\n    exposure_s: fast\n";
  const Result<Config> config = load_config(path);
  ASSERT_TRUE(config.ok()) << config.status().to_string();
  EXPECT_EQ(config->name(), path.string());
  RigOptions rig;
  EXPECT_EQ(read_config(*config, rig).message(),
            path.string() + ":4: cameras[0].exposure_s: expected a number > 0, got 'fast'");
  EXPECT_EQ(rig.name, "from disk");

  const Result<Config> missing = load_config(dir / "nope.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  EXPECT_NE(missing.status().message().find("nope.yaml"), std::string::npos);

  const Result<Config> directory = load_config(dir.path());
  ASSERT_FALSE(directory.ok());
  EXPECT_EQ(directory.status().code(), StatusCode::kInvalidArgument);
}

TEST(Config, ControlCharactersInValuesAreEscaped) {
  EXPECT_EQ(rig_errors("name: r\nrate_hz: \"a\\nb\\x01\"\n"),
            "rig.yaml:2: rate_hz: expected a number > 0, got 'a\\nb\\x01'");
}

TEST(Bounds, ContainsAndDescribe) {
  EXPECT_TRUE(Bounds{}.contains(-1e300));
  EXPECT_FALSE(Bounds{}.contains(std::nan("")));
  EXPECT_FALSE(Bounds::positive().contains(0.0));
  EXPECT_TRUE(Bounds::non_negative().contains(0.0));
  EXPECT_TRUE(Bounds::between(0, 1).contains(1.0));
  EXPECT_FALSE(Bounds::between(0, 1).contains(1.0000001));
  EXPECT_FALSE(Bounds::at_most(2).contains(2.5));
  EXPECT_TRUE(Bounds::greater_than(-1).contains(-0.5));
  EXPECT_EQ(Bounds{}.describe("a number"), "a number");
  EXPECT_EQ(Bounds::positive().describe("a number"), "a number > 0");
  EXPECT_EQ(Bounds::at_least(1).describe("an integer"), "an integer >= 1");
  EXPECT_EQ(Bounds::at_most(0.5).describe("a number"), "a number <= 0.5");
  EXPECT_EQ(Bounds::between(0, 1).describe("a number"), "a number in [0, 1]");
  EXPECT_EQ((Bounds{0.0, 1.0, true, true}.describe("a number")), "a number in (0, 1)");
}

}  // namespace
}  // namespace hc

namespace hc {
namespace {

// YAML streams are Unicode (YAML 1.2 §5.2); config strings end up in JSON session metadata, which
// must be UTF-8. Invalid sequences from RFC 3629 §3 / the Markus Kuhn UTF-8 decoder test file.
TEST(Config, RejectsTextThatIsNotUtf8WithItsLine) {
  EXPECT_TRUE(
      parse_config("name: \"caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x98\x80\"\n", "ok.yaml").ok());
  for (const std::string& bad :
       {std::string("a: 1\nname: \xFF\n"), std::string("a: 1\nb: \xC0\xAF\n"),
        std::string("a: 1\nb: \xED\xA0\x80\n"), std::string("a: 1\nb: \xE2\x82\n"),
        std::string("a: 1\nb: \xF4\x90\x80\x80\n")}) {
    const auto r = parse_config(bad, "plan.yaml");
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("plan.yaml:2"), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("not UTF-8"), std::string::npos);
  }
}

// UTF-8 text whose YAML escapes decode to bytes that are not: yaml-cpp turns \_ (U+00A0) and \N
// (U+0085) into the single bytes 0xA0 and 0x85. Reading such a string or key is an error that
// names the file, line and key; JSON output of it would throw (found by fuzz_plan).
TEST(Config, EscapesThatDecodeToInvalidUtf8AreRefusedWhereRead) {
  Result<Config> config = parse_config("a: 1\nname: \"x\\_y\"\nmap: {\"k\\N\": v}\n", "p.yaml");
  ASSERT_TRUE(config.ok()) << config.status().to_string();
  const Status status = read_config(*config, [](ConfigNode root) {
    std::int64_t a = 0;
    std::string name;
    std::map<std::string, std::string> map;
    root.required("a", a);
    root.required("name", name);
    root.required("map", map);
    return root.status();
  });
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("p.yaml:2: name: a string that is not UTF-8 at byte 1"),
            std::string::npos)
      << status.message();
  EXPECT_NE(status.message().find("p.yaml:3: map: a key that is not UTF-8"), std::string::npos)
      << status.message();
  // The message itself is UTF-8 (it may be printed as JSON).
  EXPECT_EQ(nlohmann::json(status.message()).dump().find("\\u"), std::string::npos);
}

}  // namespace
}  // namespace hc
