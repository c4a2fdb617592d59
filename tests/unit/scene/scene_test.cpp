// SCENE.json reader (every key, bad input), simulate() on small structured boxes, and the hardcopy
// simulate / validate fem command-line contract (exit codes, --json keys, --vtu).
#include "processing/scene/scene.h"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_run.h"
#include "sanitizer.h"
#include "test_data.h"

namespace hc::scene {
namespace {

using hc::testing::bin_dir;
using hc::testing::ScratchDir;

constexpr const char* kScene = R"({
  "specimen": {"box_m": [0.04, 0.04, 0.02], "cells": [8, 8, 4]},
  "material": {"linear": {"youngs_pa": 1e5, "poisson": 0.3}},
  "fixed": "bottom",
  "probe": {"shape": "sphere", "radius_m": 0.01, "position_m": [0.02, 0.02, 0.035],
            "direction": [0, 0, -1]},
  "load": {"depth_m": 0.002},
  "steps": 2})";

nlohmann::json base() { return nlohmann::json::parse(kScene); }

Result<Scene> parse(const nlohmann::json& j) { return parse_scene(j.dump(), "scene.json", "/tmp"); }

TEST(SceneReader, ParsesEveryKey) {
  auto s = parse(base());
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->specimen.kind, SpecimenSpec::Kind::kBox);
  EXPECT_EQ(*s->specimen.cells, Eigen::Vector3i(8, 8, 4));
  EXPECT_EQ(s->material.kind, MaterialKind::kLinear);
  EXPECT_DOUBLE_EQ(s->material.youngs_pa, 1e5);
  EXPECT_TRUE(s->fixed_bottom);
  EXPECT_EQ(s->probe.shape, ProbeSpec::Shape::kSphere);
  EXPECT_EQ(s->load.control, fem::LoadControl::kDepth);
  EXPECT_EQ(s->steps, 2);
  auto j = base();
  j["material"] = nlohmann::json::array(
      {{{"z_m", {0.0, 0.01}}, {"linear", {{"youngs_pa", 1e5}, {"poisson", 0.3}}}},
       {{"z_m", {0.01, 0.02}}, {"linear", {{"youngs_pa", 3e5}, {"poisson", 0.45}}}}});
  j["load"] = {{"force_n", 0.5}};
  j["fixed"] = {0, 1, 2};
  j["specimen"] = {{"mesh", "part.stl"}, {"scale_to_m", 0.001}};
  s = parse(j);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->material.layers.size(), 2u);
  EXPECT_EQ(s->load.control, fem::LoadControl::kForce);
  EXPECT_EQ(s->fixed_nodes, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(s->specimen.mesh, std::filesystem::path("/tmp/part.stl"));
  // The neo-Hookean reference's strain stiffening β, alone and per layer (default 0).
  j = base();
  j["material"] = {{"neo_hookean", {{"youngs_pa", 3e4}, {"poisson", 0.25}, {"stiffening", 8}}}};
  s = parse(j);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->material.kind, MaterialKind::kNeoHookean);
  EXPECT_DOUBLE_EQ(s->material.stiffening, 8);
  j["material"] = nlohmann::json::array(
      {{{"z_m", {0.0, 0.01}}, {"neo_hookean", {{"youngs_pa", 1.5e5}, {"poisson", 0.3}}}},
       {{"z_m", {0.01, 0.02}},
        {"neo_hookean", {{"youngs_pa", 3e4}, {"poisson", 0.25}, {"stiffening", 8}}}}});
  s = parse(j);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_DOUBLE_EQ(s->material.layers[0].stiffening, 0);
  EXPECT_DOUBLE_EQ(s->material.layers[1].stiffening, 8);
}

