// Samples and material JSON: round trips and malformed input (every reader error path names the
// offending entry; nothing is written on failure).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/file_io.h"
#include "common/tet_mesh_io.h"
#include "processing/material/material.h"
#include "processing/material/samples.h"
#include "test_data.h"

namespace hc::material {
namespace {

// Two positively oriented tets sharing the face (1, 2, 3).
TetMesh two_tets() {
  TetMesh m;
  m.nodes.resize(5, 3);
  m.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1;
  m.tets.resize(2, 4);
  m.tets << 0, 1, 2, 3, 1, 4, 2, 3;
  return m;
}

Samples small_samples() {
  Samples s;
  s.mesh = two_tets();
  Example ex;
  ex.name = "push";
  ex.probe.shape = "sphere";
  ex.probe.radius_m = 0.01;
  ex.probe.position_m = Eigen::Vector3d(1, 1, 1.5);
  ex.forces.push_back({4, Eigen::Vector3d(0, 0, -2.5)});
  ex.positions_m = s.mesh.nodes;
  ex.positions_m(4, 2) -= 0.01;
  ex.visible = {1, 1, 1, 0, 1};
  ex.fixed_nodes = {0, 1, 2};
  s.examples.push_back(ex);
  return s;
}

std::string samples_text() { return dump_json(samples_to_json(small_samples())); }

Status parse_modified(const std::function<void(Json&)>& edit) {
  Json j = samples_to_json(small_samples());
  edit(j);
  return parse_samples(dump_json(j), "s.json", ".").status();
}

TEST(SamplesFormat, RoundTripInline) {
  Result<Samples> s = parse_samples(samples_text(), "s.json", ".");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->mesh.num_nodes(), 5);
  EXPECT_EQ(s->mesh.num_tets(), 2);
  ASSERT_EQ(s->examples.size(), 1u);
  const Example& ex = s->examples[0];
  EXPECT_EQ(ex.name, "push");
  EXPECT_EQ(ex.probe.shape, "sphere");
  EXPECT_DOUBLE_EQ(ex.probe.radius_m, 0.01);
  ASSERT_EQ(ex.forces.size(), 1u);
  EXPECT_EQ(ex.forces[0].node, 4);
  EXPECT_DOUBLE_EQ(ex.forces[0].force_n.z(), -2.5);
  EXPECT_DOUBLE_EQ(ex.positions_m(4, 2), 1 - 0.01);
  EXPECT_EQ(ex.visible[3], 0);
  EXPECT_EQ(ex.fixed_nodes, (std::vector<int>{0, 1, 2}));
  // Only visible, non-fixed nodes count: node 4 moved by 0.01 m.
  EXPECT_NEAR(s->max_displacement_m(), 0.01, 1e-15);
  EXPECT_DOUBLE_EQ(ex.force_vector(5)(3 * 4 + 2), -2.5);
}

TEST(SamplesFormat, TetgenMeshReference) {
  hc::testing::ScratchDir dir;
  ASSERT_TRUE(write_tetgen(dir / "block", two_tets()).ok());
  Samples s = small_samples();
  s.node_file = "block.node";
  s.ele_file = "block.ele";
  ASSERT_TRUE(save_samples(dir / "s.json", s).ok());
  Result<Samples> back = load_samples(dir / "s.json");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_TRUE(back->mesh.nodes.isApprox(two_tets().nodes));
  EXPECT_EQ(back->mesh.num_tets(), 2);
  std::filesystem::remove(dir / "block.ele");
  Result<Samples> missing = load_samples(dir / "s.json");
  EXPECT_FALSE(missing.ok());
}

TEST(SamplesFormat, MalformedInputsAreRefusedWithTheirPath) {
  const auto expect_error = [](const std::function<void(Json&)>& edit, const std::string& needle) {
    Status s = parse_modified(edit);
    EXPECT_FALSE(s.ok()) << needle;
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.to_string();
    EXPECT_NE(s.message().find(needle), std::string::npos) << s.to_string();
  };
  expect_error([](Json& j) { j["version"] = 2; }, "unknown version 2");
  expect_error([](Json& j) { j["format"] = "other"; }, "format");
  expect_error([](Json& j) { j.erase("mesh"); }, "missing key 'mesh'");
  expect_error([](Json& j) { j["units"]["length"] = "mm"; }, "units.length");
  expect_error([](Json& j) { j["examples"] = Json::array(); }, "at least 1");
  expect_error([](Json& j) { j["examples"][0]["forces"][0]["force_n"][1] = nullptr; },
               "examples[0].forces[0].force_n[1]");
  expect_error([](Json& j) { j["examples"][0]["forces"][0]["node"] = 5; }, "out of range");
  expect_error([](Json& j) { j["examples"][0]["forces"][0]["node"] = -1; }, "negative");
  expect_error([](Json& j) { j["examples"][0]["positions_m"].erase(0); }, "expected 5 positions");
  expect_error(
      [](Json& j) {
        j["examples"][0]["positions_m"][2] = {1, 2};
      },
      "examples[0].positions_m[2]");
  expect_error([](Json& j) { j["examples"][0]["visible"][0] = 2; }, "visible[0]");
  expect_error([](Json& j) { j["examples"][0]["fixed_nodes"] = {7}; }, "fixed_nodes[0]");
  expect_error([](Json& j) { j["examples"][0]["probe"]["shape"] = "cone"; }, "unknown probe shape");
  expect_error([](Json& j) { j["examples"][0]["probe"]["direction"] = {0, 0, 2}; }, "unit vector");
  expect_error([](Json& j) { j["examples"][0]["fixed_node"] = {1}; }, "unknown key 'fixed_node'");
  expect_error([](Json& j) { j["examples"][0]["forces"].push_back(j["examples"][0]["forces"][0]); },
               "has a force already");
  expect_error([](Json& j) { j["mesh"]["tets"][0] = {0, 2, 1, 3}; }, "inverted");
  expect_error([](Json& j) { j["mesh"]["tets"][0] = {0, 1, 2, 2}; }, "degenerate");
  expect_error([](Json& j) { j["mesh"]["tets"][1] = {0, 1, 2, 9}; }, "mesh.tets[1][3]");
  // Numbers too large for a double are a parse error (JSON has no NaN or infinity literals).
  Status nan =
      parse_samples(std::string("{\"format\":\"hardcopy.samples\",\"version\":NaN}"), "s.json", ".")
          .status();
  EXPECT_FALSE(nan.ok());
  Status huge = parse_samples(std::string("{\"format\":\"hardcopy.samples\",\"version\":1e999}"),
                              "s.json", ".")
                    .status();
  EXPECT_FALSE(huge.ok());
}

TEST(SamplesFormat, SaveRefusesInvalidAndWritesNothing) {
  hc::testing::ScratchDir dir;
  Samples s = small_samples();
  s.examples[0].forces[0].force_n.x() = std::nan("");
  Status st = save_samples(dir / "bad.json", s);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("examples[0].forces[0].force_n"), std::string::npos)
      << st.to_string();
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.json"));
}

