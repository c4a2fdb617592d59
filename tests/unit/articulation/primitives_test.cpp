// The joint-hull solids: closed and outward, their volumes against the closed forms, faceting on
// the promised side of the true surface; and geometry/mesh_proximity.h on boxes with known gaps.
#include "fabrication/articulation/primitives.h"

#include <gtest/gtest.h>

#include <map>
#include <numbers>
#include <utility>

#include "geometry/mesh_proximity.h"

namespace hc::articulation {
namespace {

// Every directed edge once, and its reverse once: closed, manifold along edges, consistently
// oriented.
bool closed_and_oriented(const TriangleMesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) ++directed[{m.triangles(t, k), m.triangles(t, (k + 1) % 3)}];
  for (const auto& [e, count] : directed) {
    if (count != 1) return false;
    auto it = directed.find({e.second, e.first});
    if (it == directed.end() || it->second != 1) return false;
  }
  return true;
}

// Smallest and largest distance of the mesh's facets' centroids and vertices from the origin.
std::pair<double, double> radial_extent(const TriangleMesh& m) {
  double lo = 1e9, hi = 0;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    const Eigen::Vector3d a = m.vertices.row(m.triangles(t, 0)),
                          b = m.vertices.row(m.triangles(t, 1)),
                          c = m.vertices.row(m.triangles(t, 2));
    const Eigen::Vector3d nrm = (b - a).cross(c - a).normalized();
    lo = std::min(lo, std::abs(nrm.dot(a)));  // distance of the facet's plane
    hi = std::max({hi, a.norm(), b.norm(), c.norm()});
  }
  return {lo, hi};
}

TEST(Primitives, SpheresAreClosedAndFacetedOnTheirSide) {
  const double r = 2.0;
  const TriangleMesh in = sphere_mesh(r, 40, Facet::kInscribed);
  const TriangleMesh out = sphere_mesh(r, 40, Facet::kCircumscribed);
  for (const TriangleMesh* m : {&in, &out}) EXPECT_TRUE(closed_and_oriented(*m));
  const double v = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  EXPECT_LT(enclosed_volume(in), v);
  EXPECT_GT(enclosed_volume(in), 0.98 * v);
  EXPECT_GT(enclosed_volume(out), v);
  EXPECT_NEAR(radial_extent(in).second, r, 1e-12);  // vertices on the sphere
  EXPECT_GE(radial_extent(out).first, r - 1e-12);   // facets outside it
}

TEST(Primitives, ConeSectorVolumeIsTheSphericalSector) {
  // Spherical sector of half-angle psi: V = 2/3 pi R^3 (1 - cos psi).
  for (double psi : {0.4, 1.2, 2.0}) {
    SCOPED_TRACE(psi);
    const TriangleMesh m =
        cone_sector_mesh([psi](double) { return psi; }, 1.0, 96, Facet::kInscribed);
    EXPECT_TRUE(closed_and_oriented(m));
    EXPECT_NEAR(enclosed_volume(m), 2.0 / 3.0 * std::numbers::pi * (1 - std::cos(psi)), 0.01);
  }
  // Circumscribed sides: points just inside the true cone (polar angle 0.995 psi, half-way to
  // the cap) are inside the 12-sided mesh cone in every direction; with inscribed sides, the
  // points between two generatrices are not.
  const double psi = 0.5;
  const auto cone = [psi](Facet f) {
    return std::move(geometry::MeshProximity::build(
                         cone_sector_mesh([psi](double) { return psi; }, 1.0, 12, f)))
        .value();
  };
  const geometry::MeshProximity out = cone(Facet::kCircumscribed), in = cone(Facet::kInscribed);
  int outside_inscribed = 0;
  for (int k = 0; k < 120; ++k) {
    const double theta = 2 * std::numbers::pi * (k + 0.5) / 120, beta = 0.995 * psi;
    const Eigen::Vector3d p =
        0.5 * Eigen::Vector3d(std::sin(beta) * std::sin(theta), std::cos(beta),
                              std::sin(beta) * std::cos(theta));
    EXPECT_TRUE(out.contains(p)) << theta;
    if (!in.contains(p)) ++outside_inscribed;
  }
  EXPECT_GT(outside_inscribed, 60);
}