TEST(SceneReader, BadInputNamesTheKey) {
  const std::vector<std::pair<std::function<void(nlohmann::json&)>, std::string>> cases = {
      {[](auto& j) { j.erase("probe"); }, "probe: missing"},
      {[](auto& j) { j.erase("load"); }, "load: missing"},
      {[](auto& j) { j["probe"]["radius_m"] = -1; }, "probe.radius_m"},
      {[](auto& j) { j["probe"]["radius_m"] = "big"; }, "probe.radius_m"},
      {[](auto& j) { j["probe"]["shape"] = "cone"; }, "probe.shape"},
      {[](auto& j) {
         j["probe"]["direction"] = {0, 0, 0};
       },
       "probe.direction"},
      {[](auto& j) {
         j["probe"]["position_m"] = {0, 0};
       },
       "probe.position_m"},
      {[](auto& j) { j["material"]["linear"]["poisson"] = 0.5; }, "material.linear"},
      {[](auto& j) {
         j["material"] = {{"linear", {{"youngs_pa", 1e5}}}};
       },
       "poisson"},
      {[](auto& j) {
         j["load"] = {{"depth_m", 0.001}, {"force_n", 1}};
       },
       "load"},
      {[](auto& j) {
         j["load"] = {{"depth_m", -0.001}};
       },
       "load"},
      {[](auto& j) { j["fixed"] = "top"; }, "fixed"},
      {[](auto& j) { j["fixed"] = nlohmann::json::array(); }, "fixed"},
      {[](auto& j) { j["steps"] = 0; }, "steps"},
      {[](auto& j) {
         j["specimen"]["box_m"] = {0.1, -0.1, 0.1};
       },
       "specimen.box_m"},
      {[](auto& j) { j["material"]["linear"]["stiffening"] = 1; }, "unknown key"},
      {[](auto& j) {
         j["material"] = {
             {"neo_hookean", {{"youngs_pa", 1e5}, {"poisson", 0.3}, {"stiffening", -1}}}};
       },
       "material.neo_hookean.stiffening"},
      {[](auto& j) {
         j["material"] = {
             {"neo_hookean", {{"youngs_pa", 1e5}, {"poisson", 0.3}, {"stiffening", "high"}}}};
       },
       "material.neo_hookean.stiffening"},
      {[](auto& j) { j["specimen"]["colour"] = 1; }, "unknown key"},
      // The base scene has "cells": the refinement is of the contact-adaptive mesh only.
      {[](auto& j) { j["specimen"]["contact_elements_per_radius"] = 6; },
       "specimen.contact_elements_per_radius"},
      {[](auto& j) {
         j["specimen"].erase("cells");
         j["specimen"]["contact_elements_per_radius"] = 0.5;
       },
       "specimen.contact_elements_per_radius"},
      {[](auto& j) {
         j["specimen"].erase("cells");
         j["specimen"]["contact_elements_per_radius"] = 40;
       },
       "specimen.contact_elements_per_radius"},
      {[](auto& j) { j["extra"] = 1; }, "unknown key"},
  };
  for (const auto& [mutate, expected] : cases) {
    auto j = base();
    mutate(j);
    auto s = parse(j);
    ASSERT_FALSE(s.ok()) << j.dump();
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(s.status().message().find(expected), std::string::npos) << s.status().message();
  }
  EXPECT_FALSE(parse_scene("{\"specimen\": NaN}", "x.json", ".").ok());
  EXPECT_FALSE(parse_scene("", "x.json", ".").ok());
  EXPECT_FALSE(parse_scene("[1, 2]", "x.json", ".").ok());
}

TEST(Simulate, LinearSphereIndentationAndLayers) {
  auto s = parse(base());
  ASSERT_TRUE(s.ok());
  auto r = simulate(*s);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->model, "corotational_linear");
  ASSERT_EQ(r->steps.size(), 2u);
  EXPECT_NEAR(r->depth_m, 0.002, 1e-12);
  EXPECT_GT(r->steps[1].force_n, r->steps[0].force_n);
  EXPECT_GT(r->steps[0].force_n, 0);
  // The largest displacement is (up to the penalty penetration) the imposed depth at the pole.
  EXPECT_NEAR(r->max_displacement_m, 0.002, 0.1 * 0.002);
  EXPECT_EQ(r->mesh.num_tets(), 8 * 8 * 4 * 6);
  // A stiffer top layer raises the force (same depth).
  auto j = base();
  j["material"] = nlohmann::json::array(
      {{{"z_m", {0.0, 0.01}}, {"linear", {{"youngs_pa", 1e5}, {"poisson", 0.3}}}},
       {{"z_m", {0.01, 0.02}}, {"linear", {{"youngs_pa", 4e5}, {"poisson", 0.3}}}}});
  auto layered = simulate(*parse(j));
  ASSERT_TRUE(layered.ok()) << layered.status().to_string();
  EXPECT_GT(layered->force_n, 1.5 * r->force_n);
}

