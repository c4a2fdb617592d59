// Joints from motion on synthetic skinned arms animated about known axes and centres: the hinge
// axis within 2 degrees, the ranges within 2 degrees, the rotation centre on the true axis.
#include "fabrication/articulation/motion.h"
#include "test_units.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <numbers>

#include "fabrication/articulation/skinned_io.h"
#include "synthetic_skinned.h"

namespace hc::articulation {
namespace {

using testing::kDeg;

double angle_between_lines(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized()))));
}

double distance_to_line(const Eigen::Vector3d& p, const Eigen::Vector3d& on_line,
                        const Eigen::Vector3d& dir) {
  const Eigen::Vector3d d = dir.normalized();
  const Eigen::Vector3d v = p - on_line;
  return (v - v.dot(d) * d).norm();
}

struct Arm {
  SkinnedCharacter c;
  Eigen::Vector3d axis;
  Eigen::Vector3d centre;
};

// Two-bone arm (elbow at y = 45 mm); bone 1 swings about a tilted axis through a point off the
// rig's joint, between -20 and +60 degrees.
Arm swinging_arm() {
  testing::SyntheticLimb limb;
  Arm arm{testing::skinned_limb(limb), Eigen::Vector3d(1, 0.15, 0.35).normalized(),
          Eigen::Vector3d(0.0015, 0.046, -0.001)};
  arm.c.clips.push_back(
      testing::rotation_clip(arm.c, 1, arm.axis, arm.centre, 20 * kDeg, 40 * kDeg, 61));
  return arm;
}

void expect_hinge(const SkinnedCharacter& c, const Eigen::Vector3d& axis,
                  const Eigen::Vector3d& centre) {
  Result<LinkMotion> motion = fit_link_motion(c, MotionOptions{});
  ASSERT_TRUE(motion.ok()) << motion.status().to_string();
  const Eigen::Vector3d prior(0, 0.045, 0);  // the rig's joint
  const MotionEstimate e = estimate_joint_motion(*motion, 0, 1, Eigen::Vector3d::UnitY(), prior,
                                                 c.clips, MotionOptions{});
  ASSERT_EQ(e.type, MotionJointType::kHinge);
  EXPECT_LT(angle_between_lines(e.axis, axis), 2 * kDeg);
  // Forward is the larger swing: +60 degrees about the axis, backward 20.
  EXPECT_NEAR(e.swing_forward_rad, 60 * kDeg, 2 * kDeg);
  EXPECT_NEAR(e.swing_backward_rad, 20 * kDeg, 2 * kDeg);
  EXPECT_EQ(e.centre_free_directions, 1);
  EXPECT_LT(distance_to_line(e.centre, centre, axis), 0.2e-3);
  // Along the free axis the centre stays at the prior's foot on the line.
  const Eigen::Vector3d foot = centre + (prior - centre).dot(axis) * axis;
  EXPECT_LT((e.centre - foot).norm(), 0.2e-3);
  ASSERT_EQ(e.clips.size(), 1u);
}

TEST(Motion, RecoversTheHingeAxisRangeAndCentreOfASyntheticArm) {
  const Arm arm = swinging_arm();
  expect_hinge(arm.c, arm.axis, arm.centre);
}

TEST(Motion, RecoversTheHingeFromAnFbxAndACollada) {
  // Through files Assimp wrote and read back (float precision, resampled at 30 Hz).
  const Arm arm = swinging_arm();
  const auto dir = std::filesystem::temp_directory_path() / "hc_motion_files";
  std::filesystem::create_directories(dir);
  for (const char* name : {"arm.fbx", "arm.dae"}) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(write_skinned_character(dir / name, arm.c).ok());
    Result<SkinnedCharacter> back = read_skinned_character(dir / name);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    // The reader centres x and z and puts the feet on y = 0; the synthetic arm already is.
    ASSERT_LT(back->shift.norm(), 1e-9);
    expect_hinge(*back, arm.axis, arm.centre);
  }
  std::filesystem::remove_all(dir);
}

TEST(Motion, TwoAxesMakeABallWithTheObservedCone) {
  testing::SyntheticLimb limb;
  SkinnedCharacter c = testing::skinned_limb(limb);
  const Eigen::Vector3d centre(0, 0.045, 0);
  // 30 degrees about X in one clip, 15 about Z in another: the tilt of n = +Y reaches 30 along
  // the Z direction (rotation about X tilts Y towards Z) and 15 along X.
  c.clips.push_back(testing::rotation_clip(c, 1, Eigen::Vector3d::UnitX(), centre, 0, 30 * kDeg));
  c.clips.push_back(testing::rotation_clip(c, 1, Eigen::Vector3d::UnitZ(), centre, 0, 15 * kDeg));
  Result<LinkMotion> motion = fit_link_motion(c, MotionOptions{});
  ASSERT_TRUE(motion.ok());
  const MotionEstimate e =
      estimate_joint_motion(*motion, 0, 1, Eigen::Vector3d::UnitY(), Eigen::Vector3d(0, 0.04, 0),
                            c.clips, MotionOptions{});
  ASSERT_EQ(e.type, MotionJointType::kBall);
  EXPECT_LT(angle_between_lines(e.tilt_direction, Eigen::Vector3d::UnitZ()), 2 * kDeg);
  EXPECT_NEAR(e.cone_major_rad, 30 * kDeg, 2 * kDeg);
  EXPECT_NEAR(e.cone_minor_rad, 15 * kDeg, 2 * kDeg);
  // Two independent axes fix the centre completely.
  EXPECT_EQ(e.centre_free_directions, 0);
  EXPECT_LT((e.centre - centre).norm(), 0.2e-3);
  EXPECT_EQ(e.clips.size(), 2u);
}

TEST(Motion, ALinkThatNeverMovesIsFused) {
  testing::SyntheticLimb limb;
  limb.bones = 3;
  SkinnedCharacter c = testing::skinned_limb(limb);
  c.clips.push_back(testing::rotation_clip(c, 2, Eigen::Vector3d::UnitX(),
                                           Eigen::Vector3d(0, 0.06, 0), 0, 30 * kDeg));
  Result<LinkMotion> motion = fit_link_motion(c, MotionOptions{});
  ASSERT_TRUE(motion.ok());
  const MotionEstimate still = estimate_joint_motion(*motion, 0, 1, Eigen::Vector3d::UnitY(),
                                                     Eigen::Vector3d(0, 0.03, 0), c.clips, {});
  EXPECT_EQ(still.type, MotionJointType::kFused);
  EXPECT_LT(still.max_angle_rad, 0.1 * kDeg);
  EXPECT_TRUE(still.clips.empty());
  const MotionEstimate moving = estimate_joint_motion(*motion, 1, 2, Eigen::Vector3d::UnitY(),
                                                      Eigen::Vector3d(0, 0.06, 0), c.clips, {});
  EXPECT_EQ(moving.type, MotionJointType::kHinge);
}

TEST(Motion, RotationVectorOfAKnownRotation) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, axis).toRotationMatrix();
  EXPECT_LT((rotation_vector(r) - 0.7 * axis).norm(), 1e-12);
  EXPECT_LT(rotation_vector(Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

}  // namespace
}  // namespace hc::articulation
