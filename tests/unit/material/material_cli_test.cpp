// `hardcopy synth | fit heterogeneous | evaluate` as a user runs them: exit codes 0 / 2, --json
// keys, no output file on failure.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_run.h"
#include "test_data.h"

namespace hc::material {
namespace {

using hc::testing::CliRun;
using hc::testing::hardcopy;

TEST(MaterialCli, SynthFitEvaluateRoundTrip) {
  hc::testing::ScratchDir dir;
  std::ofstream(dir / "scene.json")
      << R"({"specimen": {"box_m": [0.04, 0.04, 0.02], "cells": [4, 4, 2]},
    "material": {"neo_hookean": {"youngs_pa": 60000, "poisson": 0.3, "stiffening": 4}},
    "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.03],
              "direction": [0, 0, -1]},
    "load": {"force_n": 2.0}, "steps": 3})";
  const std::string d = dir.path().string();
  CliRun s = hardcopy("synth " + d + "/scene.json --examples 3 --noise 0 --seed 3 -o " + d +
                      "/s.json --json");
  ASSERT_EQ(s.exit_code, 0) << s.out;
  EXPECT_EQ(nlohmann::json::parse(s.out)["tets"], 192);  // 4 x 4 x 2 cubes x 6 tets
  CliRun f = hardcopy("fit heterogeneous --samples " + d + "/s.json -o " + d +
                      "/m.json --regularization 1e-6 --json");
  ASSERT_EQ(f.exit_code, 0) << f.out;
  const auto fj = nlohmann::json::parse(f.out);
  for (const char* key : {"rms_error_m", "max_error_m", "mean_basis_size", "time_s"})
    EXPECT_TRUE(fj.contains(key)) << key;
  CliRun e = hardcopy("evaluate --material " + d + "/m.json --samples " + d + "/s.json --json");
  ASSERT_EQ(e.exit_code, 0) << e.out;
  const auto ej = nlohmann::json::parse(e.out);
  for (const char* key : {"rms_error_m", "max_error_m", "error_rel_max_disp"})
    EXPECT_TRUE(ej.contains(key)) << key;
  // Noise-free examples of a strain-stiffening neo-Hookean block: reproduced within 1 % of the
  // max displacement.
  EXPECT_LT(ej["error_rel_max_disp"].get<double>(), 0.01);

  // --joint (one material fitted to all examples at once, 13 RBF centres per tet: zero strain
  // and the quadratic-like stiffening's ±c e_k, fit.h): the same
  // homogeneous block (here with the weak Poisson prior of noisy fits), also within 1 %.
  CliRun jf = hardcopy("fit heterogeneous --samples " + d + "/s.json -o " + d +
                       "/mj.json --regularization 1e-6 --poisson-prior 0.1 --joint --json");
  ASSERT_EQ(jf.exit_code, 0) << jf.out;
  const auto jj = nlohmann::json::parse(jf.out);
  EXPECT_EQ(jj["joint"], true);
  EXPECT_EQ(jj["mean_basis_size"], 13.0);
  // --joint-linear: the linear stiffening only, one centre (zero strain) per tet (here with the
  // thesis's vertex-neighbour Laplacian instead of the default face neighbours).
  CliRun jl = hardcopy("fit heterogeneous --samples " + d + "/s.json -o " + d +
                       "/ml.json --regularization 1e-6 --joint --joint-linear "
                       "--joint-adjacency vertex --json");
  ASSERT_EQ(jl.exit_code, 0) << jl.out;
  EXPECT_EQ(nlohmann::json::parse(jl.out)["mean_basis_size"], 1.0);
  CliRun je = hardcopy("evaluate --material " + d + "/mj.json --samples " + d + "/s.json --json");
  ASSERT_EQ(je.exit_code, 0) << je.out;
  EXPECT_LT(nlohmann::json::parse(je.out)["error_rel_max_disp"].get<double>(), 0.01);
  EXPECT_EQ(hardcopy("fit heterogeneous --samples " + d + "/s.json -o " + d +
                     "/mk.json --joint --joint-regularization -1")
                .exit_code,
            2);
  EXPECT_EQ(hardcopy("fit heterogeneous --samples " + d + "/s.json -o " + d +
                     "/mk.json --joint --joint-adjacency edge")
                .exit_code,
            2);
  EXPECT_EQ(hardcopy("fit heterogeneous --samples " + d + "/s.json -o " + d +
                     "/mk.json --poisson-prior -0.1")
                .exit_code,
            2);
  EXPECT_FALSE(std::filesystem::exists(dir / "mk.json"));
}

