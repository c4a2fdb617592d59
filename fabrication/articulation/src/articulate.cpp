#include "fabrication/articulation/articulate.h"
#include "common/units.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>

#include "geometry/mesh_distance.h"

namespace hc::articulation {
namespace {

constexpr double kMaxCone = units::deg_to_rad(80);
const Eigen::Vector3d kUp = Eigen::Vector3d::UnitY();

class Stopwatch {
 public:
  explicit Stopwatch(std::vector<StageTime>* stages) : stages_(stages) {}
  void lap(const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    stages_->push_back({stage, std::chrono::duration<double>(now - last_).count()});
    last_ = now;
  }

 private:
  std::vector<StageTime>* stages_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// `v` without its component along unit `n`, normalised; `fallback` when that is too short.
Eigen::Vector3d perpendicular(const Eigen::Vector3d& v, const Eigen::Vector3d& n,
                              const Eigen::Vector3d& fallback) {
  const Eigen::Vector3d p = v - v.dot(n) * n;
  if (p.norm() > 0.2 * v.norm()) return p.normalized();
  const Eigen::Vector3d q = fallback - fallback.dot(n) * n;
  return q.norm() > 1e-6 ? q.normalized() : n.unitOrthogonal();
}

void redesign(const ArticulateOptions& o, Joint* j) {
  JointDesignOptions d;
  d.clearance_m = o.printer.clearance_m;
  if (j->type == JointType::kBall) {
    j->ball = design_ball_socket(j->r_max, j->cone, d);
    j->min_area = j->ball.feasible ? j->ball.min_area : 0.0;
  } else {
    j->hinge = design_hinge(j->r_max, j->swing, d);
    j->min_area = j->hinge.feasible ? j->hinge.min_area : 0.0;
  }
}

// Joint type, axis, range and centre from the clips.
void apply_motion(const ArticulateOptions& o, const LinkMotion& motion,
                  const std::vector<Clip>& clips,
                  const std::function<double(const Eigen::Vector3d&)>& depth, Joint* j) {
  const MotionEstimate e = estimate_joint_motion(motion, j->parent_link, j->child_link, j->n,
                                                 j->centre, clips, o.motion);
  j->motion = e;
  if (e.type == MotionJointType::kFused) {
    j->excluded = true;
    j->reason = fmt::format(
        "fused: the links never turn more than {:.1f} deg relative to each "
        "other in the clips",
        units::rad_to_deg(o.motion.fused_below_rad));
    return;
  }
  j->source = JointSource::kAnimation;
  if (e.type == MotionJointType::kHinge) {
    j->type = JointType::kHinge;
    j->a = e.axis;
    // Keep the observed axis exactly: tilt n into the plane perpendicular to it.
    j->n = perpendicular(j->n, j->a, j->n.cross(j->a));
    j->swing = {e.swing_forward_rad, e.swing_backward_rad};
  } else {
    j->type = JointType::kBall;
    j->a = j->n.cross(e.tilt_direction).normalized();  // f = a x n = the principal tilt
    j->cone = {std::min(e.cone_major_rad, kMaxCone), std::min(e.cone_minor_rad, kMaxCone)};
  }
  const double d = depth(e.centre);
  if (d >= o.motion_centre_min_depth * j->r_max) {
    j->motion_centre_shift_m = (e.centre - j->centre).norm();
    j->centre = e.centre;
    j->r_max = j->r_max_initial = d;
  } else {
    j->notes.push_back(
        fmt::format("motion centre kept off: only {:.2f} mm inside (medial r_max {:.2f} mm)",
                    units::m_to_mm(d), units::m_to_mm(j->r_max)));
  }
}

void apply_override(const JointOverride& u, Joint* j) {
  if (u.type && *u.type == "none") {
    j->excluded = true;
    j->reason = "user: no joint";
    return;
  }
  j->source = JointSource::kUser;
  if (u.type) j->type = *u.type == "hinge" ? JointType::kHinge : JointType::kBall;
  if (u.frame_angle_rad) j->a = Eigen::AngleAxisd(*u.frame_angle_rad, j->n) * j->a;
  if (u.swing_rad) j->swing = {(*u.swing_rad)[0], (*u.swing_rad)[1]};
  if (u.cone_rad) j->cone = {(*u.cone_rad)[0], (*u.cone_rad)[1]};
}

}  // namespace

Status ArticulateOptions::validate() const {
  HC_RETURN_IF_ERROR(printer.validate());
  HC_RETURN_IF_ERROR(transitions.validate());
  HC_RETURN_IF_ERROR(motion.validate());
  if (hull_segments < 12) return invalid_argument("hull_segments must be >= 12");
  return {};
}

int ArticulateResult::accepted() const {
  int n = 0;
  for (const Joint& j : joints) n += j.excluded ? 0 : 1;
  return n;
}

Result<ArticulateResult> articulate(const SkinnedCharacter& c, const ArticulateOptions& o) {
  HC_RETURN_IF_ERROR(o.validate());
  HC_RETURN_IF_ERROR(validate(c));
  const auto start = std::chrono::steady_clock::now();
  ArticulateResult out;
  Stopwatch watch(&out.stages);

  FabricationMeshOptions fm;
  fm.wrap_alpha_m = o.printer.wrap_alpha_m;
  fm.force_wrap = o.force_wrap;
  fm.progress = o.progress;
  HC_ASSIGN_OR_RETURN(FabricationMesh F, build_fabrication_mesh(c, fm));
  out.fabrication = F.summary;
  watch.lap("fabrication mesh");

  std::vector<int> parents, depths;
  std::vector<std::string> names;
  for (const Bone& b : c.bones)
    parents.push_back(b.parent), depths.push_back(b.depth), names.push_back(b.name);
  HC_ASSIGN_OR_RETURN(const std::vector<Transition> transitions,
                      find_transitions(F.mesh, F.weights, parents, depths, o.transitions));
  HC_ASSIGN_OR_RETURN(const geometry::MeshDistance distance, geometry::MeshDistance::build(F.mesh));
  const auto depth = [&distance](const Eigen::Vector3d& p) { return -distance.signed_distance(p); };
  std::vector<LinkContact> contacts;
  for (const Transition& t : transitions) {
    contacts.push_back({t.parent_link, t.child_link});
    Joint j;
    j.parent_link = t.parent_link;
    j.child_link = t.child_link;
    j.parent_name = names[static_cast<std::size_t>(t.parent_link)];
    j.child_name = names[static_cast<std::size_t>(t.child_link)];
    j.tree_edge = t.tree_edge;
    j.transition_centre = t.centre;
    j.n = t.normal;
    j.a = perpendicular(o.printer.pins_upright ? kUp : t.major, j.n, t.major);
    j.cone = {o.printer.default_cone_rad, o.printer.default_cone_rad};
    j.swing = {o.printer.default_swing_rad, o.printer.default_swing_rad};
    j.centre_from_rig_m = -1;
    if (t.degenerate) {
      j.excluded = true;
      j.reason = static_cast<int>(t.points.size()) < o.transitions.min_points
                     ? fmt::format(
                           "degenerate transition: {} transition points (fewer than {}): the "
                           "links barely touch",
                           t.points.size(), o.transitions.min_points)
                     : fmt::format(
                           "degenerate transition: lambda3/lambda2 = {:.2f} > f = {:.2f} ({} "
                           "points): the links are not joined around a loop",
                           t.ratio, o.transitions.degenerate_ratio, t.points.size());
    } else {
      const MedialCentre m =
          medial_centre(t.centre, t.normal, 1.5 * std::sqrt(2 * t.lambdas(2)), depth);
      if (!m.found) {
        j.excluded = true;
        j.reason = "no point of the transition plane near it lies inside the mesh";
      } else {
        j.centre = m.centre;
        j.r_max = j.r_max_initial = m.r_max;
      }
    }
    out.joints.push_back(std::move(j));
  }
  watch.lap("joint locations");

  std::optional<LinkMotion> motion;
  if (o.use_animation && !c.clips.empty()) {
    HC_ASSIGN_OR_RETURN(motion, fit_link_motion(c, o.motion));
    for (Joint& j : out.joints)
      if (!j.excluded) apply_motion(o, *motion, c.clips, depth, &j);
  }
  for (Joint& j : out.joints) {
    if (const JointOverride* u = o.overrides.find(j.parent_name, j.child_name))
      apply_override(*u, &j);
    if (j.excluded) continue;
    const Eigen::Vector3d rig = c.bones[static_cast<std::size_t>(j.child_link)].rest_origin_m;
    j.centre_from_rig_m = (j.centre - rig).norm();
    redesign(o, &j);
    if (!j.feasible()) {
      j.excluded = true;
      j.reason = fmt::format(
          "too thin: r_max {:.2f} mm leaves no room for a {} with {:.2f} mm "
          "clearance",
          units::m_to_mm(j.r_max), to_string(j.type), units::m_to_mm(o.printer.clearance_m));
    } else if (j.min_area < o.printer.min_area_m2) {
      j.excluded = true;
      j.reason = fmt::format(
          "too weak: best smallest cross-section {:.2f} mm^2 < A_min {:.2f} "
          "mm^2 (r_max {:.2f} mm)",
          j.min_area / (units::kMetresPerMillimetre * units::kMetresPerMillimetre),
          o.printer.min_area_m2 / (units::kMetresPerMillimetre * units::kMetresPerMillimetre),
          units::m_to_mm(j.r_max));
    }
  }
  exclude_unseparable_joints(contacts, static_cast<int>(c.bones.size()), &out.joints);
  watch.lap("joint design");

  HullOptions hull_options;
  hull_options.clearance_m = o.printer.clearance_m;
  hull_options.bump_radius_m = o.printer.bump_radius_m;
  hull_options.segments = o.hull_segments;
  const std::vector<int> labels = segment_by_max_weight(F.weights);
  // A hull reaches only through its joint's own side of the tree: the parent and its ancestors,
  // the child and its descendants. A point whose nearest surface belongs to another link (the
  // other leg beside a knee, the other arm) counts as outside, so the hull's cut surfaces stop
  // before a sibling limb and never slice pieces off it.
  const HullFn build = [&](const Joint& j) {
    std::vector<char> own(names.size(), 0);
    for (int l = j.parent_link; l >= 0; l = parents[static_cast<std::size_t>(l)])
      own[static_cast<std::size_t>(l)] = 1;
    for (std::size_t l = 0; l < own.size(); ++l)
      for (int k = static_cast<int>(l); k >= 0 && !own[l]; k = parents[static_cast<std::size_t>(k)])
        own[l] = k == j.child_link;
    const auto own_depth = [&](const Eigen::Vector3d& p) {
      const double s = depth(p);
      if (s <= 0) return s;
      Eigen::Index t = -1;
      distance.closest_point(p, &t);
      for (int k = 0; k < 3; ++k)
        if (own[static_cast<std::size_t>(labels[static_cast<std::size_t>(F.mesh.triangles(t, k))])])
          return s;
      return 0.0;
    };
    return build_joint_hull(j, hull_options, own_depth);
  };
  std::vector<JointHull> hulls;
  CollisionOptions co;
  co.clearance_m = o.printer.clearance_m;
  co.min_area_m2 = o.printer.min_area_m2;
  co.progress = o.progress;
  HC_RETURN_IF_ERROR(resolve_collisions(
      &out.joints, &hulls, [&](Joint* j) { redesign(o, j); }, build, co, &out.collisions));
  exclude_unseparable_joints(contacts, static_cast<int>(c.bones.size()), &out.joints);
  watch.lap("collisions");

  // Below the volume of a cube twice the printer's smallest feature, a loose piece is a crumb.
  const double debris_volume = std::pow(2 * o.printer.wrap_alpha_m, 3);
  for (int attempt = 0; attempt < 3; ++attempt) {
    out.carving = CarveSummary{};
    HC_ASSIGN_OR_RETURN(out.parts, carve_parts(F.mesh, labels, names, depths, out.joints, hulls,
                                               debris_volume, o.progress, &out.carving));
    if (out.carving.unseparated.empty() && out.carving.severed.empty()) break;
    for (int i : out.carving.unseparated) {
      Joint& j = out.joints[static_cast<std::size_t>(i)];
      j.excluded = true;
      j.reason = "its hull did not separate the two sides (the cut left them connected)";
    }
    for (int i : out.carving.severed) {
      Joint& j = out.joints[static_cast<std::size_t>(i)];
      if (j.excluded) continue;
      j.excluded = true;
      j.reason = "its cut severed a piece that no joint holds (a protrusion beyond the socket)";
    }
    exclude_unseparable_joints(contacts, static_cast<int>(c.bones.size()), &out.joints);
  }
  watch.lap("carving");

  if (o.verify) {
    VerificationOptions v = o.verification;
    v.clearance_m = o.printer.clearance_m;
    HC_ASSIGN_OR_RETURN(out.verification,
                        verify_articulation(out.parts, out.joints, hulls,
                                            motion ? &*motion : nullptr, c.clips, v, o.progress));
    watch.lap("verification");
    // The usable ranges the checks narrowed are the joints' ranges from now on.
    for (const RangeNarrowing& n : out.verification.narrowed) {
      Joint& j = out.joints[static_cast<std::size_t>(n.joint)];
      narrow_range(j, n.factor);
      j.notes.push_back(fmt::format(
          "range narrowed to {:.0f} % of the design so that {} without collision", 100 * n.factor,
          n.by_sweep && n.by_replay ? "its range poses and the clips replay"
          : n.by_sweep              ? "its range poses sweep"
                                    : "the clips replay"));
    }
  }
  out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace hc::articulation
