// check_mesh and repair_mesh on small synthetic meshes whose answers follow from their
// construction (counts by hand, Euler's formula, volumes of boxes and tetrahedra).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"
#include "printability_test_util.h"
#include "synthetic_meshes.h"

namespace hc::fabrication {
namespace {

using testing::box;
using testing::check;
using testing::flip;
using testing::join;
using testing::repair;
using testing::unit_cube;

// Corners of the unit right tetrahedron, faces outward (normals -z, -y, -x, (1,1,1)).
TriangleMesh tetrahedron() {
  TriangleMesh m;
  m.vertices.resize(4, 3);
  m.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.triangles.resize(4, 3);
  m.triangles << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return m;
}

// `m` without triangles first .. first + count - 1.
TriangleMesh without(TriangleMesh m, Eigen::Index first, Eigen::Index count) {
  const Eigen::Index rest = m.num_triangles() - first - count;
  m.triangles.middleRows(first, rest) = m.triangles.bottomRows(rest).eval();
  m.triangles.conservativeResize(m.num_triangles() - count, 3);
  return m;
}

// Two tetrahedra sharing only vertex 0, a bowtie vertex; the second is the first reflected through
// the origin (a reflection reverses orientation, so its faces are flipped back outward). The
// second's own apex, vertex 4, is left unreferenced.
TriangleMesh bowtie() {
  TriangleMesh b = tetrahedron();
  b.vertices = -b.vertices;
  for (Eigen::Index t = 0; t < b.num_triangles(); ++t) flip(&b, t);
  TriangleMesh m = join(tetrahedron(), b);
  for (Eigen::Index t = 4; t < 8; ++t)
    for (int k = 0; k < 3; ++k)
      if (m.triangles(t, k) == 4) m.triangles(t, k) = 0;  // share the apex
  return m;
}

// Torus around the z axis (radii big_r > small_r), n segments around the axis and m around the
// tube; each quad of the grid split in two. V = nm, E = 3nm, F = 2nm.
TriangleMesh torus(int n, int m, double big_r, double small_r) {
  TriangleMesh t;
  t.vertices.resize(n * m, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const double u = 2 * std::numbers::pi * i / n;
      const double v = 2 * std::numbers::pi * j / m;
      t.vertices.row(i * m + j) << (big_r + small_r * std::cos(v)) * std::cos(u),
          (big_r + small_r * std::cos(v)) * std::sin(u), small_r * std::sin(v);
    }
  }
  t.triangles.resize(2 * n * m, 3);
  const auto id = [&](int i, int j) { return (i % n) * m + (j % m); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      // d/du x d/dv points away from the tube's centre line, so (u, v) order is outward.
      t.triangles.row(2 * (i * m + j)) << id(i, j), id(i + 1, j), id(i + 1, j + 1);
      t.triangles.row(2 * (i * m + j) + 1) << id(i, j), id(i + 1, j + 1), id(i, j + 1);
    }
  }
  return t;
}

TEST(MeshCheck, UnitCube) {
  const MeshCheckReport r = check(unit_cube());
  EXPECT_EQ(r.vertices, 8);
  EXPECT_EQ(r.triangles, 12);
  EXPECT_EQ(r.edges, 18);  // Euler: E = V + F - 2 = 8 + 12 - 2
  EXPECT_EQ(r.components, 1);
  EXPECT_EQ(r.boundary_edges, 0);
  EXPECT_EQ(r.non_manifold_edges, 0);
  EXPECT_EQ(r.non_manifold_vertices, 0);
  EXPECT_EQ(r.misoriented_edges, 0);
  EXPECT_TRUE(r.consistently_oriented);
  EXPECT_EQ(r.degenerate_triangles, 0);
  EXPECT_EQ(r.duplicate_triangles, 0);
  EXPECT_TRUE(r.self_intersections_checked);
  EXPECT_EQ(r.self_intersecting_pairs, 0);
  EXPECT_NEAR(r.area, 6.0, 1e-12);    // six unit squares
  EXPECT_NEAR(r.volume, 1.0, 1e-12);  // 1 x 1 x 1
  ASSERT_TRUE(r.genus.has_value());
  EXPECT_EQ(*r.genus, 0);  // a cube is a sphere
  EXPECT_TRUE(r.closed);
  EXPECT_TRUE(r.manifold);
  EXPECT_TRUE(r.printable);
  EXPECT_TRUE(r.problems.empty());
  EXPECT_TRUE(r.bounding_box.min().isApprox(Eigen::Vector3d(0, 0, 0)));
  EXPECT_TRUE(r.bounding_box.max().isApprox(Eigen::Vector3d(1, 1, 1)));
  ASSERT_FALSE(r.stage_seconds.empty());
  EXPECT_EQ(r.stage_seconds.back().first, "total");
}

