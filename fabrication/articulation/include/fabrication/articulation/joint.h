// A mechanical joint between two links of a character: where it is, how it is oriented, its type
// and range and where they came from, its optimised design, and why it was excluded if it was.
// Plus the per-joint user overrides read from YAML:
//
//   joints:
//     - child: forearm_L        # the joint whose child link is this bone
//       parent: upperarm_L      # optional: only the transition from this link
//       type: hinge             # ball, hinge or none (no joint: the links stay fused)
//       frame_angle_deg: 30     # turns the frame's axis a about n (a hinge's axis)
//       swing_deg: [120, 5]     # hinge: forward, backward
//       cone_deg: [30, 15]      # ball: opening towards f, towards a
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/status.h"
#include "fabrication/articulation/joint_design.h"
#include "fabrication/articulation/motion.h"
#include "fabrication/articulation/primitives.h"

namespace hc::articulation {

enum class JointType { kBall, kHinge };
enum class JointSource { kDefault, kAnimation, kUser };

const char* to_string(JointType type);
const char* to_string(JointSource source);

struct Joint {
  int parent_link = -1;  // bone index of the link nearer the root (m)
  int child_link = -1;   // (o)
  std::string parent_name, child_name;
  bool tree_edge = true;  // the child's bone is the parent's child in the rig
  JointType type = JointType::kBall;
  JointSource source = JointSource::kDefault;
  Eigen::Vector3d transition_centre = Eigen::Vector3d::Zero();  // p (m)
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();             // c (m)
  Eigen::Vector3d n = Eigen::Vector3d::UnitY();  // orientation, parent -> child
  Eigen::Vector3d a = Eigen::Vector3d::UnitX();  // frame axis (hinge axis), perpendicular to n
  double r_max_initial = 0.0;  // maximum inscribed sphere at c (m)
  double r_max = 0.0;          // after collision resolution
  BallRange cone;
  HingeRange swing;
  BallSocketDesign ball;
  HingeDesign hinge;
  double min_area = 0.0;  // of the chosen design (m^2)
  bool excluded = false;
  std::string reason;  // why excluded
  std::optional<MotionEstimate> motion;
  double centre_from_rig_m = -1.0;     // |c - the rig's joint|
  double motion_centre_shift_m = -1.0;  // |motion centre - medial centre|, -1: no motion used
  std::vector<std::string> notes;

  Eigen::Vector3d f() const { return a.cross(n); }
  LocalFrame frame() const;  // origin c, axes [a, n, f]
  bool feasible() const { return type == JointType::kBall ? ball.feasible : hinge.feasible; }
};

struct JointOverride {
  std::string child;
  std::string parent;  // empty: any transition into `child`
  std::optional<std::string> type;  // "ball", "hinge", "none"
  std::optional<double> frame_angle_rad;
  std::optional<std::array<double, 2>> swing_rad;  // forward, backward
  std::optional<std::array<double, 2>> cone_rad;   // towards f, towards a
  Status read(ConfigNode node);
};

struct JointOverrides {
  std::vector<JointOverride> joints;
  Status read(ConfigNode node);
  // The override for a joint, if any (the first whose child and, if given, parent match).
  const JointOverride* find(const std::string& parent, const std::string& child) const;
};

Result<JointOverrides> load_joint_overrides(const std::filesystem::path& path);
Result<JointOverrides> parse_joint_overrides(std::string_view yaml, std::string_view name);

}  // namespace hc::articulation