StrainRbf sample_rbf() {
  StrainRbf rbf;
  Vector6d c1;
  c1 << 0.1, -0.05, 0.02, 0.01, 0, 0.03;
  rbf.centres = {Vector6d::Zero(), c1};
  rbf.weights.resize(2, 2);
  rbf.weights << 1e5, 2e4, -3e4, 1e4;
  rbf.constant = Eigen::Vector2d(2e5, 6e4);
  rbf.lambda_floor_pa = 1e3;
  return rbf;
}

TEST(MaterialFormat, RoundTripAndEvaluation) {
  Material m;
  m.rbfs = {sample_rbf(), sample_rbf()};
  Result<Material> back = parse_material(dump_json(material_to_json(m)), "m.json");
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  ASSERT_EQ(back->rbfs.size(), 2u);
  RbfMaterial model(*back);
  EXPECT_EQ(model.num_elements(), 2);
  Vector6d e;
  e << 0.1, 0, 0, 0, 0, 0;
  // p = c + w0 |e| + w1 |e - c1|, by hand.
  Vector6d c1 = sample_rbf().centres[1];
  const double r0 = 0.1, r1 = (e - c1).norm();
  const fem::LambdaAlpha p = model.params(1, e);
  EXPECT_NEAR(p.lambda, 2e5 + 1e5 * r0 - 3e4 * r1, 1e-6);
  EXPECT_NEAR(p.alpha, 6e4 + 2e4 * r0 + 1e4 * r1, 1e-6);
}