TEST(MeshCheck, Tetrahedron) {
  const MeshCheckReport r = check(tetrahedron());
  EXPECT_EQ(r.edges, 6);
  EXPECT_NEAR(r.volume, 1.0 / 6.0, 1e-15);  // base 1/2 x height 1 / 3
  // Three right triangles of area 1/2 and an equilateral one of side sqrt(2): sqrt(3)/4 * 2.
  EXPECT_NEAR(r.area, 1.5 + std::sqrt(3.0) / 2.0, 1e-12);
  ASSERT_TRUE(r.genus.has_value());
  EXPECT_EQ(*r.genus, 0);
  EXPECT_TRUE(r.printable);
}

TEST(MeshCheck, TorusHasGenusOne) {
  const int n = 32;
  const int m = 16;
  const MeshCheckReport r = check(torus(n, m, 2.0, 0.5));
  EXPECT_EQ(r.vertices, n * m);
  EXPECT_EQ(r.edges, 3 * n * m);
  ASSERT_TRUE(r.genus.has_value());
  EXPECT_EQ(*r.genus, 1);  // chi = nm - 3nm + 2nm = 0 = 2 - 2g
  EXPECT_TRUE(r.printable);
  // Pappus: 2 pi^2 R r^2 for the smooth torus; the inscribed polyhedron is a few % smaller.
  const double smooth = 2 * std::numbers::pi * std::numbers::pi * 2.0 * 0.25;
  EXPECT_LT(r.volume, smooth);
  EXPECT_GT(r.volume, 0.95 * smooth);
}

TEST(MeshCheck, TwoDisjointCubes) {
  const MeshCheckReport r = check(join(unit_cube(), box({3, 0, 0}, {4, 1, 1})));
  EXPECT_EQ(r.components, 2);
  EXPECT_NEAR(r.volume, 2.0, 1e-12);
  ASSERT_TRUE(r.genus.has_value());
  EXPECT_EQ(*r.genus, 0);  // 0 + 0
  EXPECT_EQ(r.self_intersecting_pairs, 0);
  EXPECT_TRUE(r.printable);
}

TEST(MeshCheck, OpenBox) {
  // Without the two top triangles (rows 2 and 3) the top square's four edges become boundary.
  const MeshCheckReport r = check(without(unit_cube(), 2, 2));
  EXPECT_EQ(r.boundary_edges, 4);
  EXPECT_EQ(r.edges, 17);  // the cube's 18 less the top diagonal
  EXPECT_FALSE(r.closed);
  EXPECT_FALSE(r.genus.has_value());
  EXPECT_FALSE(r.printable);
  EXPECT_TRUE(r.manifold);
  EXPECT_EQ(to_json(r)["genus"], nullptr);
}

TEST(MeshCheck, CubeWithOneFlippedTriangle) {
  TriangleMesh m = unit_cube();
  flip(&m, 0);
  const MeshCheckReport r = check(m);
  EXPECT_EQ(r.misoriented_edges, 3);  // each of its three edges now runs like its neighbour's
  EXPECT_FALSE(r.consistently_oriented);
  EXPECT_TRUE(r.closed);
  EXPECT_TRUE(r.manifold);
  EXPECT_FALSE(r.printable);
}

TEST(MeshCheck, BowtieVertex) {
  const MeshCheckReport r = check(bowtie());
  EXPECT_EQ(r.unreferenced_vertices, 1);  // the second apex, now unused
  EXPECT_EQ(r.non_manifold_vertices, 1);
  EXPECT_EQ(r.non_manifold_edges, 0);
  EXPECT_EQ(r.components, 2);  // connected through edges, not through the shared vertex
  EXPECT_TRUE(r.closed);
  EXPECT_FALSE(r.manifold);
  EXPECT_FALSE(r.genus.has_value());
  // They touch only in the shared vertex, which is no intersection (the 3 x 3 triangle pairs
  // around it would be reported if the duplicated vertex were not recognised as shared).
  EXPECT_EQ(r.self_intersecting_pairs, 0);
  EXPECT_NEAR(r.volume, 2.0 / 6.0, 1e-15);
  EXPECT_FALSE(r.printable);
}

