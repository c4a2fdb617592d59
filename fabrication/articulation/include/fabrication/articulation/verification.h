// Checks of a carved articulated model, on its real geometry: every part closed, manifold and
// free of self-intersections; parts at least d apart; every ball held by its socket (the ball,
// pulled out along its axis, hits the socket's lip); every joint swept through its range (both
// hinge swings, the ball's cone and twist) without its moving side crossing another part; and the
// file's clips replayed on the rigid parts, counting the frames without collision. Contacts at the
// friction bumps are by design and not counted.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "fabrication/articulation/carving.h"
#include "fabrication/articulation/joint.h"
#include "fabrication/articulation/joint_hull.h"
#include "fabrication/articulation/motion.h"
#include "fabrication/articulation/skinned_character.h"

namespace hc::articulation {

struct VerificationOptions {
  bool check_self_intersections = true;
  double sweep_step_rad = 5.0 * 3.14159265358979 / 180;
  bool sweeps = true;
  bool replay = true;
  int max_frames_per_clip = 24;
  double replay_required_share = 0.95;
  // A joint whose range poses collide keeps the largest fraction of its range (at least 10 %,
  // found to about 10 %) that sweeps cleanly; below the required replay share, the joints between
  // the colliding parts are narrowed likewise until the clips replay cleanly.
  bool narrow_ranges = true;
  double clearance_m = 0.3e-3;
};

struct PartCheck {
  std::string name;
  bool closed = false;
  bool manifold = false;
  std::int64_t self_intersecting_pairs = -1;  // -1: not checked
  double volume_m3 = 0.0;
};

struct JointCheck {
  int joint = -1;
  int parent_part = -1, child_part = -1;
  bool ball_held = true;  // ball joints: pulled along n it hits the lip
  int sweep_poses = 0;
  int sweep_collisions = 0;   // poses where the moving side crossed another part (designed range)
  std::string sweep_note;     // which part it hit first
  double range_factor = 1.0;  // of the designed range that sweeps without collision
};

struct ClipReplay {
  std::string clip;
  int frames = 0;
  int collision_free = 0;
  double share = 0.0;
  std::vector<std::string> colliding_pairs;          // "partA/partB" seen colliding
  std::vector<std::pair<int, int>> colliding_parts;  // the same pairs as part indices
};

// A joint whose usable range the checks narrowed: `factor` of its designed range (hinge swings,
// ball cone) sweeps without collision and keeps the clip replay at the required share.
struct RangeNarrowing {
  int joint = -1;
  double factor = 1.0;
  bool by_sweep = false;   // its own range poses collided
  bool by_replay = false;  // the clips collided
};

struct VerificationReport {
  std::vector<PartCheck> parts;
  bool parts_valid = false;           // every part closed, manifold, free of self-intersections
  int expected_parts = 0;             // accepted joints + 1 (a tree)
  double min_part_distance_m = -1.0;  // closest approach of two parts (-1: none within 2d)
  std::string closest_parts;
  std::vector<JointCheck> joints;
  std::vector<ClipReplay> clips;
  double replay_share = 1.0;                   // over all clips (after any narrowing)
  double replay_share_before_narrowing = 1.0;  // on the ranges the sweeps left
  std::vector<RangeNarrowing> narrowed;
  bool ok = false;
  std::vector<std::string> problems;
};

// Rigid transform of each part at one pose (world frame).
using PartPose = std::vector<Eigen::Isometry3d>;

struct PartTree {
  std::vector<int> joint_parent_part, joint_child_part;  // per joint (-1: excluded)
  // Parts that move with each joint's child side (the child part and its descendants).
  std::vector<std::vector<int>> moving;
  int root = 0;
};

// Scales a joint's range (hinge swings, ball cone) by `factor` (RangeNarrowing).
void narrow_range(Joint& joint, double factor);

// Which part is on each side of each accepted joint, and what moves with it.
Result<PartTree> part_tree(const std::vector<CarvedPart>& parts, const std::vector<Joint>& joints);

Result<VerificationReport> verify_articulation(
    const std::vector<CarvedPart>& parts, const std::vector<Joint>& joints,
    const std::vector<JointHull>& hulls, const LinkMotion* motion, const std::vector<Clip>& clips,
    const VerificationOptions& options, ProgressReporter* progress);

}  // namespace hc::articulation
