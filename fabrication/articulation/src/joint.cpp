#include "fabrication/articulation/joint.h"
#include "common/units.h"

#include <numbers>

namespace hc::articulation {
const char* to_string(JointType type) { return type == JointType::kBall ? "ball" : "hinge"; }

const char* to_string(JointSource source) {
  switch (source) {
    case JointSource::kDefault:
      return "default";
    case JointSource::kAnimation:
      return "animation";
    case JointSource::kUser:
      return "user";
  }
  return "default";
}

LocalFrame Joint::frame() const {
  LocalFrame fr;
  fr.origin = centre;
  fr.axes.col(0) = a;
  fr.axes.col(1) = n;
  fr.axes.col(2) = f();
  return fr;
}

Status JointOverride::read(ConfigNode node) {
  node.required("child", child);
  node.optional("parent", parent);
  std::string t;
  if (node.optional("type", t, {"ball", "hinge", "none"})) type = t;
  double angle = 0;
  if (node.optional("frame_angle_deg", angle, Bounds::between(-360, 360)))
    frame_angle_rad = units::deg_to_rad(angle);
  std::array<double, 2> pair{};
  if (node.optional("swing_deg", pair, Bounds::between(0, 170)))
    swing_rad = std::array<double, 2>{units::deg_to_rad(pair[0]), units::deg_to_rad(pair[1])};
  if (node.optional("cone_deg", pair, Bounds::between(0, 80)))
    cone_rad = std::array<double, 2>{units::deg_to_rad(pair[0]), units::deg_to_rad(pair[1])};
  if (type && *type == "ball" && swing_rad) node.error("swing_deg", "is for hinges, not balls");
  if (type && *type == "hinge" && cone_rad) node.error("cone_deg", "is for balls, not hinges");
  return node.status();
}

Status JointOverrides::read(ConfigNode node) {
  node.required("joints", joints);
  return node.status();
}

const JointOverride* JointOverrides::find(const std::string& parent,
                                          const std::string& child) const {
  for (const JointOverride& o : joints)
    if (o.child == child && (o.parent.empty() || o.parent == parent)) return &o;
  return nullptr;
}

Result<JointOverrides> parse_joint_overrides(std::string_view yaml, std::string_view name) {
  HC_ASSIGN_OR_RETURN(const Config config, parse_config(yaml, name));
  return read_config<JointOverrides>(config);
}

Result<JointOverrides> load_joint_overrides(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(const Config config, load_config(path));
  return read_config<JointOverrides>(config);
}

}  // namespace hc::articulation