TEST(MeshCheck, ThreeTrianglesOnOneEdge) {
  TriangleMesh m;
  m.vertices.resize(5, 3);
  m.vertices << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0, 0.5, 0, 1;
  m.triangles.resize(3, 3);
  m.triangles << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  const MeshCheckReport r = check(m);
  EXPECT_EQ(r.non_manifold_edges, 1);
  EXPECT_EQ(r.boundary_edges, 6);         // two free edges per triangle
  EXPECT_EQ(r.edges, 7);                  // 1 shared + 6 free
  EXPECT_EQ(r.non_manifold_vertices, 2);  // 0 and 1: three separate fans each
  EXPECT_EQ(r.components, 1);
  // The two coplanar triangles lie on opposite sides of the shared edge: no overlap.
  EXPECT_EQ(r.self_intersecting_pairs, 0);
  EXPECT_FALSE(r.manifold);
  EXPECT_FALSE(r.printable);
}

TEST(MeshCheck, OverlappingCubesSelfIntersect) {
  const TriangleMesh m = join(unit_cube(), box({0.5, 0.5, 0.5}, {1.5, 1.5, 1.5}));
  const MeshCheckReport r = check(m);
  EXPECT_TRUE(r.closed);
  EXPECT_TRUE(r.manifold);
  EXPECT_GT(r.self_intersecting_pairs, 0);
  EXPECT_FALSE(r.printable);

  // The same count sequentially, and a limit that stops at one pair.
  MeshCheckOptions sequential;
  sequential.parallel = false;
  EXPECT_EQ(check(m, sequential).self_intersecting_pairs, r.self_intersecting_pairs);
  MeshCheckOptions limited;
  limited.max_self_intersecting_pairs = 1;
  const MeshCheckReport l = check(m, limited);
  EXPECT_EQ(l.self_intersecting_pairs, 1);
  EXPECT_TRUE(l.self_intersection_limit_reached);
}

TEST(MeshCheck, SelfIntersectionsCanBeSkipped) {
  MeshCheckOptions options;
  options.check_self_intersections = false;
  const MeshCheckReport r = check(unit_cube(), options);
  EXPECT_FALSE(r.self_intersections_checked);
  EXPECT_FALSE(r.printable);  // undecided without the test
  EXPECT_EQ(to_json(r)["self_intersecting_pairs"], nullptr);
}

TEST(MeshCheck, DegenerateTriangles) {
  // A lone triangle with collinear corners.
  TriangleMesh line;
  line.vertices.resize(3, 3);
  line.vertices << 0, 0, 0, 1, 1, 1, 3, 3, 3;
  line.triangles.resize(1, 3);
  line.triangles << 0, 1, 2;
  EXPECT_EQ(check(line).degenerate_triangles, 1);
  EXPECT_EQ(check(line).area, 0.0);

  // A cube plus a triangle with a repeated corner: degenerate, but the surface is untouched.
  TriangleMesh m = unit_cube();
  m.triangles.conservativeResize(13, 3);
  m.triangles.row(12) << 0, 0, 1;
  const MeshCheckReport r = check(m);
  EXPECT_EQ(r.degenerate_triangles, 1);
  EXPECT_TRUE(r.closed);
  EXPECT_TRUE(r.manifold);
  EXPECT_TRUE(r.printable);
  EXPECT_FALSE(r.warnings.empty());
}

// The unit tetrahedron with edge 0-1 split at its midpoint m: the face on that edge becomes two,
// and the collinear triangle (0, 1, m) closes the crack. V = 5, F = 6, E = 9: closed, genus 0.
TriangleMesh tetrahedron_with_cap() {
  TriangleMesh t;
  t.vertices.resize(5, 3);
  t.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.5, 0, 0;
  t.triangles.resize(6, 3);
  t.triangles << 0, 2, 1, 0, 4, 3, 4, 1, 3, 0, 3, 2, 1, 2, 3, 0, 1, 4;
  return t;
}