TEST(MaterialCli, BadInputExitsTwoAndWritesNothing) {
  hc::testing::ScratchDir dir;
  const std::string d = dir.path().string();
  std::ofstream(dir / "bad.json") << R"({"format": "hardcopy.samples", "version": 9})";
  EXPECT_EQ(
      hardcopy("fit heterogeneous --samples " + d + "/bad.json -o " + d + "/m.json").exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir / "m.json"));
  EXPECT_EQ(
      hardcopy("evaluate --material " + d + "/none.json --samples " + d + "/bad.json").exit_code,
      2);
  std::ofstream(dir / "scene.json")
      << R"({"specimen": {"box_m": [0.04, 0.04, 0.02], "cells": [2, 2, 1]},
    "material": {"neo_hookean": {"youngs_pa": 60000, "poisson": 0.3, "stiffening": 4}},
    "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.03],
              "direction": [0, 0, -1]}, "load": {"depth_m": 0.001}})";
  EXPECT_EQ(hardcopy("synth " + d + "/scene.json -o " + d + "/s.json").exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir / "s.json"));
  EXPECT_EQ(hardcopy("synth " + d + "/scene.json -o " + d + "/s.json --examples 0").exit_code, 2);
}

TEST(MaterialCli, OutOfRangeOptionsNameTheRealProblem) {
  // Before: --noise 1e308 wrote positions of ~1e305 m ("max displacement inf", exit 0);
  // --examples 100000000 was accepted and failed after 87 s; --regularization inf said "must be
  // >= 0". Now each is refused at once, naming what is wrong, and nothing is written.
  hc::testing::ScratchDir dir;
  const std::string d = dir.path().string();
  std::ofstream(dir / "scene.json")
      << R"({"specimen": {"box_m": [0.04, 0.04, 0.02], "cells": [2, 2, 1]},
    "material": {"neo_hookean": {"youngs_pa": 60000, "poisson": 0.3}},
    "fixed": "bottom",
    "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.03],
              "direction": [0, 0, -1]}, "load": {"force_n": 1.0}})";
  // stderr too: the messages are the point.
  const auto with_stderr = [](const std::string& args) {
    return hc::testing::run_command((hc::testing::bin_dir() / "hardcopy").string() + " --quiet " +
                                    args + " 2>&1");
  };
  const std::string synth = "synth " + d + "/scene.json -o " + d + "/s.json ";
  CliRun n = with_stderr(synth + "--noise 1e308");
  EXPECT_EQ(n.exit_code, 2) << n.out;
  EXPECT_NE(n.out.find("--noise 1e+308: must be in [0, 10]"), std::string::npos) << n.out;
  CliRun e = with_stderr(synth + "--examples 100000000");
  EXPECT_EQ(e.exit_code, 2) << e.out;
  EXPECT_NE(e.out.find("--examples 100000000: must be in [1, 10000]"), std::string::npos) << e.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "s.json"));
  CliRun g = with_stderr("fit heterogeneous --samples " + d + "/s.json -o " + d +
                         "/m.json --regularization inf");
  EXPECT_EQ(g.exit_code, 2) << g.out;
  EXPECT_NE(g.out.find("must be a finite number, got inf"), std::string::npos) << g.out;
}

}  // namespace
}  // namespace hc::material