TEST(MaterialFormat, ProjectionKeepsParametersPhysical) {
  // nu = alpha / lambda in [0, max_poisson], lambda >= floor (thesis Sec. 4.6).
  const fem::LambdaAlpha a = project_valid(Eigen::Vector2d(-5, 3), 10, 0.49);
  EXPECT_DOUBLE_EQ(a.lambda, 10);
  EXPECT_DOUBLE_EQ(a.alpha, 3);
  const fem::LambdaAlpha b = project_valid(Eigen::Vector2d(100, 80), 10, 0.49);
  EXPECT_DOUBLE_EQ(b.alpha, 49);
  const fem::LambdaAlpha c = project_valid(Eigen::Vector2d(100, -1), 10, 0.49);
  EXPECT_DOUBLE_EQ(c.alpha, 0);
  EXPECT_TRUE(fem::is_physically_valid(b));
}

TEST(MaterialFormat, BaseMaterialAppliesToAnyElement) {
  Material m;
  m.kind = MaterialKind::kBase;
  m.rbfs = {sample_rbf()};
  m.names = {"foam"};
  hc::testing::ScratchDir dir;
  ASSERT_TRUE(save_material(dir / "base.json", m).ok());
  Result<std::unique_ptr<fem::MaterialModel>> model = load_material(dir / "base.json");
  ASSERT_TRUE(model.ok()) << model.status().to_string();
  EXPECT_EQ((*model)->num_elements(), -1);
  EXPECT_NEAR((*model)->params(12345, Vector6d::Zero()).lambda,
              2e5 + 1e5 * 0 - 3e4 * sample_rbf().centres[1].norm(), 1e-6);
}

TEST(MaterialFormat, MalformedInputsAreRefused) {
  Material m;
  m.rbfs = {sample_rbf()};
  const auto expect_error = [&](const std::function<void(Json&)>& edit, const std::string& needle) {
    Json j = material_to_json(m);
    edit(j);
    Result<Material> r = parse_material(dump_json(j), "m.json");
    ASSERT_FALSE(r.ok()) << needle;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(needle), std::string::npos) << r.status().to_string();
  };
  expect_error([](Json& j) { j["version"] = 7; }, "unknown version 7");
  expect_error([](Json& j) { j["kind"] = "magic"; }, "unknown kind");
  expect_error([](Json& j) { j["elements"] = Json::array(); }, "at least 1");
  expect_error([](Json& j) { j["elements"][0]["weights"].erase(0); }, "expected 2 weights");
  expect_error(
      [](Json& j) {
        j["elements"][0]["centres"][1] = {1, 2, 3};
      },
      "elements[0].centres[1]");
  expect_error([](Json& j) { j["elements"][0]["constant"][0] = nullptr; }, "constant[0]");
  expect_error([](Json& j) { j["elements"][0]["lambda_floor_pa"] = 0; }, "must be > 0");
  expect_error([](Json& j) { j["elements"][0]["max_poisson"] = 0.5; }, "(0, 0.5)");
  expect_error([](Json& j) { j["elements"][0].erase("constant"); }, "missing key 'constant'");
  expect_error(
      [](Json& j) {
        j["kind"] = "base";
        j["materials"] = {{{"name", "a"}, {"rbf", j["elements"][0]}}};
        j.erase("elements");
        j["element_material"] = {0, 1};
      },
      "element_material[1]");
  EXPECT_FALSE(parse_material("{", "m.json").ok());
  EXPECT_EQ(read_material("/nonexistent/m.json").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace hc::material