TEST(MeshCheck, CollinearCapInClosedSurface) {
  const MeshCheckReport r = check(tetrahedron_with_cap());
  EXPECT_EQ(r.degenerate_triangles, 1);
  EXPECT_EQ(r.edges, 9);
  EXPECT_TRUE(r.closed);
  ASSERT_TRUE(r.genus.has_value());
  EXPECT_EQ(*r.genus, 0);
  EXPECT_NEAR(r.volume, 1.0 / 6.0, 1e-15);
  // The T-junction at m is a contact by CGAL's rule: (0, 2, 1) shares only corner 0 with
  // (0, m, 3) and only corner 1 with (m, 1, 3), yet touches each along half of edge 0-1.
  EXPECT_EQ(r.self_intersecting_pairs, 2);
  EXPECT_FALSE(r.printable);
}

TEST(MeshCheck, DuplicateTriangle) {
  TriangleMesh m = unit_cube();
  m.triangles.conservativeResize(13, 3);
  m.triangles.row(12) << 3, 0, 2;  // triangle 0 again, rotated
  const MeshCheckReport r = check(m);
  EXPECT_EQ(r.duplicate_triangles, 1);
  EXPECT_EQ(r.non_manifold_edges, 3);       // its edges now have three triangles each
  EXPECT_EQ(r.self_intersecting_pairs, 0);  // the copy is not tested against the original
  EXPECT_FALSE(r.printable);
}

TEST(MeshCheck, EmptyMesh) {
  const MeshCheckReport r = check(TriangleMesh{});
  EXPECT_EQ(r.triangles, 0);
  EXPECT_FALSE(r.closed);
  EXPECT_FALSE(r.printable);
  EXPECT_FALSE(r.problems.empty());
  EXPECT_EQ(to_json(r)["bounding_box"], nullptr);
}

TEST(MeshCheck, RejectsBadIndicesAndCoordinates) {
  TriangleMesh m = unit_cube();
  m.triangles(5, 1) = 8;
  auto r = check_mesh(m);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("triangle 5"), std::string::npos);

  m = unit_cube();
  m.triangles(0, 0) = -1;
  EXPECT_EQ(check_mesh(m).status().code(), StatusCode::kInvalidArgument);

  m = unit_cube();
  m.vertices(3, 2) = std::nan("");
  EXPECT_EQ(check_mesh(m).status().code(), StatusCode::kInvalidArgument);

  // A non-finite vertex that no triangle uses is only unreferenced.
  m = unit_cube();
  m.vertices.conservativeResize(9, 3);
  m.vertices.row(8) << INFINITY, 0, 0;
  EXPECT_TRUE(check_mesh(m).ok());
}

TEST(MeshCheck, JsonAndText) {
  const MeshCheckReport r = check(unit_cube());
  const nlohmann::json j = to_json(r);
  for (const char* key : {"vertices",
                          "triangles",
                          "components",
                          "boundary_edges",
                          "non_manifold_edges",
                          "non_manifold_vertices",
                          "consistently_oriented",
                          "self_intersecting_pairs",
                          "volume",
                          "genus",
                          "printable",
                          "bounding_box",
                          "problems",
                          "stage_seconds",
                          "misoriented_edges",
                          "degenerate_triangles",
                          "duplicate_triangles",
                          "unreferenced_vertices",
                          "edges",
                          "area",
                          "closed",
                          "manifold"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["genus"], 0);
  EXPECT_EQ(j["printable"], true);
  EXPECT_EQ(j["bounding_box"]["max"][0], 1.0);
  EXPECT_TRUE(j["stage_seconds"].contains("self_intersections"));
  const std::string text = to_text(r);
  EXPECT_NE(text.find("printable"), std::string::npos);
  EXPECT_NE(text.find("yes"), std::string::npos);

  const std::string open_text = to_text(check(without(unit_cube(), 11, 1)));
  EXPECT_NE(open_text.find("problem: 3 edges lie on a single triangle"), std::string::npos)
      << open_text;
}

// --- repair ---------------------------------------------------------------------------------

// Each triangle with its own three corners, as an STL file stores them.
TriangleMesh unwelded(const TriangleMesh& m) {
  TriangleMesh soup;
  soup.vertices.resize(3 * m.num_triangles(), 3);
  soup.triangles.resize(m.num_triangles(), 3);
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    for (int k = 0; k < 3; ++k) {
      soup.vertices.row(3 * t + k) = m.vertices.row(m.triangles(t, k));
      soup.triangles(t, k) = static_cast<int>(3 * t + k);
    }
  }
  return soup;
}

