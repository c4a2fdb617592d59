// TetGen wrapper against TetGen 1.5.0's own reference output, box specimens against exact
// volumes and conformity, and corpus surfaces against their enclosed volume.
#include "processing/meshing/tetrahedralize.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <limits>
#include <map>
#include <set>

#include "common/file_io.h"
#include "common/mesh_io.h"
#include "common/tet_mesh_io.h"
#include "test_data.h"

namespace hc::meshing {
namespace {

using ::testing::HasSubstr;
using testing::shared_data;

// Faces of all tets, sorted corner triples → how many tets share them.
std::map<std::array<int, 3>, int> face_counts(const TetMesh& m) {
  std::map<std::array<int, 3>, int> faces;
  static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (Eigen::Index t = 0; t < m.num_tets(); ++t)
    for (const auto& f : kFace) {
      std::array<int, 3> k = {m.tets(t, f[0]), m.tets(t, f[1]), m.tets(t, f[2])};
      std::sort(k.begin(), k.end());
      ++faces[k];
    }
  return faces;
}

// Volume enclosed by a closed outward-oriented surface (divergence theorem).
double enclosed_volume(const TriangleMesh& s) {
  double v = 0;
  for (Eigen::Index f = 0; f < s.num_triangles(); ++f) {
    const Eigen::Vector3d a = s.vertices.row(s.triangles(f, 0)).transpose();
    const Eigen::Vector3d b = s.vertices.row(s.triangles(f, 1)).transpose();
    const Eigen::Vector3d c = s.vertices.row(s.triangles(f, 2)).transpose();
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

double radius_edge_ratio(const TetMesh& m, Eigen::Index t) {
  Eigen::Vector3d p[4];
  for (int k = 0; k < 4; ++k) p[k] = m.nodes.row(m.tets(t, k)).transpose();
  Eigen::Matrix3d A;
  Eigen::Vector3d rhs;
  for (int k = 0; k < 3; ++k) {
    A.row(k) = (p[k + 1] - p[0]).transpose();
    rhs[k] = 0.5 * (p[k + 1] - p[0]).squaredNorm();
  }
  const double r = A.colPivHouseholderQr().solve(rhs).norm();
  double shortest = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) shortest = std::min(shortest, (p[a] - p[b]).norm());
  return r / shortest;
}

struct PolyCase {
  double quality;
  double max_volume;
  Eigen::Index points, tets, faces_on_facets;
};

// ../shared/data/fem/tetgen/tetgen_1.5.0_reference_counts.txt: Debian tetgen 1.5.0-5 run as
// `tetgen -p`, `-pq`, `-pq1.414a0.1`, `-pq1.2a0.05` on example.poly.
class PolyReference : public ::testing::TestWithParam<PolyCase> {};

TEST_P(PolyReference, MatchesTetgenCommandLineCounts) {
  const PolyCase& c = GetParam();
  TetrahedralizeOptions o;
  o.max_radius_edge_ratio = c.quality;
  o.max_volume = c.max_volume;
  TetrahedralizeSummary s;
  Result<TetMesh> m = tetrahedralize_poly(shared_data("fem/tetgen/example.poly"), o, &s);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_nodes(), c.points) << s.switches;
  EXPECT_EQ(m->num_tets(), c.tets) << s.switches;
  EXPECT_EQ(s.boundary_faces, c.faces_on_facets) << s.switches;
  for (Eigen::Index t = 0; t < m->num_tets(); ++t) ASSERT_GT(tet_signed_volume(*m, t), 0);
  if (c.max_volume > 0) {
    EXPECT_LE(s.max_tet_volume, c.max_volume * (1 + 1e-12));
  }
  // Every refinement fills the same domain: its volume is that of TetGen's own -pq1.414a0.1
  // output (read back from the reference files).
  Result<TetMesh> ref = read_tetgen(shared_data("fem/tetgen/example_pq1.414a0.1/example.1"));
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_NEAR(total_volume(*m), total_volume(*ref), 1e-12 * total_volume(*ref));
  // Faces: interior ones shared by two tets, the rest on the boundary; TetGen's "faces on
  // facets" also counts faces on facets inside the domain (example.poly has internal facets).
  Eigen::Index boundary = 0;
  for (const auto& [face, count] : face_counts(*m)) {
    ASSERT_LE(count, 2);
    if (count == 1) ++boundary;
  }
  EXPECT_LE(boundary, c.faces_on_facets);
  EXPECT_GT(boundary, c.faces_on_facets * 9 / 10);
}

INSTANTIATE_TEST_SUITE_P(Example, PolyReference,
                         ::testing::Values(PolyCase{0, 0, 28, 68, 50},
                                           PolyCase{2.0, 0, 209, 672, 416},
                                           PolyCase{1.414, 0.1, 482, 1533, 928},
                                           PolyCase{1.2, 0.05, 977, 3762, 1558}));

TEST(Poly, SameNodesAsTetgenReferenceOutput) {
  TetrahedralizeOptions o;
  o.max_radius_edge_ratio = 1.414;
  o.max_volume = 0.1;
  Result<TetMesh> m = tetrahedralize_poly(shared_data("fem/tetgen/example.poly"), o);
  Result<TetMesh> ref = read_tetgen(shared_data("fem/tetgen/example_pq1.414a0.1/example.1"));
  ASSERT_TRUE(m.ok() && ref.ok());
  ASSERT_EQ(m->num_nodes(), ref->num_nodes());
  // The reference file prints 16 significant digits at most: compare to that.
  EXPECT_LT((m->nodes - ref->nodes).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Poly, RegionAttributesFromTheFile) {
  // example.poly's region list: attribute 10 seeded at (1, 0.25, 0.1) and 20 at (1, 0.5, 4);
  // both must appear when region attributes are requested.
  TetrahedralizeOptions o;
  Result<TetMesh> m = tetrahedralize_poly(shared_data("fem/tetgen/example.poly"), o, nullptr, true);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  ASSERT_EQ(m->tet_regions.size(), static_cast<std::size_t>(m->num_tets()));
  std::set<int> seen(m->tet_regions.begin(), m->tet_regions.end());
  EXPECT_EQ(seen, (std::set<int>{10, 20}));
}

TEST(Poly, BadFiles) {
  testing::ScratchDir dir;
  TetrahedralizeOptions o;
  EXPECT_EQ(tetrahedralize_poly(dir / "missing.poly", o).status().code(), StatusCode::kNotFound);
  ASSERT_TRUE(write_file_atomic(dir / "junk.poly", "this is not a poly file\n").ok());
  Result<TetMesh> junk = tetrahedralize_poly(dir / "junk.poly", o);
  ASSERT_FALSE(junk.ok());
  EXPECT_EQ(junk.status().code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(tetrahedralize_poly(dir / "x.off", o).ok());
}

TEST(Poly, ParsesExampleSections) {
  Result<std::string> bytes = read_file(shared_data("fem/tetgen/example.poly"));
  ASSERT_TRUE(bytes.ok());
  Result<Plc> plc = parse_poly(*bytes, "example.poly");
  ASSERT_TRUE(plc.ok()) << plc.status().to_string();
  EXPECT_EQ(plc->points.rows(), 28);
  ASSERT_EQ(plc->facets.size(), 23u);
  EXPECT_EQ(plc->facets[2].polygons.size(), 2u);  // facet 3: two polygons and one hole
  EXPECT_EQ(plc->facets[2].holes.size(), 1u);
  EXPECT_EQ(plc->facets[2].marker, 3);
  EXPECT_EQ(plc->facets[0].polygons[0], (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(plc->holes.size(), 2u);
  ASSERT_EQ(plc->regions.size(), 2u);
  EXPECT_EQ(plc->regions[1].attribute, 20);
  EXPECT_EQ(plc->regions[1].max_volume, 0.01);
}

struct BadPoly {
  std::string text;
  std::string expect;
};
class PolyMalformed : public ::testing::TestWithParam<BadPoly> {};
TEST_P(PolyMalformed, ClearError) {
  Result<Plc> plc = parse_poly(GetParam().text, "t.poly");
  ASSERT_FALSE(plc.ok()) << GetParam().text;
  EXPECT_EQ(plc.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(plc.status().message(), HasSubstr(GetParam().expect));
}
const std::string kTetPoints = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
INSTANTIATE_TEST_SUITE_P(
    Cases, PolyMalformed,
    ::testing::Values(
        BadPoly{"", "t.poly:1: file ends before the number of points"},
        BadPoly{"0 3 0 0\n", "points in a separate .node file"},
        BadPoly{"4 2 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", "dimension 2"},
        BadPoly{"99999 3 0 0\n1 0 0 0\n", "t.poly:1: the number of points 99999 needs"},
        BadPoly{"4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 nan\n4 0 0 1\n", "t.poly:4: coordinate z"},
        BadPoly{"4 3 0 0\n1 0 0 0\n3 1 0 0\n3 0 1 0\n4 0 0 1\n", "t.poly:3: point index 3"},
        BadPoly{kTetPoints, "file ends before the number of facets"},
        BadPoly{kTetPoints + "1 0\n1\n3 1 2 9\n", "t.poly:8: facet 1: point index 9 out of range"},
        BadPoly{kTetPoints + "1 0\n0\n", "facet 1 has no polygon"},
        BadPoly{kTetPoints + "1 0\n1\n3 1 2\n", "file ends before a polygon corner"},
        BadPoly{kTetPoints + "1 0\n1\n3 1 2 3\n1\n1 0 0\n",
                "file ends before coordinate z of hole 1"},
        BadPoly{kTetPoints + "1 0\n1\n3 1 2 3\n0\n1\n1 0 0 0 0.5 -1\n",
                "attribute 0.5 is not an integer"},
        BadPoly{kTetPoints + "1 0\n1\n3 1 2 3\n0\n0\nextra\n", "unexpected text"}));

TEST(Options, ValidateAndSwitches) {
  TetrahedralizeOptions o;
  o.max_radius_edge_ratio = 1.414;
  o.max_volume = 0.1;
  EXPECT_EQ(o.tetgen_switches(), "pq1.414a0.1Q");
  o.max_radius_edge_ratio = 0.9;
  EXPECT_THAT(o.validate().message(), HasSubstr(">= 1.1"));
  o.max_radius_edge_ratio = 1.05;  // below TetGen's practical termination bound
  EXPECT_FALSE(o.validate().ok());
  o.max_radius_edge_ratio = 1.1;
  EXPECT_TRUE(o.validate().ok());
  o.max_radius_edge_ratio = 2;
  o.max_volume = -1;
  EXPECT_FALSE(o.validate().ok());
}

// The thesis's specimen: a 50 × 50 × 25 mm block (Sec. 4.4).
const Eigen::Vector3d kBlock(0.05, 0.05, 0.025);

TEST(StructuredBox, ExactVolumeConformingAndMarked) {
  Result<TetMesh> m = structured_box(kBlock, Eigen::Vector3i(10, 10, 5));
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_EQ(m->num_nodes(), 11 * 11 * 6);
  EXPECT_EQ(m->num_tets(), 6 * 10 * 10 * 5);
  const double cell = 0.005 * 0.005 * 0.005;
  for (Eigen::Index t = 0; t < m->num_tets(); ++t)
    ASSERT_NEAR(tet_signed_volume(*m, t), cell / 6, 1e-12 * cell) << t;
  EXPECT_NEAR(total_volume(*m), 0.05 * 0.05 * 0.025, 1e-15);
  // Conforming: interior faces shared by exactly 2 tets; boundary = 2 triangles per boundary
  // quad: 2 · 2 · (10·10 + 10·5 + 10·5) = 800.
  int boundary = 0;
  for (const auto& [face, count] : face_counts(*m)) {
    ASSERT_LE(count, 2);
    boundary += count == 1;
  }
  EXPECT_EQ(boundary, 800);
  const std::vector<int> bottom = nodes_with_marker(*m, kMarkerBottom);
  EXPECT_EQ(bottom.size(), 121u);
  for (int i : bottom) EXPECT_EQ(m->nodes(i, 2), 0.0);
  EXPECT_EQ(nodes_with_marker(*m, kMarkerTop).size(), 121u);
  EXPECT_EQ(nodes_with_marker(*m, kMarkerInterior).size(), 9u * 9u * 4u);
  EXPECT_EQ(nodes_on_plane(*m, 2, 0.0, 1e-12), bottom);
}

TEST(StructuredBox, BadArguments) {
  EXPECT_FALSE(structured_box(Eigen::Vector3d(0, 1, 1), Eigen::Vector3i(1, 1, 1)).ok());
  EXPECT_FALSE(structured_box(kBlock, Eigen::Vector3i(0, 1, 1)).ok());
  EXPECT_FALSE(structured_box(Eigen::Vector3d(1, NAN, 1), Eigen::Vector3i(1, 1, 1)).ok());
}

TEST(BoxTetMesh, QualityAndVolumeBoundsHold) {
  TetrahedralizeOptions o;
  o.max_radius_edge_ratio = 1.414;
  o.max_volume = 1e-7;  // m³: about 600+ tets in the 6.25e-5 m³ block
  TetrahedralizeSummary s;
  Result<TetMesh> m = box_tet_mesh(kBlock, o, &s);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  EXPECT_GE(m->num_tets(), 625);
  EXPECT_NEAR(total_volume(*m), 0.05 * 0.05 * 0.025, 1e-12 * 6.25e-5);
  EXPECT_LE(s.max_tet_volume, 1e-7 * (1 + 1e-9));
  double worst = 0;
  for (Eigen::Index t = 0; t < m->num_tets(); ++t)
    worst = std::max(worst, radius_edge_ratio(*m, t));
  // TetGen's guarantee for a PLC with no small input angles (the box has only right angles).
  EXPECT_LE(worst, 1.414 * (1 + 1e-6));
  const std::vector<int> bottom = nodes_with_marker(*m, kMarkerBottom);
  EXPECT_GE(bottom.size(), 4u);
  for (int i : bottom) EXPECT_EQ(m->nodes(i, 2), 0.0);
  EXPECT_EQ(bottom, nodes_on_plane(*m, 2, 0.0, 1e-15));
}

// Closed corpus surfaces (../shared/data/MANIFEST.md says which are closed): the tets fill the
// enclosed volume (TetGen keeps the input surface with 'p').
TEST(Surface, CorpusMeshesFillTheirVolume) {
  for (const char* name : {"bunny.obj", "pinion.off", "example001.stl"}) {
    Result<TriangleMesh> s = read_mesh(shared_data("meshes") / name);
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    TetrahedralizeOptions o;
    TetrahedralizeSummary sum;
    Result<TetMesh> m = tetrahedralize(*s, o, &sum);
    ASSERT_TRUE(m.ok()) << name << ": " << m.status().to_string();
    const double v = enclosed_volume(*s);
    // Not exact: the Steiner points TetGen adds on facets during quality refinement are rounded
    // off the input planes (measured: up to 9e-6 relative on pinion.off).
    EXPECT_NEAR(total_volume(*m), v, 2e-5 * std::abs(v)) << name;
    EXPECT_GE(m->num_nodes(), s->num_vertices()) << name;
    std::size_t boundary = nodes_with_marker(*m, 1).size();
    EXPECT_GE(boundary, static_cast<std::size_t>(s->num_vertices())) << name;
    for (Eigen::Index t = 0; t < m->num_tets(); ++t) ASSERT_GT(tet_signed_volume(*m, t), 0);
  }
}

TEST(Surface, BadSurfaces) {
  TetrahedralizeOptions o;
  TriangleMesh empty;
  EXPECT_THAT(tetrahedralize(empty, o).status().message(), HasSubstr("at least 4"));
  TriangleMesh box = box_surface(Eigen::Vector3d(1, 1, 1));
  box.triangles(0, 0) = 99;
  EXPECT_THAT(tetrahedralize(box, o).status().message(), HasSubstr("out of range"));
  box = box_surface(Eigen::Vector3d(1, 1, 1));
  box.vertices(0, 0) = NAN;
  EXPECT_THAT(tetrahedralize(box, o).status().message(), HasSubstr("non-finite"));
  // Open (MANIFEST.md: ChineseDragon-10kv.off has 6 boundary edges) or misoriented
  // (blobby-shuffled.off) surfaces are refused before TetGen sees them.
  for (const char* name : {"ChineseDragon-10kv.off", "blobby-shuffled.off"}) {
    Result<TriangleMesh> s = read_mesh(shared_data("meshes") / name);
    ASSERT_TRUE(s.ok());
    Result<TetMesh> m = tetrahedralize(*s, o);
    ASSERT_FALSE(m.ok()) << name;
    EXPECT_EQ(m.status().code(), StatusCode::kInvalidArgument);
    EXPECT_THAT(m.status().message(), HasSubstr("not closed")) << name;
  }
  // Closed and oriented but self-intersecting (candleStand.stl: 10 intersecting pairs, see
  // tests/unit/tools): refused here too, where TetGen 1.5.0 would free its memory twice.
  {
    Result<TriangleMesh> s = read_mesh(shared_data("meshes") / "candleStand.stl");
    ASSERT_TRUE(s.ok());
    Result<TetMesh> m = tetrahedralize(*s, o);
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.status().code(), StatusCode::kInvalidArgument);
    EXPECT_THAT(m.status().message(), HasSubstr("intersects itself"));
  }
  box = box_surface(Eigen::Vector3d(1, 1, 1));
  std::swap(box.triangles(0, 1), box.triangles(0, 2));  // one flipped triangle
  EXPECT_THAT(tetrahedralize(box, o).status().message(), HasSubstr("not closed"));
  box.triangles.conservativeResize(11, 3);  // a hole
  EXPECT_THAT(tetrahedralize(box, o).status().message(), HasSubstr("not closed"));
}

}  // namespace
}  // namespace hc::meshing
