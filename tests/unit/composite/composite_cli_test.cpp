// `hardcopy fit base | design composite | simulate` as a user runs them: the contract's --json
// keys, exit codes 0 / 1 / 2, nothing written on bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_run.h"
#include "sanitizer.h"
#include "test_data.h"

namespace hc::composite {
namespace {

using hc::testing::CliRun;
using hc::testing::hardcopy;
namespace fs = std::filesystem;

// A 4 x 4 x 2 cm block, 4 x 4 x 2 cells, of a neo-Hookean material under a sphere probe.
void write_scene(const fs::path& file, double youngs_pa, double height_m = 0.02) {
  std::ofstream(file) << R"({"specimen": {"box_m": [0.04, 0.04, )" << height_m
                      << R"(], "cells": [4, 4, 2]},
    "material": {"neo_hookean": {"youngs_pa": )"
                      << youngs_pa << R"(, "poisson": 0.3, "stiffening": 4}},
    "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.03],
              "direction": [0, 0, -1]},
    "load": {"force_n": 3.0}, "steps": 3})";
}

TEST(CompositeCli, FitBaseDesignSimulate) {
  HC_SKIP_WHEN_SANITIZED("two fits and a design through the CLI (~20 s in Release)");
  hc::testing::ScratchDir dir;
  const std::string d = dir.path().string();
  for (const auto& [name, e] : {std::pair{"soft", 60e3}, std::pair{"hard", 400e3}}) {
    write_scene(dir / (std::string(name) + ".scene.json"), e);
    CliRun s = hardcopy("synth " + d + "/" + name + ".scene.json --examples 3 --seed 5 -o " + d +
                        "/" + name + ".samples.json");
    ASSERT_EQ(s.exit_code, 0) << s.out;
    // The hard block's fit on 2 of its 3 examples (--max-examples keeps the first and the last).
    const bool hard = std::string(name) == "hard";
    CliRun f = hardcopy("fit base --samples " + d + "/" + name + ".samples.json --model isotropic " +
                        (hard ? "--max-examples 2 " : "") + "--name " + name +
                        " --printer-material 'TPU " + name + "' -o " + d + "/" + name + ".json --json");
    ASSERT_EQ(f.exit_code, 0) << f.out;
    const auto j = nlohmann::json::parse(f.out);
    for (const char* key : {"rms_error_m", "max_error_m", "levels", "centres", "time_s"})
      EXPECT_TRUE(j.contains(key)) << key;
    for (const auto& l : j["levels"])
      for (const char* key : {"force_n", "avg_m", "std_m", "max_m"}) EXPECT_TRUE(l.contains(key));
    EXPECT_EQ(j["centres"], 6);
    int examples = 0;
    for (const auto& l : j["levels"]) examples += l["examples"].get<int>();
    EXPECT_EQ(examples, hard ? 2 : 3) << name;
  }
  std::ofstream(dir / "lib.json") << R"({"materials": [
      {"name": "soft", "file": "soft.json", "printer_material": "TPU 85A"},
      {"name": "hard", "file": "hard.json", "printer_material": "PLA"}]})";
  // Target: the soft material's samples (a block of the soft material itself).
  CliRun c = hardcopy("design composite --target " + d + "/soft.samples.json --library " + d +
                      "/lib.json --layers 2 --search exact -o " + d + "/design.json --3mf " + d +
                      "/design.3mf --json");
  ASSERT_EQ(c.exit_code, 0) << c.out;
  const auto j = nlohmann::json::parse(c.out);
  for (const char* key : {"design", "rms_error_m", "designs_simulated", "certified", "time_s"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["design"], nlohmann::json::array({"soft", "soft"}));
  EXPECT_TRUE(fs::exists(dir / "design.3mf"));
  // The design as a scene material on its specimen.
  std::ofstream(dir / "design.scene.json") << R"({"specimen": {"box_m": [0.04, 0.04, 0.02], "cells": [4, 4, 2]},
    "material": {"file": "design.json"}, "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.03],
              "direction": [0, 0, -1]}, "load": {"force_n": 2.0}, "steps": 3})";
  CliRun sim = hardcopy("simulate " + d + "/design.scene.json --json");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  EXPECT_NEAR(nlohmann::json::parse(sim.out)["force_n"].get<double>(), 2.0, 0.01);
  // ... and on a different specimen: exit 2.
  std::ofstream(dir / "other.scene.json") << R"({"specimen": {"box_m": [0.04, 0.04, 0.03], "cells": [4, 4, 2]},
    "material": {"file": "design.json"}, "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.04],
              "direction": [0, 0, -1]}, "load": {"force_n": 2.0}, "steps": 3})";
  EXPECT_EQ(hardcopy("simulate " + d + "/other.scene.json").exit_code, 2);

  // Bad input: exit 2, nothing written.
  const std::string base = "design composite --target " + d + "/soft.samples.json -o " + d + "/bad.json ";
  std::ofstream(dir / "empty.json") << R"({"materials": []})";
  EXPECT_EQ(hardcopy(base + "--library " + d + "/empty.json --layers 2").exit_code, 2);
  // Thicknesses in millimetres where metres are expected.
  EXPECT_EQ(hardcopy(base + "--library " + d + "/lib.json --thickness-m 10 10").exit_code, 2);
  // 2 materials in 4 x 4 x 2 voxels: 2^32 designs, more than the exact mode enumerates.
  EXPECT_EQ(hardcopy(base + "--library " + d + "/lib.json --cells 4 4 2 --search exact").exit_code, 2);
  EXPECT_EQ(hardcopy(base + "--library " + d + "/lib.json --layers 2 --cells 1 1 2").exit_code, 2);
  EXPECT_FALSE(fs::exists(dir / "bad.json"));
  // fit base: a samples file in millimetres is refused by the samples reader.
  std::ifstream in(dir / "soft.samples.json");
  auto sj = nlohmann::json::parse(in);
  sj["units"] = {{"length", "mm"}, {"force", "N"}};
  std::ofstream(dir / "mm.json") << sj.dump();
  EXPECT_EQ(hardcopy("fit base --samples " + d + "/mm.json --name x -o " + d + "/x.json").exit_code, 2);
  EXPECT_FALSE(fs::exists(dir / "x.json"));
}

}  // namespace
}  // namespace hc::composite