// A flat punch wider than the block compresses it uniformly. With ν = 0 and the bottom fixed the
// strain is uniaxial, so the force is F = E·A·d/H exactly (Hooke's law) for the linear model and,
// at 1 % strain, within ~1 % for the neo-Hookean one (small-strain limit). This caught the
// reference model's probe being counted twice (half the force).
TEST(Simulate, FlatPunchOverTheWholeTopMatchesHookesLawForBothModels) {
  constexpr double kE = 1e5, kA = 0.04 * 0.04, kH = 0.02, kD = 2e-4;
  const double expected = kE * kA * kD / kH;  // 0.8 N
  for (const char* model : {"linear", "neo_hookean"}) {
    auto j = base();
    j["material"] = {{model, {{"youngs_pa", kE}, {"poisson", 0.0}}}};
    j["probe"] = {{"shape", "flat"},
                  {"radius_m", 0.1},
                  {"position_m", {0.02, 0.02, 0.03}},
                  {"direction", {0, 0, -1}}};
    j["load"] = {{"depth_m", kD}};
    auto r = simulate(*parse(j));
    ASSERT_TRUE(r.ok()) << model << ": " << r.status().to_string();
    EXPECT_NEAR(r->force_n, expected, 0.015 * expected) << model;
  }
  // The strain-stiffening term is quartic in the strain (hyperelastic/neo_hookean.h): at 1 %
  // strain β = 8 still gives Hooke's law within the same 1.5 %. At 15 % the closed form of the
  // same uniaxial strain (ν = 0, so λ = 0 and the free sides carry no stress at lateral stretch
  // 1): with stretch s, ψ = μ/2 (s² − 1) − μ ln s + β μ/4 g², g = s² − 1 − 2 ln s, the nominal
  // stress is dψ/ds = μ (s − 1/s)(1 + β g), so F = A μ (1/s − s)(1 + β g): 26.12 N plain and
  // 1.380x that with β = 8.
  constexpr double kS = 0.85, kBeta = 8;
  auto j = base();
  j["material"] = {{"neo_hookean", {{"youngs_pa", kE}, {"poisson", 0.0}, {"stiffening", kBeta}}}};
  j["probe"] = {{"shape", "flat"},
                {"radius_m", 0.1},
                {"position_m", {0.02, 0.02, 0.03}},
                {"direction", {0, 0, -1}}};
  j["load"] = {{"depth_m", kD}};
  auto small = simulate(*parse(j));
  ASSERT_TRUE(small.ok()) << small.status().to_string();
  EXPECT_NEAR(small->force_n, expected, 0.015 * expected);
  const double g = kS * kS - 1 - 2 * std::log(kS);
  const double plain_n = kA * (kE / 2) * (1 / kS - kS);
  j["load"] = {{"depth_m", (1 - kS) * kH}};
  auto stiff = simulate(*parse(j));
  j["material"]["neo_hookean"]["stiffening"] = 0;
  auto plain = simulate(*parse(j));
  ASSERT_TRUE(stiff.ok() && plain.ok());
  EXPECT_NEAR(plain->force_n, plain_n, 0.01 * plain_n);
  EXPECT_NEAR(stiff->force_n, plain_n * (1 + kBeta * g), 0.01 * plain_n * (1 + kBeta * g));
}

TEST(Simulate, BadScenesFailClearly) {
  auto j = base();
  j["probe"]["position_m"] = {0.5, 0.5, 0.035};  // misses the block
  auto r = simulate(*parse(j));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("misses the specimen"), std::string::npos);
  j = base();
  j["fixed"] = {100000};
  r = simulate(*parse(j));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("out of range"), std::string::npos);
  j = base();
  j["material"] = {{"file", "/nonexistent/material.json"}};
  EXPECT_FALSE(simulate(*parse(j)).ok());
  j = base();
  j["specimen"] = {{"mesh", "/nonexistent/part.stl"}};
  EXPECT_FALSE(simulate(*parse(j)).ok());
}

// ---- CLI ----

struct CliRun {
  int exit_code = -1;
  std::string out;
};

