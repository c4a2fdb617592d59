// The whole pipeline on small inputs: a synthetic skinned arm animated about a known hinge axis,
// the same arm without clips (a default ball joint), and the smallest real character
// (RiggedSimple.glb). The carved parts are checked with the geometry target's predicates:
// closed, manifold, free of self-intersections, d apart, the ball held, the range swept and the
// clip replayed without collision.
#include "fabrication/articulation/articulate.h"
#include "test_units.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <vector>

#include "fabrication/articulation/skinned_io.h"
#include "sanitizer.h"
#include "synthetic_skinned.h"

namespace hc::articulation {
namespace {

using testing::kDeg;
using testing::kMm;

// A 16 mm thick, 90 mm long arm of two bones; the elbow at 45 mm.
SkinnedCharacter arm() {
  testing::SyntheticLimb limb;
  limb.segments = 24;
  limb.rings = 25;
  return testing::skinned_limb(limb);
}

// The arm's tube with a third bone: 135 mm long, joints at y = 45 and 90 mm.
SkinnedCharacter three_bone_limb() {
  testing::SyntheticLimb limb;
  limb.bones = 3;
  limb.length_m = 0.135;
  limb.segments = 24;
  limb.rings = 37;
  return testing::skinned_limb(limb);
}

void expect_valid(const ArticulateResult& r, double clearance) {
  const VerificationReport& v = r.verification;
  EXPECT_TRUE(v.parts_valid);
  for (const PartCheck& p : v.parts) {
    EXPECT_TRUE(p.closed) << p.name;
    EXPECT_TRUE(p.manifold) << p.name;
    EXPECT_EQ(p.self_intersecting_pairs, 0) << p.name;
    EXPECT_GT(p.volume_m3, 0) << p.name;
  }
  EXPECT_EQ(static_cast<int>(r.parts.size()), r.accepted() + 1);
  // The joint's clearance gap is the closest approach of the parts (faceting only widens it).
  ASSERT_GE(v.min_part_distance_m, 0.0);
  EXPECT_GE(v.min_part_distance_m, 0.99 * clearance);
  for (const Joint& j : r.joints) {
    if (!j.excluded) {
      EXPECT_GE(j.min_area, 10 * kMm * kMm) << j.child_name;
    }
  }
  for (const JointCheck& jc : v.joints) {
    EXPECT_TRUE(jc.ball_held);
    EXPECT_GT(jc.sweep_poses, 0);
    EXPECT_EQ(jc.sweep_collisions, 0);
  }
  EXPECT_TRUE(v.ok) << (v.problems.empty() ? "" : v.problems.front());
}

TEST(Articulate, SyntheticArmAnimatedAboutAnAxisBecomesAHingeWithThatAxis) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  SkinnedCharacter c = arm();
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 0, 0.3).normalized();
  c.clips.push_back(
      testing::rotation_clip(c, 1, axis, Eigen::Vector3d(0, 0.045, 0), 15 * kDeg, 30 * kDeg, 31));
  ArticulateOptions o;
  Result<ArticulateResult> r = articulate(c, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  ASSERT_EQ(r->accepted(), 1);
  const Joint& j = r->joints.front();
  EXPECT_EQ(j.type, JointType::kHinge);
  EXPECT_EQ(j.source, JointSource::kAnimation);
  EXPECT_LT(std::acos(std::abs(j.a.dot(axis))), 2 * kDeg);
  EXPECT_NEAR(j.swing.forward, 45 * kDeg, 2 * kDeg);
  EXPECT_NEAR(j.swing.backward, 15 * kDeg, 2 * kDeg);
  expect_valid(*r, o.printer.clearance_m);
  ASSERT_EQ(r->verification.clips.size(), 1u);
  EXPECT_GE(r->verification.clips[0].share, 0.95);
  EXPECT_TRUE(r->verification.narrowed.empty());  // a clean replay keeps the designed range
}

TEST(Articulate, SyntheticArmWithoutClipsGetsADefaultBall) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  const SkinnedCharacter c = arm();
  ArticulateOptions o;
  Result<ArticulateResult> r = articulate(c, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  ASSERT_EQ(r->accepted(), 1);
  const Joint& j = r->joints.front();
  EXPECT_EQ(j.type, JointType::kBall);
  EXPECT_EQ(j.source, JointSource::kDefault);
  // On the tube's axis at the elbow, with the tube's radius as r_max (faceting: within 2 %).
  EXPECT_LT(std::hypot(j.centre.x(), j.centre.z()), 0.1 * kMm);
  EXPECT_NEAR(j.centre.y(), 0.045, 2.5 * kMm);
  EXPECT_NEAR(j.r_max, 8 * kMm, 0.02 * 8 * kMm);
  expect_valid(*r, o.printer.clearance_m);
}

TEST(Articulate, ThreeBoneLimbGivesTwoJointsAlongTheChainAndThreeParts) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  // Both joints are between a bone and its child in the rig, so the parts form a tree of three.
  const SkinnedCharacter c = three_bone_limb();
  ArticulateOptions o;
  Result<ArticulateResult> r = articulate(c, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  ASSERT_EQ(r->accepted(), 2);
  std::vector<const Joint*> accepted;
  for (const Joint& j : r->joints)
    if (!j.excluded) accepted.push_back(&j);
  std::sort(accepted.begin(), accepted.end(),
            [](const Joint* a, const Joint* b) { return a->centre.y() < b->centre.y(); });
  for (std::size_t k = 0; k < 2; ++k) {
    const Joint& j = *accepted[k];
    EXPECT_TRUE(j.tree_edge);
    EXPECT_EQ(j.parent_link, static_cast<int>(k));
    EXPECT_EQ(j.child_link, static_cast<int>(k) + 1);
    EXPECT_LT(std::hypot(j.centre.x(), j.centre.z()), 0.1 * kMm);
    EXPECT_NEAR(j.centre.y(), 0.045 * static_cast<double>(k + 1), 2.5 * kMm);
    EXPECT_NEAR(j.r_max, 8 * kMm, 0.02 * 8 * kMm);
  }
  expect_valid(*r, o.printer.clearance_m);
}

// The three-bone tube folded at its first joint from 0 to 160 degrees: at the top of the swing
// the child side meets the parent.
SkinnedCharacter folded_limb() {
  SkinnedCharacter c = three_bone_limb();
  c.clips.push_back(testing::rotation_clip(c, 1, Eigen::Vector3d::UnitX(),
                                           Eigen::Vector3d(0, 0.045, 0), 80 * kDeg, 80 * kDeg, 31));
  return c;
}

// The narrowed joint carries its narrowed range (less than the clip's 160 degrees times the
// factor: the design's range is at most the clip's) and says so.
void expect_narrowed_hinge(const ArticulateResult& r, const RangeNarrowing& n) {
  // The carved parts themselves are sound: two closed parts, d apart (a fork wedge past 90
  // degrees once split the parent's tube lengthwise: four parts).
  EXPECT_TRUE(r.verification.parts_valid);
  EXPECT_EQ(r.parts.size(), 2u);
  EXPECT_GE(r.verification.min_part_distance_m, 0.99 * ArticulateOptions().printer.clearance_m);
  EXPECT_GT(n.factor, 0.1);
  EXPECT_LT(n.factor, 1.0);
  const Joint& j = r.joints[static_cast<std::size_t>(n.joint)];
  EXPECT_FALSE(j.excluded);
  EXPECT_EQ(j.type, JointType::kHinge);
  EXPECT_LT(j.swing.forward, 160 * kDeg * n.factor + 1e-9);
  ASSERT_FALSE(j.notes.empty());
  EXPECT_NE(j.notes.back().find("range narrowed"), std::string::npos) << j.notes.back();
}

TEST(Articulate, RangePosesThatCollideNarrowTheRange) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  ArticulateOptions o;
  Result<ArticulateResult> r = articulate(folded_limb(), o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const VerificationReport& v = r->verification;
  ASSERT_EQ(v.joints.size(), 1u);
  EXPECT_GT(v.joints[0].sweep_collisions, 0);  // at the designed range
  EXPECT_LT(v.joints[0].range_factor, 1.0);
  ASSERT_EQ(v.narrowed.size(), 1u);
  EXPECT_TRUE(v.narrowed[0].by_sweep);
  expect_narrowed_hinge(*r, v.narrowed[0]);
  EXPECT_GE(v.replay_share, o.verification.replay_required_share);
  for (const std::string& p : v.problems) {
    EXPECT_EQ(p.find("range poses collide"), std::string::npos) << p;
    EXPECT_EQ(p.find("clip replay"), std::string::npos) << p;
  }
}

TEST(Articulate, AClipThatCollidesNarrowsTheRangeUntilItReplaysCleanly) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  // Without the sweeps (which would narrow the range first), 81 % of the clip's frames replay
  // cleanly at the designed range; the replay narrows the joint until >= 95 % do.
  ArticulateOptions o;
  o.verification.sweeps = false;
  Result<ArticulateResult> r = articulate(folded_limb(), o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const VerificationReport& v = r->verification;
  EXPECT_LT(v.replay_share_before_narrowing, o.verification.replay_required_share);
  EXPECT_GE(v.replay_share, o.verification.replay_required_share);
  ASSERT_EQ(v.narrowed.size(), 1u);
  EXPECT_TRUE(v.narrowed[0].by_replay);
  EXPECT_FALSE(v.narrowed[0].by_sweep);
  expect_narrowed_hinge(*r, v.narrowed[0]);
  for (const std::string& p : v.problems) EXPECT_EQ(p.find("clip replay"), std::string::npos) << p;
}

TEST(Articulate, HingesFoldedFrom90To170DegreesCarveSoundParts) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  // The three-bone tube folded at its first joint from 0 to each range. Past 90 degrees the fork
  // wedge once followed the mesh to its exit behind the transition plane: at 135 degrees the
  // rounded parts self-intersected, at 140 and 160 degrees the parent's tube came apart. Every
  // range must give two sound parts, d apart; the sweeps then narrow what the folded child
  // cannot reach.
  for (double range_deg : {90.0, 120.0, 135.0, 140.0, 170.0}) {
    SCOPED_TRACE(range_deg);
    SkinnedCharacter c = three_bone_limb();
    const double half = range_deg / 2 * kDeg;
    c.clips.push_back(testing::rotation_clip(c, 1, Eigen::Vector3d::UnitX(),
                                             Eigen::Vector3d(0, 0.045, 0), half, half, 31));
    ArticulateOptions o;
    Result<ArticulateResult> r = articulate(c, o);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    ASSERT_EQ(r->accepted(), 1);
    const VerificationReport& v = r->verification;
    EXPECT_TRUE(v.parts_valid);
    for (const PartCheck& p : v.parts) EXPECT_EQ(p.self_intersecting_pairs, 0) << p.name;
    EXPECT_EQ(r->parts.size(), 2u);
    EXPECT_GE(v.min_part_distance_m, 0.99 * o.printer.clearance_m);
    EXPECT_EQ(r->carving.debris_pieces, 0);
  }
}

