// Segmentation, transitions (Eqs. 6.2, 6.3), PCA planes and the medial joint centre on synthetic
// tubes whose joints are known by construction.
#include "fabrication/articulation/joint_locations.h"

#include <gtest/gtest.h>

#include "synthetic_skinned.h"

namespace hc::articulation {
namespace {

TEST(JointLocations, ATubeOfThreeBonesHasTwoRingTransitions) {
  testing::SyntheticLimb limb;  // radius 8 mm, 90 mm long
  limb.bones = 3;               // joints at y = 30 and 60 mm
  const SkinnedCharacter c = testing::skinned_limb(limb);
  const Eigen::MatrixXd w = c.dense_weights();
  const std::vector<int> label = segment_by_max_weight(w);
  EXPECT_EQ(label[0], 0);                                            // ring 0, y = 0
  EXPECT_EQ(label[static_cast<std::size_t>(36 * limb.segments)], 2);  // last ring, y = 90 mm
  Result<std::vector<Transition>> t =
      find_transitions(c.mesh, w, {-1, 0, 1}, {0, 1, 2}, TransitionOptions{});
  ASSERT_TRUE(t.ok()) << t.status().to_string();
  ASSERT_EQ(t->size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const Transition& tr = (*t)[static_cast<std::size_t>(k)];
    EXPECT_EQ(tr.parent_link, k);
    EXPECT_EQ(tr.child_link, k + 1);
    EXPECT_TRUE(tr.tree_edge);
    EXPECT_FALSE(tr.degenerate);
    // A ring of the tube: centre on the axis, normal along +Y (parent below). The ring at the
    // joint (y = 30k mm) has weights 0.5 / 0.5 and rounding gives it to the child; the ring below
    // (2.5 mm lower) has the parent's weight smoothstep(0.75) = 0.84375 over the 10 mm ramp. Eq.
    // 6.3 puts every point of the vertical and diagonal edges between those two rings at
    // y = (0.84375 (y - 2.5 mm) + 0.5 y) / 1.34375. In-plane variances: points on circles of
    // radius 8 mm and chords between neighbours, ~rho^2 / 2 = 32 mm^2 (within 1 %).
    const double y = 0.03 * (k + 1);
    EXPECT_LT(std::hypot(tr.centre.x(), tr.centre.z()), 1e-9);
    EXPECT_NEAR(tr.centre.y(), (0.84375 * (y - 0.0025) + 0.5 * y) / 1.34375, 1e-9);
    EXPECT_GT(tr.normal.y(), 0.999);
    EXPECT_NEAR(tr.lambdas(2), 32e-6, 0.32e-6);
    EXPECT_NEAR(tr.lambdas(1), 32e-6, 0.32e-6);
    EXPECT_LT(tr.ratio, 1.01);
    EXPECT_EQ(tr.points.size(), static_cast<std::size_t>(2 * limb.segments));  // | and / edges
  }
}

TEST(JointLocations, AStripTransitionIsDegenerate) {
  // Bone 1 dominates a strip of the tube along its length: its transition edges run along two
  // lines, lambda3 >> lambda2.
  testing::SyntheticLimb limb;
  const SkinnedCharacter c = testing::skinned_limb(limb);
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(c.mesh.num_vertices(), 2);
  for (Eigen::Index v = 0; v < w.rows(); ++v) w(v, c.mesh.vertices(v, 0) > 0.5 * limb.radius_m ? 1 : 0) = 1;
  Result<std::vector<Transition>> t = find_transitions(c.mesh, w, {-1, 0}, {0, 1}, {});
  ASSERT_TRUE(t.ok());
  ASSERT_EQ(t->size(), 1u);
  EXPECT_TRUE(t->front().degenerate);
  EXPECT_GT(t->front().ratio, 4.0);
}

TEST(JointLocations, MedialCentreIsTheDeepestPointOfTheCrossSection) {
  // An ellipse-section tube along Y (semi-axes 10 and 6 mm, centre (3, *, -2) mm): the deepest
  // point of any plane y = const is the centre, at depth 6 mm. Depth of an ellipse approximated
  // by the distance to the nearer bounding line pair, exact at the centre.
  const Eigen::Vector3d axis_point(0.003, 0.0, -0.002);
  const auto depth = [&](const Eigen::Vector3d& p) {
    const double x = p.x() - axis_point.x(), z = p.z() - axis_point.z();
    const double inside = 1 - (x * x) / (0.01 * 0.01) - (z * z) / (0.006 * 0.006);
    return inside <= 0 ? inside : std::min(0.01 - std::abs(x), 0.006 - std::abs(z));
  };
  // Transition centre off the axis (a bent loop), normal along Y.
  const MedialCentre m =
      medial_centre(Eigen::Vector3d(0.006, 0.05, 0.001), Eigen::Vector3d::UnitY(), 0.015, depth);
  ASSERT_TRUE(m.found);
  EXPECT_NEAR(m.r_max, 0.006, 1e-6);
  EXPECT_NEAR(m.centre.y(), 0.05, 1e-12);  // stays in the plane
  EXPECT_NEAR(m.centre.z(), axis_point.z(), 1e-5);
  // Along x the depth is flat (6 mm) for |x - 3 mm| <= 4 mm: any point there is deepest.
  EXPECT_LE(std::abs(m.centre.x() - axis_point.x()), 0.004 + 1e-6);
  // Nothing inside near the transition: not found.
  EXPECT_FALSE(medial_centre(Eigen::Vector3d(0.5, 0, 0), Eigen::Vector3d::UnitY(), 0.01, depth).found);
}

}  // namespace
}  // namespace hc::articulation