TEST(MeshRepair, WeldsExactCopies) {
  TriangleMesh m = unwelded(unit_cube());
  ASSERT_FALSE(check(m).closed);
  const MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.merged_vertices, 36 - 8);  // 12 x 3 corners on 8 positions
  EXPECT_EQ(m.num_vertices(), 8);
  EXPECT_EQ(m.num_triangles(), 12);
  EXPECT_EQ(s.flipped_triangles, 0);
  EXPECT_TRUE(s.closed);
  EXPECT_TRUE(s.printable);
  EXPECT_NEAR(s.after.volume, 1.0, 1e-12);
}

TEST(MeshRepair, WeldsWithinTolerance) {
  TriangleMesh m = unwelded(unit_cube());
  for (Eigen::Index v = 0; v < m.num_vertices(); ++v)
    m.vertices.row(v) += Eigen::RowVector3d(1e-7, -1e-7, 0.5e-7) * static_cast<double>(v % 3);
  TriangleMesh exact = m;
  EXPECT_FALSE(repair(&exact).closed);  // copies differ by up to 2 x 1.5e-7

  MeshRepairOptions options;
  options.weld_tolerance = 1e-5;
  const MeshRepairSummary s = repair(&m, options);
  EXPECT_EQ(m.num_vertices(), 8);
  EXPECT_TRUE(s.printable);
  EXPECT_NEAR(s.after.volume, 1.0, 1e-5);
}

TEST(MeshRepair, OrientsConsistentlyAndOutward) {
  TriangleMesh m = unit_cube();
  flip(&m, 0);
  MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.flipped_triangles, 1);
  EXPECT_TRUE(s.printable);
  EXPECT_NEAR(s.after.volume, 1.0, 1e-12);

  TriangleMesh inside_out = unit_cube();
  for (Eigen::Index t = 0; t < 12; ++t) flip(&inside_out, t);
  ASSERT_NEAR(check(inside_out).volume, -1.0, 1e-12);
  s = repair(&inside_out);
  EXPECT_EQ(s.flipped_triangles, 12);
  EXPECT_NEAR(s.after.volume, 1.0, 1e-12);
  EXPECT_TRUE(s.printable);
}

TEST(MeshRepair, InnerShellOfHollowPartPointsInward) {
  // Outer box 3^3 and inner box 1^3, both outward: volume 28 before, 27 - 1 = 26 after.
  TriangleMesh m = join(box({0, 0, 0}, {3, 3, 3}), box({1, 1, 1}, {2, 2, 2}));
  ASSERT_NEAR(check(m).volume, 28.0, 1e-12);
  const MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.flipped_triangles, 12);
  EXPECT_NEAR(s.after.volume, 26.0, 1e-12);
  EXPECT_TRUE(s.printable);
}

TEST(MeshRepair, RemovesDuplicatesDegeneratesAndUnreferenced) {
  TriangleMesh m = unit_cube();
  m.triangles.conservativeResize(14, 3);
  m.triangles.row(12) << 0, 3, 2;  // triangle 0 reversed
  m.triangles.row(13) << 5, 5, 1;  // repeated corner
  m.vertices.conservativeResize(10, 3);
  m.vertices.row(8) << 7, 7, 7;
  m.vertices.row(9) << NAN, 0, 0;  // unused, so harmless
  const MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.removed_duplicate_triangles, 1);
  EXPECT_EQ(s.removed_degenerate_triangles, 1);
  EXPECT_EQ(s.removed_unreferenced_vertices, 2);
  EXPECT_EQ(m.num_vertices(), 8);
  EXPECT_EQ(m.num_triangles(), 12);
  EXPECT_TRUE(s.printable);
}