TEST(Articulate, UserOverridesTurnTheJointIntoAHinge) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  const SkinnedCharacter c = arm();
  ArticulateOptions o;
  Result<JointOverrides> u = parse_joint_overrides(
      "joints:\n  - child: bone1\n    type: hinge\n    swing_deg: [60, 10]\n", "joints.yaml");
  ASSERT_TRUE(u.ok()) << u.status().to_string();
  o.overrides = *u;
  o.verify = false;
  Result<ArticulateResult> r = articulate(c, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  ASSERT_EQ(r->accepted(), 1);
  EXPECT_EQ(r->joints.front().type, JointType::kHinge);
  EXPECT_EQ(r->joints.front().source, JointSource::kUser);
  EXPECT_NEAR(r->joints.front().swing.forward, 60 * kDeg, 1e-12);
  EXPECT_EQ(r->parts.size(), 2u);
}

TEST(Articulate, OverridesAndProfilesRejectBadYamlWithFileAndLine) {
  Result<JointOverrides> u =
      parse_joint_overrides("joints:\n  - child: a\n    type: socket\n", "joints.yaml");
  ASSERT_FALSE(u.ok());
  EXPECT_NE(u.status().message().find("joints.yaml:3"), std::string::npos) << u.status().message();
  Result<PrinterProfile> p = parse_printer_profile("base: fdm\nclearance_mm: -1\n", "p.yaml");
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.status().message().find("p.yaml:2"), std::string::npos) << p.status().message();
  Result<PrinterProfile> fdm = parse_printer_profile("base: fdm\nmin_area_mm2: 20\n", "p.yaml");
  ASSERT_TRUE(fdm.ok());
  EXPECT_NEAR(fdm->clearance_m, 0.4 * kMm, 1e-15);  // the FDM clearance
  EXPECT_NEAR(fdm->min_area_m2, 20e-6, 1e-18);
  EXPECT_TRUE(fdm->pins_upright);
  Result<PrinterProfile> polyjet = builtin_printer_profile("polyjet");
  ASSERT_TRUE(polyjet.ok());
  // Thesis Sec. 6.5: d = 0.3 mm, A_min = 10 mm^2, r_b = 0.7 mm.
  EXPECT_NEAR(polyjet->clearance_m, 0.3 * kMm, 1e-15);
  EXPECT_NEAR(polyjet->min_area_m2, 10e-6, 1e-18);
  EXPECT_NEAR(polyjet->bump_radius_m, 0.7 * kMm, 1e-15);
  EXPECT_NEAR(builtin_printer_profile("sla")->clearance_m, 0.25 * kMm, 1e-15);
}

TEST(Articulate, RiggedSimpleGivesTwoPartsOrAClearReason) {
  HC_SKIP_WHEN_SANITIZED("CGAL's exact booleans take minutes");
  SkinnedReadOptions read;
  read.target_height_m = 0.08;
  Result<SkinnedCharacter> c =
      read_skinned_character(std::string(HARDCOPY_SHARED_DATA) + "/skinned/RiggedSimple.glb", read);
  ASSERT_TRUE(c.ok());
  ArticulateOptions o;
  Result<ArticulateResult> r = articulate(*c, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  ASSERT_EQ(r->joints.size(), 1u);
  if (r->accepted() == 1) {
    expect_valid(*r, o.printer.clearance_m);
  } else {
    EXPECT_FALSE(r->joints.front().reason.empty());
  }
}

}  // namespace
}  // namespace hc::articulation
