// Probe curves, boundary triangles, curve comparison and the report page on inputs whose answers
// are known in closed form.
#include <gtest/gtest.h>

#include <cmath>

#include "common/file_io.h"
#include "figures/report.h"
#include "figures/samples_figures.h"
#include "processing/material/fit.h"
#include "processing/material/material.h"
#include "test_data.h"

namespace hc::figures {
namespace {

// A cube of side `a` split into six tets around its main diagonal (Kuhn), positively oriented.
// Node i + 2j + 4k sits at (i, j, k) * a.
TetMesh cube(double a) {
  TetMesh m;
  m.nodes.resize(8, 3);
  for (int n = 0; n < 8; ++n) m.nodes.row(n) << (n & 1) * a, ((n >> 1) & 1) * a, ((n >> 2) & 1) * a;
  const int axes[3] = {1, 2, 4};
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  m.tets.resize(6, 4);
  for (int t = 0; t < 6; ++t) {
    const int p = axes[perms[t][0]], q = axes[perms[t][1]];
    m.tets.row(t) << 0, p, p + q, 7;
    if (tet_signed_volume(m, t) < 0) std::swap(m.tets(t, 1), m.tets(t, 2));
  }
  return m;
}

material::Example press(const TetMesh& m, std::vector<std::pair<int, double>> loads,
                        double compliance_m_per_n) {
  material::Example e;
  e.probe.shape = "sphere";
  e.probe.radius_m = 0.004;
  e.positions_m = m.nodes;
  e.visible.assign(static_cast<std::size_t>(m.num_nodes()), 1);
  for (const auto& [node, f] : loads) {
    e.forces.push_back({node, Eigen::Vector3d(0, 0, -f)});
    e.positions_m(node, 2) -= compliance_m_per_n * f;
  }
  return e;
}

TEST(ProbeCurves, GroupsByLocationAndMeasuresTheIndentation) {
  material::Samples s;
  s.mesh = cube(0.05);
  // Location A: node 4 (0, 0, a), 2 N then 1 N; location B: node 7 (a, a, a), 3 N.
  s.examples.push_back(press(s.mesh, {{4, 2.0}}, 1e-3));
  s.examples.push_back(press(s.mesh, {{7, 3.0}}, 1e-3));
  s.examples.push_back(press(s.mesh, {{4, 1.0}}, 1e-3));
  s.examples.push_back(press(s.mesh, {}, 0.0));  // unloaded: no point
  Result<std::vector<ProbeCurve>> c = probe_curves(s);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  ASSERT_EQ(c->size(), 2u);
  const ProbeCurve& a = (*c)[0];
  ASSERT_EQ(a.points.size(), 2u);
  // Sorted by force; force = f·d with d = (0, 0, -1); displacement along d = compliance * f.
  EXPECT_EQ(a.points[0].example, 2u);
  EXPECT_DOUBLE_EQ(a.points[0].force_n, 1.0);
  // (z0 - c f) - z0 in doubles: exact up to the rounding of the subtraction (1e-15 m).
  EXPECT_NEAR(a.points[0].displacement_m, 1e-3, 1e-15);
  EXPECT_NEAR(a.points[1].displacement_m, 2e-3, 1e-15);
  EXPECT_DOUBLE_EQ(a.position_m[2], 0.05);
  EXPECT_NEAR((*c)[1].points[0].displacement_m, 3e-3, 1e-15);
  EXPECT_DOUBLE_EQ((*c)[1].position_m[0], 0.05);
}

TEST(ProbeCurves, DistributedLoadsAreForceWeighted) {
  material::Samples s;
  s.mesh = cube(0.002);  // nodes 4 and 5 are 2 mm apart: one location at tolerance 2 mm
  material::Example e = press(s.mesh, {{4, 3.0}, {5, 1.0}}, 0.0);
  e.positions_m(4, 2) -= 0.004;  // 4 mm under the 3 N node, 0 under the 1 N one
  s.examples.push_back(e);
  Result<std::vector<ProbeCurve>> c = probe_curves(s, nullptr, {.location_tolerance_m = 0.002});
  ASSERT_TRUE(c.ok());
  ASSERT_EQ(c->size(), 1u);
  EXPECT_DOUBLE_EQ((*c)[0].points[0].force_n, 4.0);
  EXPECT_DOUBLE_EQ((*c)[0].points[0].displacement_m, 0.75 * 0.004);  // (3 * 4 + 1 * 0) / 4 mm
  EXPECT_DOUBLE_EQ((*c)[0].position_m[0], 0.25 * 0.002);           // (3 * 0 + 1 * a) / 4
}

TEST(ProbeCurves, OtherPositionsAndBadInput) {
  material::Samples s;
  s.mesh = cube(0.05);
  s.examples.push_back(press(s.mesh, {{4, 2.0}}, 1e-3));
  std::vector<MatrixX3d> sim{s.mesh.nodes};
  sim[0](4, 2) -= 0.01;
  Result<std::vector<ProbeCurve>> c = probe_curves(s, &sim);
  ASSERT_TRUE(c.ok());
  EXPECT_DOUBLE_EQ((*c)[0].points[0].displacement_m, 0.01);
  sim.push_back(sim[0]);
  EXPECT_EQ(probe_curves(s, &sim).status().code(), StatusCode::kInvalidArgument);
  material::Samples none;
  none.mesh = cube(1);
  EXPECT_EQ(probe_curves(none).status().code(), StatusCode::kInvalidArgument);
}

TEST(BoundaryTriangles, CubeSurfaceIsClosedAndOutward) {
  const TetMesh m = cube(2.0);
  const MatrixX3i f = boundary_triangles(m);
  ASSERT_EQ(f.rows(), 12);  // two per face
  // Divergence theorem: sum over outward faces of (x · n) area / 3 = volume (8).
  double volume = 0;
  for (Eigen::Index t = 0; t < f.rows(); ++t) {
    const Eigen::Vector3d a = m.nodes.row(f(t, 0)), b = m.nodes.row(f(t, 1)), c = m.nodes.row(f(t, 2));
    volume += a.dot((b - a).cross(c - a)) / 6.0;
    const Eigen::Vector3d n = (b - a).cross(c - a);
    EXPECT_GT(n.dot((a + b + c) / 3.0 - Eigen::Vector3d(1, 1, 1)), 0) << "face " << t;
  }
  EXPECT_NEAR(volume, 8.0, 1e-12);
}

ProbeCurve linear_curve(double compliance, std::vector<double> forces) {
  ProbeCurve c;
  c.position_m = {0.01, 0.0, 0.05};
  for (std::size_t i = 0; i < forces.size(); ++i)
    c.points.push_back({i, forces[i], compliance * forces[i]});
  return c;
}

TEST(CompareCurves, RmsOfLinearCurvesIsAnalytic) {
  // Target d = F / 1000, design d = F / 1250 sampled at other forces; interpolation along a linear
  // design curve is exact, so the differences are F (1/1000 - 1/1250) = 2e-4 F at the target's
  // forces inside the design's range (2..20 N; 1 N and 25 N fall outside).
  const ProbeCurve target = linear_curve(1e-3, {1, 5, 10, 15, 25});
  ProbeCurve design = linear_curve(8e-4, {2, 4, 8, 12, 16, 20});
  design.position_m[0] += 0.0005;  // 0.5 mm away: still the same location at 1 mm
  Result<Comparison> c = compare_curves({target}, {design}, 1e-3);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(c->compared_points, 3u);
  const double expected = 2e-4 * std::sqrt((25.0 + 100.0 + 225.0) / 3.0);
  EXPECT_NEAR(c->rms_error_m, expected, 1e-15);
  EXPECT_NEAR(c->max_error_m, 2e-4 * 15, 1e-15);
  // No location within 0.1 mm: nothing to compare.
  EXPECT_EQ(compare_curves({target}, {design}, 1e-4).status().code(),
            StatusCode::kInvalidArgument);
}

TEST(Report, Base64MatchesRfc4648Vectors) {
  EXPECT_EQ(base64(""), "");
  EXPECT_EQ(base64("f"), "Zg==");
  EXPECT_EQ(base64("fo"), "Zm8=");
  EXPECT_EQ(base64("foo"), "Zm9v");
  EXPECT_EQ(base64("foob"), "Zm9vYg==");
  EXPECT_EQ(base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(html_escape("<a href=\"x\">&'"), "&lt;a href=&quot;x&quot;&gt;&amp;&#39;");
}

TEST(Report, PageIsSelfContained) {
  material::Samples s;
  s.mesh = cube(0.05);
  s.examples.push_back(press(s.mesh, {{4, 2.0}}, 1e-3));
  s.examples.push_back(press(s.mesh, {{4, 4.0}}, 1e-3));
  Result<FigureSet> set = samples_figures({"<block>", "block.json", s});
  ASSERT_TRUE(set.ok()) << set.status().to_string();
  Result<std::string> html = report_html({*set}, {});
  ASSERT_TRUE(html.ok());
  EXPECT_NE(html->find("&lt;block&gt;"), std::string::npos);  // titles are escaped
  EXPECT_NE(html->find("src=\"data:image/svg+xml;base64,"), std::string::npos);
  // Nothing is fetched: no src/href other than data: URIs, no <script>, no <link>. (A scan, not
  // std::regex: libstdc++'s regex recurses per character and overflows the stack on big pages.)
  for (const std::string attr : {"src=\"", "href=\""})
    for (std::size_t p = html->find(attr); p != std::string::npos; p = html->find(attr, p + 1))
      EXPECT_EQ(html->compare(p + attr.size(), 5, "data:"), 0) << html->substr(p, 40);
  EXPECT_EQ(html->find("<script"), std::string::npos);
  EXPECT_EQ(html->find("<link"), std::string::npos);
}

TEST(FitFigures, PlottedNumbersAreTheSimulationsAndTheErrorMapsTheNodeDistances) {
  hc::testing::ScratchDir dir;
  // A homogeneous linear material (lambda = 100 kPa, alpha = 30 kPa) on any mesh.
  const std::filesystem::path mat = dir / "linear.json";
  ASSERT_TRUE(write_file_atomic(mat, R"({"format": "hardcopy.material", "version": 1, "kind": "base",
      "materials": [{"name": "linear", "rbf": {"centres": [], "weights": [],
                     "constant": [1.0e5, 3.0e4], "lambda_floor_pa": 1}}]})")
                  .ok());
  material::Samples s;
  s.mesh = cube(0.05);
  for (double f : {0.5, 1.0, 1.5}) {
    material::Example e = press(s.mesh, {{4, f}}, 1e-4);  // "measured": 0.1 mm per N at node 4
    e.fixed_nodes = {0, 1, 2, 3};
    s.examples.push_back(e);
  }
  ASSERT_TRUE(material::validate_samples(s).ok()) << material::validate_samples(s).to_string();
  Result<FigureSet> set = fit_figures({"block", "block.json", s}, {{"linear", mat.string()}});
  ASSERT_TRUE(set.ok()) << set.status().to_string();
  // The same simulation, run here: the figure's simulated curve must carry exactly its numbers.
  Result<std::unique_ptr<fem::MaterialModel>> model = material::load_material(mat);
  ASSERT_TRUE(model.ok());
  Result<material::EvaluateSummary> ev = material::evaluate_material(**model, s, {});
  ASSERT_TRUE(ev.ok());
  const Figure& loc0 = set->figures.front();
  ASSERT_EQ(loc0.name, "fit_loc0");
  const Json& sim = loc0.data["curves"]["linear"];
  ASSERT_EQ(sim.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const auto ex = sim[i]["example"].get<std::size_t>();
    // Displacement along (0, 0, -1) of the one loaded node.
    EXPECT_EQ(sim[i]["displacement_m"].get<double>(),
              -(ev->positions[ex](4, 2) - s.mesh.nodes(4, 2)));
    EXPECT_NEAR(loc0.data["curves"]["measured"][i]["displacement_m"].get<double>(),
                1e-4 * sim[i]["force_n"].get<double>(), 1e-15);  // up to the subtraction's rounding
  }
  EXPECT_EQ(set->numbers["linear.rms_error_m"].get<double>(), ev->rms_error_m);
  // The error map: the example with the largest force (1.5 N, example 2), node distances.
  const Figure& map = set->figures.back();
  ASSERT_EQ(map.name, "error_map");
  EXPECT_EQ(map.data["example"], 2);
  for (const Json& n : map.data["nodes"]) {
    const int i = n["node"].get<int>();
    EXPECT_DOUBLE_EQ(n["error_m"].get<double>(),
                     (ev->positions[2].row(i) - s.examples[2].positions_m.row(i)).norm());
  }
  ASSERT_EQ(set->files.size(), 1u);
  EXPECT_EQ(set->files[0].first, "error_map.vtu");
  EXPECT_NE(set->files[0].second.find("Name=\"error_m\""), std::string::npos);
  // Everything draws.
  for (const Figure& f : set->figures) EXPECT_TRUE(render_figure(f, plot::ImageFormat::kPng).ok());
}

}  // namespace
}  // namespace hc::figures