TEST(Primitives, CylindersAndSectorPrisms) {
  const TriangleMesh c = cylinder_mesh(1.0, -1.0, 2.0, 64, Facet::kInscribed);
  EXPECT_TRUE(closed_and_oriented(c));
  EXPECT_NEAR(enclosed_volume(c), std::numbers::pi * 3.0, 0.02 * 3);
  EXPECT_GT(enclosed_volume(cylinder_mesh(1.0, -1.0, 2.0, 64, Facet::kCircumscribed)),
            std::numbers::pi * 3.0);
  // Annular sector: 1/2 (r1^2 - r0^2) (phi1 - phi0) (x1 - x0).
  const TriangleMesh ring =
      sector_prism_mesh(1.0, 3.0, -0.5, 1.0, 0.0, 2.0, 256, Facet::kInscribed);
  EXPECT_TRUE(closed_and_oriented(ring));
  EXPECT_NEAR(enclosed_volume(ring), 0.5 * 8.0 * 1.5 * 2.0, 0.01 * 12);
  const TriangleMesh wedge =
      sector_prism_mesh(0.0, 2.0, -0.3, 0.3, -1.0, 1.0, 256, Facet::kInscribed);
  EXPECT_TRUE(closed_and_oriented(wedge));
  EXPECT_NEAR(enclosed_volume(wedge), 0.5 * 4.0 * 0.6 * 2.0, 0.01 * 2.4);
}

TEST(MeshProximity, BoxesAtAKnownGapAndOverlap) {
  const TriangleMesh a = cylinder_mesh(0.5, 0.0, 1.0, 4, Facet::kInscribed);  // a square prism
  TriangleMesh b = a;
  b.vertices.col(0).array() += 1.25;  // gap 0.25 along x between the end faces
  Result<geometry::MeshProximity> tree = geometry::MeshProximity::build(b);
  ASSERT_TRUE(tree.ok());
  Result<geometry::ClosestApproach> near = tree->closest_approach(a, 0.5);
  ASSERT_TRUE(near.ok());
  ASSERT_TRUE(near->found);
  EXPECT_NEAR(near->distance, 0.25, 1e-12);
  EXPECT_NEAR(near->point_a.x(), 1.0, 1e-12);
  EXPECT_NEAR(near->point_b.x(), 1.25, 1e-12);
  EXPECT_FALSE(tree->closest_approach(a, 0.2)->found);
  EXPECT_TRUE(tree->crossings(a)->empty());
  EXPECT_FALSE(*tree->solids_overlap(a));
  // Shifted into each other: crossing surfaces.
  TriangleMesh c = a;
  c.vertices.col(0).array() += 0.75;
  EXPECT_FALSE(tree->crossings(c)->empty());
  EXPECT_TRUE(*tree->solids_overlap(c));
  EXPECT_EQ(tree->closest_approach(c, 0.1)->distance, 0.0);
  // One inside the other without crossing surfaces.
  const TriangleMesh small = cylinder_mesh(0.1, 1.5, 1.8, 8, Facet::kInscribed);
  EXPECT_TRUE(tree->crossings(small)->empty());
  EXPECT_TRUE(*tree->solids_overlap(small));
  EXPECT_TRUE(tree->contains(Eigen::Vector3d(1.7, 0.05, -0.1)));
  EXPECT_FALSE(tree->contains(Eigen::Vector3d(0.7, 0.05, -0.1)));
}

TEST(MeshProximity, TriangleEdgeToEdgeDistance) {
  // Two triangles whose closest features are two crossing edges 1 apart (no vertex is closest).
  Eigen::Vector3d pa, pb;
  const double d = geometry::triangle_closest_points({-1, 0, 0}, {1, 0, 0}, {0, 0, -1}, {0, -1, 1},
                                                     {0, 1, 1}, {0, 0, 2}, &pa, &pb);
  EXPECT_NEAR(d, 1.0, 1e-12);
  EXPECT_LT((pa - Eigen::Vector3d(0, 0, 0)).norm(), 1e-12);
  EXPECT_LT((pb - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
}

}  // namespace
}  // namespace hc::articulation
