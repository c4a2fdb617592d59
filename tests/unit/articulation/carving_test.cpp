// Carving's bookkeeping of the pieces a cut leaves: each piece holding a joint's probe is a part,
// with the cavities inside it; a piece without a joint is kept but blamed on the hull that bounds
// it (severed), unless it is a crumb below the debris volume, which is dropped and counted.
// Hand-built: a 40 x 10 x 10 mm bar holding a cavity, and a "hull" of three slabs across it whose
// pieces have volumes known by construction.
#include "fabrication/articulation/carving.h"
#include "test_units.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "fabrication/articulation/primitives.h"
#include "synthetic_meshes.h"

namespace hc::articulation {
namespace {

using testing::kMm;

TEST(Carving, PiecesWithoutAJointAreSeveredOrDroppedAsCrumbs) {
  using testing::box;
  // The bar holds a 2 x 2 x 2 mm cavity in its parent half (an inward shell, 8 mm^3).
  TriangleMesh cavity = box(Eigen::Vector3d(-10, -1, -1) * kMm, Eigen::Vector3d(-8, 1, 1) * kMm);
  cavity.triangles.col(1).swap(cavity.triangles.col(2));
  const TriangleMesh bar = concatenated(
      {box(Eigen::Vector3d(-20, -5, -5) * kMm, Eigen::Vector3d(20, 5, 5) * kMm), cavity});
  // Links: x < 0 the parent (0), x >= 0 the child (1).
  std::vector<int> link;
  for (Eigen::Index v = 0; v < bar.num_vertices(); ++v)
    link.push_back(bar.vertices(v, 0) < 0 ? 0 : 1);
  // The joint's cut (x in [-0.25, 0.25] mm), a cut that severs x > 15.5 mm (450 mm^3) and one
  // that leaves a 0.2 mm crumb at x < -19.8 mm (20 mm^3). The slabs overhang the bar in y and z.
  const auto slab = [](double x0, double x1) {
    return box(Eigen::Vector3d(x0, -6, -6) * kMm, Eigen::Vector3d(x1, 6, 6) * kMm);
  };
  JointHull hull;
  hull.hull = concatenated({slab(-0.25, 0.25), slab(15, 15.5), slab(-19.8, -19.7)});
  Joint j;
  j.parent_link = 0, j.child_link = 1;
  j.type = JointType::kBall;
  j.n = Eigen::Vector3d::UnitX();
  j.centre = Eigen::Vector3d(2, 0, 0) * kMm;  // child probe: x = 2 mm
  j.ball.r = 2 * kMm, j.r_max = 4 * kMm;      // parent probe: x = 2 - (2 + 4) / 2 = -1 mm
  ASSERT_LT(parent_probe(j).x(), -0.25 * kMm);

  CarveSummary s;
  Result<std::vector<CarvedPart>> parts =
      carve_parts(bar, link, {"parent", "child"}, {0, 1}, {j}, {hull}, 30e-9, nullptr, &s);
  ASSERT_TRUE(parts.ok()) << parts.status().to_string();
  EXPECT_EQ(s.components, 5);
  EXPECT_EQ(s.cavities, 1);  // kept in the parent part, not a part of its own
  EXPECT_TRUE(s.unseparated.empty());
  // The crumb: dropped and counted with its volume (0.2 x 10 x 10 mm).
  EXPECT_EQ(s.debris_pieces, 1);
  EXPECT_NEAR(s.debris_volume_m3, 20e-9, 1e-12);
  // The severed end is kept as a part and blamed on the joint whose hull bounds it.
  ASSERT_EQ(parts->size(), 3u);
  EXPECT_EQ(s.severed, std::vector<int>{0});
  std::vector<double> volumes;
  for (const CarvedPart& p : *parts) volumes.push_back(enclosed_volume(p.mesh));
  std::sort(volumes.begin(), volumes.end());
  EXPECT_NEAR(volumes[0], 450e-9, 1e-12);   // x in [15.5, 20]
  EXPECT_NEAR(volumes[1], 1475e-9, 1e-12);  // child: x in [0.25, 15]
  EXPECT_NEAR(volumes[2], 1937e-9, 1e-12);  // parent: x in [-19.7, -0.25], less the cavity

  // Without the severing slab, nothing is blamed.
  hull.hull = concatenated({slab(-0.25, 0.25), slab(-19.8, -19.7)});
  s = CarveSummary{};
  parts = carve_parts(bar, link, {"parent", "child"}, {0, 1}, {j}, {hull}, 30e-9, nullptr, &s);
  ASSERT_TRUE(parts.ok()) << parts.status().to_string();
  EXPECT_EQ(parts->size(), 2u);
  EXPECT_TRUE(s.severed.empty());
  EXPECT_EQ(s.debris_pieces, 1);
}

}  // namespace
}  // namespace hc::articulation