TEST(MeshRepair, RemovesCollinearCapWithoutOpeningTheSurface) {
  TriangleMesh m = tetrahedron_with_cap();
  const MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.removed_degenerate_triangles, 1);
  EXPECT_EQ(s.after.degenerate_triangles, 0);
  EXPECT_TRUE(s.closed);  // dropping the cap alone would leave three boundary edges
  EXPECT_TRUE(s.printable);
  EXPECT_NEAR(s.after.volume, 1.0 / 6.0, 1e-15);
}

TEST(MeshRepair, KeepsWhatOptionsSayToKeep) {
  TriangleMesh m = unit_cube();
  m.triangles.conservativeResize(13, 3);
  m.triangles.row(12) << 5, 5, 1;
  m.vertices.conservativeResize(9, 3);
  m.vertices.row(8) << 7, 7, 7;
  MeshRepairOptions options;
  options.remove_degenerate_triangles = false;
  options.remove_unreferenced_vertices = false;
  const MeshRepairSummary s = repair(&m, options);
  EXPECT_EQ(m.num_triangles(), 13);
  EXPECT_EQ(m.num_vertices(), 9);
  EXPECT_EQ(s.after.degenerate_triangles, 1);
  EXPECT_FALSE(s.changed());
}

TEST(MeshRepair, OpenBoxStaysOpenAndSaysSo) {
  TriangleMesh m = without(unit_cube(), 2, 2);
  const MeshRepairSummary s = repair(&m);
  EXPECT_FALSE(s.closed);
  EXPECT_FALSE(s.printable);
  EXPECT_EQ(s.after.boundary_edges, 4);  // the missing top's rim, as before
}

TEST(MeshRepair, SplitsBowtieVertex) {
  TriangleMesh m = bowtie();
  const MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.split_non_manifold_vertices, 1);
  EXPECT_TRUE(s.after.manifold);
  EXPECT_TRUE(s.closed);
  // The two tetrahedra now touch at two distinct vertices in one place: that is an intersection
  // (3 x 3 triangles around the point), so the repair must not call it printable.
  EXPECT_EQ(s.after.self_intersecting_pairs, 9);
  EXPECT_FALSE(s.printable);
}

TEST(MeshRepair, IsIdempotent) {
  TriangleMesh m = unwelded(unit_cube());
  flip(&m, 4);
  repair(&m);
  const TriangleMesh once = m;
  const MeshRepairSummary again = repair(&m);
  EXPECT_FALSE(again.changed());
  EXPECT_EQ(m.vertices, once.vertices);
  EXPECT_EQ(m.triangles, once.triangles);
}