CliRun run(const std::string& args) {
  CliRun r;
  const std::string cmd = (bin_dir() / "hardcopy").string() + " " + args + " 2>/dev/null";
  std::unique_ptr<FILE, int (*)(FILE*)> p(popen(cmd.c_str(), "r"), pclose);
  std::array<char, 4096> buf{};
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p.get())) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p.release());
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(SimulateCli, JsonContractAndVtu) {
  ScratchDir dir;
  { std::ofstream(dir / "scene.json") << kScene; }
  const CliRun r = run("simulate " + (dir / "scene.json").string() + " --json --vtu " +
                       (dir / "out.vtu").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key :
       {"force_n", "depth_m", "max_displacement_m", "steps", "nodes", "tets", "time_s"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["steps"].size(), 2u);
  EXPECT_TRUE(j["steps"][0].contains("depth_m") && j["steps"][0].contains("force_n"));
  EXPECT_EQ(j["tets"], 1536);
  EXPECT_TRUE(std::filesystem::exists(dir / "out.vtu"));
}

TEST(SimulateCli, BadInputExitsTwo) {
  ScratchDir dir;
  { std::ofstream(dir / "nan.json") << "{\"specimen\": {\"box_m\": [NaN, 1, 1]}}"; }
  EXPECT_EQ(run("simulate " + (dir / "nan.json").string()).exit_code, 2);
  auto j = base();
  j.erase("material");
  { std::ofstream(dir / "missing.json") << j.dump(); }
  EXPECT_EQ(run("simulate " + (dir / "missing.json").string()).exit_code, 2);
  j = base();
  j["probe"]["direction"] = {0, 0, 1};  // moves away from the specimen
  { std::ofstream(dir / "away.json") << j.dump(); }
  EXPECT_EQ(run("simulate " + (dir / "away.json").string()).exit_code, 2);
  EXPECT_EQ(run("simulate " + (dir / "absent.json").string()).exit_code, 2);
}

TEST(SimulateCli, NonsenseIsRefusedNamingTheRealProblem) {
  // Each of these exited 0 or with a misleading message before (issue 18, items 10-11).
  ScratchDir dir;
  const auto run_scene = [&](const std::string& name, const nlohmann::json& j) {
    { std::ofstream(dir / name) << j.dump(); }
    return hc::testing::run_command((bin_dir() / "hardcopy").string() + " --quiet simulate " +
                                    (dir / name).string() + " 2>&1");
  };
  auto inside = base();
  inside["probe"]["position_m"] = {0.02, 0.02, 0.01};  // the box is 20 mm high
  hc::testing::CliRun r = run_scene("inside.json", inside);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("is inside the specimen"), std::string::npos) << r.out;

  auto force = base();
  force["load"] = {{"force_n", 1e300}};
  r = run_scene("force.json", force);
  EXPECT_EQ(r.exit_code, 2) << r.out;  // was "unreachable probe", exit 1
  EXPECT_NE(r.out.find("load.force_n 1e+300 N is not a probe load"), std::string::npos) << r.out;

  auto stiff = base();
  stiff["material"]["linear"]["youngs_pa"] = 1e308;
  r = run_scene("stiff.json", stiff);
  EXPECT_EQ(r.exit_code, 2) << r.out;  // was "contact stiffness -nan"
  EXPECT_NE(r.out.find("Young's modulus must be in (0, 1e+13] Pa"), std::string::npos) << r.out;

  // A closed mesh specimen that intersects itself (issue 12: SIGSEGV inside TetGen before).
  auto tangled = base();
  tangled["specimen"] = {{"mesh", HARDCOPY_SHARED_DATA "/meshes/candleStand.stl"},
                         {"scale_to_m", 0.001}};
  r = run_scene("tangled.json", tangled);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("the surface intersects itself"), std::string::npos) << r.out;
}

TEST(ValidateFemCli, PrintsEveryCaseAndFailsWhenACaseIsOutOfTolerance) {
  HC_SKIP_WHEN_SANITIZED("~1 min: every validation case");
  // Level 1 is coarse: the patch tests pass, the cantilever (linear tets lock in bending, ~50 %
  // low) does not, so the command must exit 1 and say which case failed.
  const CliRun r = run("validate fem --level 1 --json");
  ASSERT_EQ(r.exit_code, 1) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["cases"].size(), 5u);
  EXPECT_EQ(j["cases"][0]["name"], "patch_linear");
  EXPECT_TRUE(j["cases"][0]["pass"].get<bool>());
  EXPECT_TRUE(j["cases"][1]["pass"].get<bool>());
  EXPECT_EQ(j["cases"][2]["name"], "cantilever");
  EXPECT_FALSE(j["cases"][2]["pass"].get<bool>());
  EXPECT_FALSE(j["pass"].get<bool>());
  EXPECT_EQ(run("validate fem --level 9").exit_code, 2);
}

}  // namespace
}  // namespace hc::scene
