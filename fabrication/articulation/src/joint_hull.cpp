#include "fabrication/articulation/joint_hull.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

#include "fabrication/articulation/carving.h"
#include "fabrication/articulation/primitives.h"
#include "geometry/csg_sequence.h"

namespace hc::articulation {
namespace {

using geometry::BooleanOperation;
using geometry::CsgStep;
// Fraction of a facet step the neck cone's generatrices are turned by: an irrational amount, so
// they do not lie in the planes of a symmetric character's edges (a tube's edges through its axis
// share every rational azimuth), which would leave slivers that rounding folds.
constexpr double kNeckPhase = 0.3819660112501051;  // 2 - golden ratio

using Depth = std::function<double(const Eigen::Vector3d&)>;

CsgStep step(BooleanOperation op, TriangleMesh mesh, const char* name) {
  return {op, std::move(mesh), name};
}

// A small sphere (bump or dimple) at `centre`, its UV grid turned by an arbitrary fixed rotation
// so that none of its vertices or edges lines up with the joint's own spheres and cones (such
// near-coincidences leave slivers that rounding turns into self-intersections).
TriangleMesh small_sphere(double radius, int segments, Facet facet, const Eigen::Vector3d& centre) {
  static const Eigen::Matrix3d kTurn =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  TriangleMesh m = sphere_mesh(radius, segments, facet);
  for (Eigen::Index v = 0; v < m.num_vertices(); ++v)
    m.vertices.row(v) = (kTurn * m.vertices.row(v).transpose() + centre).transpose();
  return m;
}

// The hull without the solid fragments its CSG can leave apart from the mechanism: where a cut's
// reach changes fast between neighbouring directions (along a limb), the swing wedge and the
// child's body sector, sampled at different azimuths, leave thin islands of the wedge behind.
// Carved out of F they would slice slivers off the parts. Kept: the largest solid and any
// cavity inside it.
Result<TriangleMesh> without_fragments(const TriangleMesh& hull) {
  HC_ASSIGN_OR_RETURN(std::vector<Solid> solids, solids_of(hull));
  if (solids.size() <= 1) return solids.empty() ? hull : std::move(solids.front().mesh);
  return std::move(
      std::max_element(solids.begin(), solids.end(), [](const Solid& a, const Solid& b) {
        return a.volume_m3 < b.volume_m3;
      })->mesh);
}

// Evaluates the hull's CSG in the joint's frame and moves it to the world.
Result<TriangleMesh> evaluate(const TriangleMesh& base, std::vector<CsgStep> steps,
                              const LocalFrame& frame) {
  geometry::CsgOptions options;
  options.check_operands = false;  // primitives are closed and outward by construction
  geometry::CsgSummary summary;
  HC_ASSIGN_OR_RETURN(TriangleMesh local, geometry::csg_sequence(base, steps, options, &summary));
  if (!summary.closed || local.num_triangles() == 0)
    return internal_error("joint hull: the CSG result is not a closed mesh");
  // Carving needs a hull free of self-intersections; rounding the exact result can (rarely) fold
  // a sliver.
  if (summary.self_intersecting_pairs_after_rounding > 0)
    return internal_error(fmt::format("joint hull: rounding left {} self-intersecting pairs",
                                      summary.self_intersecting_pairs_after_rounding));
  HC_ASSIGN_OR_RETURN(local, without_fragments(local));
  return transformed(local, frame);
}

Result<JointHull> ball_hull(const Joint& j, const HullOptions& o, const Depth& depth) {
  const BallSocketDesign& s = j.ball;
  const LocalFrame frame = j.frame();
  const double d = o.clearance_m, m = o.reach_margin_m;
  JointHull out;
  // Reach of a direction given in the joint frame.
  const auto reach = [&](double extra) {
    return [&, extra](const Eigen::Vector3d& local_dir) {
      return std::max(exit_distance(depth, j.centre, frame.axes * local_dir), s.r) + extra;
    };
  };
  const auto psi = [&](double theta) { return s.alpha + j.cone.at(theta) + s.delta; };
  const auto alpha = [&](double) { return s.alpha; };
  std::vector<CsgStep> steps;
  // The socket's cut: the shell between half the neck's angle and psi (the part inside the neck
  // goes with the neck), its generatrices half a step away from the neck cone's so that no
  // vertex of one lies on an edge of the other.
  steps.push_back(
      step(BooleanOperation::kUnion,
           cone_sector_mesh(psi, reach(m), o.segments, Facet::kCircumscribed, s.alpha / 2, s.r / 2,
                            (kNeckPhase + 0.5) * 2 * std::numbers::pi / o.segments),
           "socket cone"));
  // Friction bumps on the ball's equator, three around n; dimples of r_b + d in the socket, when
  // they fit inside the inscribed sphere.
  std::vector<Eigen::Vector3d> bumps_local;
  const double rb = o.bump_radius_m;
  if (rb > 0 && s.ball_radius + rb + d < j.r_max) {
    for (int k = 0; k < 3; ++k) {
      const double t = 2 * std::numbers::pi * k / 3 + std::numbers::pi / 6;
      bumps_local.emplace_back(s.ball_radius * std::sin(t), 0.0, s.ball_radius * std::cos(t));
    }
  }
  const int small = std::max(12, o.segments / 3);
  for (const Eigen::Vector3d& c : bumps_local) {
    steps.push_back(step(BooleanOperation::kUnion,
                         small_sphere(rb + d, small, Facet::kCircumscribed, c), "dimple"));
  }
  steps.push_back(step(BooleanOperation::kDifference,
                       sphere_mesh(s.ball_radius, o.segments, Facet::kInscribed), "ball"));
  steps.push_back(step(BooleanOperation::kDifference,
                       cone_sector_mesh(alpha, reach(2 * m), o.segments, Facet::kInscribed, 0.0,
                                        0.0, kNeckPhase * 2 * std::numbers::pi / o.segments),
                       "neck cone"));
  for (const Eigen::Vector3d& c : bumps_local) {
    steps.push_back(step(BooleanOperation::kDifference,
                         small_sphere(rb, small - 2, Facet::kInscribed, c), "bump"));
    out.bumps.push_back(frame.origin + frame.axes * c);
  }
  out.bump_radius_m = bumps_local.empty() ? 0.0 : rb;
  HC_ASSIGN_OR_RETURN(out.hull, evaluate(sphere_mesh(s.r, o.segments, Facet::kCircumscribed),
                                         std::move(steps), frame));
  return out;
}

Result<JointHull> hinge_hull(const Joint& j, const HullOptions& o, const Depth& depth) {
  const HingeDesign& h = j.hinge;
  const LocalFrame frame = j.frame();
  const double d = o.clearance_m, m = o.reach_margin_m;
  JointHull out;
  const double psi_f = std::min(h.alpha + j.swing.forward + h.delta, 0.97 * std::numbers::pi);
  const double psi_b = std::min(h.alpha + j.swing.backward + h.delta, 0.97 * std::numbers::pi);
  // Where the ray from the axis at x in direction phi leaves the mesh.
  const auto exit_at = [&](double x, double phi) {
    return exit_distance(depth, j.centre + x * j.a, std::cos(phi) * j.n + std::sin(phi) * j.f());
  };
  // Half-extent along the axis: where rays along +-a leave the mesh, from points of the wedge out
  // to where its rays leave the mesh (a flat limb is wider far from the axis than near it).
  double half = h.b / 2 + d;
  for (double phi : {-psi_b, -h.alpha, 0.0, h.alpha, psi_f}) {
    const Eigen::Vector3d dir = std::cos(phi) * j.n + std::sin(phi) * j.f();
    const double out_to = std::max(2 * j.r_max, std::min(exit_at(0.0, phi), 4 * j.r_max));
    for (double t : {0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0}) {
      const Eigen::Vector3d q = j.centre + t * out_to * dir;
      half = std::max({half, exit_distance(depth, q, j.a), exit_distance(depth, q, -j.a)});
    }
  }
  half += m;
  // Where rays in direction phi leave the mesh, farthest over the slot's whole width: the prisms
  // below keep one radius along the axis, so the cut also leaves the mesh between their
  // cross-sections where a flat-sided limb is as wide at its sides as in its middle (sampled at
  // the cross-sections alone, the facets between the last one inside the limb and the first one
  // outside stopped short of its surface there and left the two sides joined).
  std::map<double, double> widest;
  const auto exit_across = [&](double phi) {
    auto [it, fresh] = widest.emplace(phi, 0.0);
    if (fresh)
      for (int k = 0; k <= 16; ++k)
        it->second = std::max(it->second, exit_at(-half + half * k / 8, phi));
    return it->second;
  };
  // The fork wedge's outer radius: past the mesh at the swing's angles. Well inside the neck's
  // angle, which the child's body (subtracted below) covers, it goes no farther than at the
  // neck's sides: followed to the exit there it would run down the child's whole limb, and the
  // two prisms' facets would leave a sliver of it along the limb. The samples next to the neck's
  // sides keep their full reach, so the facets between them still cut through at the sides.
  const double wedge_step = sector_step(-psi_b, psi_f, o.segments);
  const auto wedge_reach = [&](double, double phi) {
    double t = exit_across(phi);
    if (std::abs(phi) + wedge_step < h.alpha)
      t = std::min(t, std::max(exit_across(-h.alpha), exit_across(h.alpha)));
    // Past the transition plane (a swing beyond 90 degrees) the wedge frees only the
    // mechanism's disc of radius r_max, as Fig. 6.4.9's area a3 assumes: the parent's body
    // behind it stays whole (followed to the exit, the wedge's side would split the parent's limb
    // lengthwise). Where the folded child then meets that body, the sweeps narrow the range.
    if (std::abs(phi) > std::numbers::pi / 2) t = std::min(t, j.r_max);
    return std::max(t, h.R) + m;
  };
  const auto body_reach = [&](double, double phi) {
    return std::max(exit_across(phi), h.R) + 2 * m;
  };
  const int stations = 8;
  const int small = std::max(12, o.segments / 3);
  std::vector<CsgStep> steps;
  // The swing wedge frees the cheeks from radius R - d outwards; its inner arc is kept a little
  // inside the knuckle's (which the knuckle then removes again) so the two surfaces never
  // coincide, and outside the pin.
  const double wedge_inner = h.R - d - 0.5 * std::min(d, h.R - d - h.r);
  steps.push_back(step(BooleanOperation::kUnion,
                       sector_prism_mesh(wedge_inner, wedge_reach, -psi_b, psi_f, -half, half,
                                         stations, o.segments, Facet::kInscribed),
                       "fork wedge"));
  // Friction bumps on the knuckle's faces, behind the pin (away from the neck).
  std::vector<Eigen::Vector3d> bumps_local;
  const double rb = o.bump_radius_m;
  const double rho = 0.5 * (h.r + h.R - d);
  if (rb > 0 && rb + d < 0.5 * (h.R - d - h.r)) {
    for (double side : {-1.0, 1.0}) bumps_local.emplace_back(side * (h.b / 2 - d), -rho, 0.0);
  }
  for (const Eigen::Vector3d& c : bumps_local) {
    steps.push_back(step(BooleanOperation::kUnion,
                         small_sphere(rb + d, small, Facet::kCircumscribed, c), "dimple"));
  }
  // K: the knuckle, its neck (a wedge of half-angle alpha within the slot) and the child's body
  // beyond the cheeks (outside R + d/2). The neck is a hair narrower than the body's wedge and
  // reaches only into it, so their sides never coincide. Then the hole through the knuckle is
  // put back and the pin (r - d, into the cheeks) taken out: the gap around the pin.
  const double knuckle = h.b / 2 - d;
  steps.push_back(step(
      BooleanOperation::kDifference,
      cylinder_mesh(h.R - d, -knuckle, knuckle, o.segments, Facet::kInscribed, 0.25), "knuckle"));
  const double neck_alpha = 0.998 * h.alpha;
  steps.push_back(step(BooleanOperation::kDifference,
                       sector_prism_mesh(0.0, h.R + d, -neck_alpha, neck_alpha, -knuckle, knuckle,
                                         o.segments, Facet::kInscribed),
                       "neck"));
  steps.push_back(step(BooleanOperation::kDifference,
                       sector_prism_mesh(h.R + d / 2, body_reach, -h.alpha, h.alpha, -half - m,
                                         half + m, stations, o.segments, Facet::kCircumscribed),
                       "child body"));
  const double hole_end = h.b / 2 - d / 2;
  steps.push_back(step(
      BooleanOperation::kUnion,
      cylinder_mesh(h.r, -hole_end, hole_end, o.segments, Facet::kCircumscribed, 0.75), "hole"));
  const double pin_end = h.b / 2 + d;
  steps.push_back(
      step(BooleanOperation::kDifference,
           cylinder_mesh(h.r - d, -pin_end, pin_end, o.segments, Facet::kInscribed, 0.5), "pin"));
  for (const Eigen::Vector3d& c : bumps_local) {
    steps.push_back(step(BooleanOperation::kDifference,
                         small_sphere(rb, small - 2, Facet::kInscribed, c), "bump"));
    out.bumps.push_back(frame.origin + frame.axes * c);
  }
  out.bump_radius_m = bumps_local.empty() ? 0.0 : rb;
  HC_ASSIGN_OR_RETURN(
      out.hull, evaluate(cylinder_mesh(h.R, -h.b / 2, h.b / 2, o.segments, Facet::kCircumscribed),
                         std::move(steps), frame));
  return out;
}

}  // namespace

double exit_distance(const Depth& depth, const Eigen::Vector3d& origin,
                     const Eigen::Vector3d& direction) {
  const Eigen::Vector3d u = direction.normalized();
  double t = 0.0;
  double s = depth(origin);
  if (s <= 0) return 0.0;
  const double tolerance = 1e-6 + 1e-4 * s;
  for (int i = 0; i < 400 && s > tolerance; ++i) {
    t += s;
    s = depth(origin + t * u);
  }
  return t;
}

Result<JointHull> build_joint_hull(const Joint& joint, const HullOptions& options,
                                   const Depth& depth) {
  if (!joint.feasible())
    return failed_precondition(fmt::format("joint {} -> {}: no feasible design to build",
                                           joint.parent_name, joint.child_name));
  HC_ASSIGN_OR_RETURN(JointHull out, joint.type == JointType::kBall
                                         ? ball_hull(joint, options, depth)
                                         : hinge_hull(joint, options, depth));
  for (Eigen::Index v = 0; v < out.hull.num_vertices(); ++v)
    out.reach_m =
        std::max(out.reach_m, (out.hull.vertices.row(v).transpose() - joint.centre).norm());
  return out;
}

}  // namespace hc::articulation