TEST(MeshRepair, RejectsBadInput) {
  TriangleMesh m = unit_cube();
  MeshRepairSummary s;
  MeshRepairOptions bad;
  bad.weld_tolerance = -1.0;
  EXPECT_EQ(repair_mesh(bad, &m, &s).code(), StatusCode::kInvalidArgument);
  bad.weld_tolerance = std::nan("");
  EXPECT_FALSE(bad.validate().ok());
  EXPECT_EQ(repair_mesh(MeshRepairOptions{}, nullptr, &s).code(), StatusCode::kInvalidArgument);
  m.triangles(0, 0) = 99;
  EXPECT_EQ(repair_mesh(MeshRepairOptions{}, &m, &s).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(m.triangles(0, 0), 99);  // untouched on failure
}

TEST(MeshRepair, DropsVertexUsedOnlyByADroppedTriangle) {
  TriangleMesh m = tetrahedron();
  m.vertices.conservativeResize(5, 3);
  m.vertices.row(4) << 2, 2, 2;
  m.triangles.conservativeResize(5, 3);
  m.triangles.row(4) << 0, 4, 4;  // repeated corner: dropped, and vertex 4 with it
  const MeshRepairSummary s = repair(&m);
  EXPECT_EQ(s.removed_degenerate_triangles, 1);
  EXPECT_EQ(s.removed_unreferenced_vertices, 1);
  EXPECT_EQ(m.num_vertices(), 4);
  EXPECT_TRUE(s.printable);
  EXPECT_NEAR(s.after.volume, 1.0 / 6.0, 1e-15);
}

TEST(MeshRepair, KeptOppositeCopiesAreNotFlips) {
  // A triangle and its reverse: a closed two-sided sheet of zero volume.
  TriangleMesh m;
  m.vertices.resize(3, 3);
  m.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  m.triangles.resize(2, 3);
  m.triangles << 0, 1, 2, 1, 0, 2;
  MeshRepairOptions keep;
  keep.remove_duplicate_triangles = false;
  const MeshRepairSummary s = repair(&m, keep);
  EXPECT_EQ(s.flipped_triangles, 0);
  EXPECT_EQ(m.num_triangles(), 2);
  EXPECT_TRUE(s.closed);
  EXPECT_FALSE(s.printable);  // zero volume
  EXPECT_FALSE(repair(&m, keep).changed());
}

// Inputs on which fuzz_mesh_check once found a second repair still changing something: removing
// a collinear triangle rejoined sheets the first orientation had split, pinched the surface into
// a new non-manifold vertex, or recreated an existing triangle. Corners on a half-unit grid.
TEST(MeshRepair, ReachesItsFixedPointInOnePass) {
  const auto mesh = [](std::vector<Eigen::RowVector3d> v, std::vector<Eigen::RowVector3i> t) {
    TriangleMesh m;
    m.vertices.resize(static_cast<Eigen::Index>(v.size()), 3);
    for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(static_cast<Eigen::Index>(i)) = v[i];
    m.triangles.resize(static_cast<Eigen::Index>(t.size()), 3);
    for (std::size_t i = 0; i < t.size(); ++i) m.triangles.row(static_cast<Eigen::Index>(i)) = t[i];
    return m;
  };
  const std::vector<TriangleMesh> cases = {
      mesh({{-2, 1, -2}, {0, -2, -2}, {-2, -2, -2}, {-2, -1, -0.5}, {-1, -0.5, -2}},
           {{0, 4, 1}, {4, 2, 1}, {3, 1, 0}}),
      mesh({{-2, -2, 1}, {-2, -2, -1.5}, {-2, -2, 1.5}, {1.5, -1, -1.5}, {-0.5, -0.5, -0.5}},
           {{0, 1, 4}, {2, 0, 1}, {3, 4, 2}, {0, 0, 4}}),
      mesh({{-2, 1, -2}, {-2, -2, -1.5}, {-2, -2, -2}, {-2, -0.5, -2}, {-1.5, -1.5, -0.5}},
           {{3, 4, 0}, {2, 3, 4}, {2, 3, 0}, {1, 3, 2}}),
      mesh({{-2, 1, -2}, {-2, -2, -1.5}, {-2, -2, -2}, {-2, -0.5, -2}, {-1.5, -1.5, -0.5}},
           {{1, 4, 0}, {2, 3, 4}, {0, 1, 2}, {3, 0, 1}, {0, 2, 3}}),
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(i);
    TriangleMesh m = cases[i];
    const MeshRepairSummary first = repair(&m);
    EXPECT_TRUE(first.changed());
    const TriangleMesh once = m;
    const MeshRepairSummary second = repair(&m);
    EXPECT_EQ(second.removed_degenerate_triangles, 0);
    EXPECT_EQ(second.removed_duplicate_triangles, 0);
    EXPECT_EQ(second.flipped_triangles, 0);
    // Welding merges the copies of a split vertex, which orientation splits again.
    EXPECT_EQ(second.merged_vertices, second.split_non_manifold_vertices);
    EXPECT_EQ(m.num_triangles(), once.num_triangles());
    EXPECT_EQ(m.num_vertices(), once.num_vertices());
    nlohmann::json before = to_json(first.after);
    nlohmann::json after = to_json(second.after);
    before.erase("stage_seconds");
    after.erase("stage_seconds");
    EXPECT_EQ(after, before);
  }
}

TEST(MeshRepair, JsonAndText) {
  TriangleMesh m = unit_cube();
  flip(&m, 2);
  const MeshRepairSummary s = repair(&m);
  const nlohmann::json j = to_json(s);
  EXPECT_EQ(j["flipped_triangles"], 1);
  EXPECT_EQ(j["changed"], true);
  EXPECT_EQ(j["printable"], true);
  EXPECT_EQ(j["before"]["consistently_oriented"], false);
  EXPECT_EQ(j["after"]["consistently_oriented"], true);
  EXPECT_NE(to_text(s).find("flipped triangles"), std::string::npos);
}

}  // namespace
}  // namespace hc::fabrication
