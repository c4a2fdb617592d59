#include "fabrication/articulation/verification.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <set>

#include "fabrication/printability/mesh_check.h"
#include "geometry/mesh_proximity.h"

namespace hc::articulation {
namespace {

TriangleMesh moved(const TriangleMesh& m, const Eigen::Isometry3d& t) {
  TriangleMesh out = m;
  for (Eigen::Index v = 0; v < out.num_vertices(); ++v)
    out.vertices.row(v) = (t * m.vertices.row(v).transpose()).transpose();
  return out;
}

Eigen::Isometry3d rotation_about(const Eigen::Vector3d& c, const Eigen::Matrix3d& r) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = c - r * c;
  return t;
}

// Crossing points that are not contacts of a friction bump with its socket or cheek.
bool real_crossing(const std::vector<geometry::CrossingPair>& pairs,
                   const std::vector<Eigen::Vector3d>& bumps, double zone) {
  for (const auto& p : pairs) {
    bool at_bump = false;
    for (const Eigen::Vector3d& b : bumps) at_bump = at_bump || (p.point - b).norm() < zone;
    if (!at_bump) return true;
  }
  return false;
}

// Rotations the ball's range allows at a given relative rotation: the tilt of n clamped to the
// cone, the twist about n kept.
Eigen::Matrix3d clamp_to_range(const Joint& j, const Eigen::Matrix3d& r) {
  if (j.type == JointType::kHinge) {
    const double angle =
        std::clamp(rotation_vector(r).dot(j.a), -j.swing.backward, j.swing.forward);
    return Eigen::AngleAxisd(angle, j.a).toRotationMatrix();
  }
  const Eigen::Vector3d m = r * j.n;
  const Eigen::Vector3d side = m - m.dot(j.n) * j.n;
  const double tilt = std::atan2(side.norm(), m.dot(j.n));
  if (side.norm() < 1e-12) return r;
  const double theta = std::atan2(side.dot(j.a), side.dot(j.f()));
  const double limit = j.cone.at(theta);
  if (tilt <= limit) return r;
  const Eigen::Quaterniond q(r);
  return Eigen::Quaterniond::Identity().slerp(limit / tilt, q).toRotationMatrix();
}

struct Sets {
  TriangleMesh moving, fixed;
};

Sets split_sets(const std::vector<CarvedPart>& parts, const std::vector<int>& moving) {
  std::vector<TriangleMesh> a, b;
  for (std::size_t p = 0; p < parts.size(); ++p)
    (std::find(moving.begin(), moving.end(), static_cast<int>(p)) != moving.end() ? a : b)
        .push_back(parts[p].mesh);
  return {concatenated(a), concatenated(b)};
}

// The joint's poses for the sweep: hinge swings; the ball's cone in 8 directions at full tilt
// and the twist about n.
std::vector<Eigen::Matrix3d> sweep_rotations(const Joint& j, double step) {
  std::vector<Eigen::Matrix3d> out;
  if (j.type == JointType::kHinge) {
    for (double g = step; g <= j.swing.forward + 1e-9; g += step)
      out.push_back(Eigen::AngleAxisd(g, j.a).toRotationMatrix());
    for (double g = step; g <= j.swing.backward + 1e-9; g += step)
      out.push_back(Eigen::AngleAxisd(-g, j.a).toRotationMatrix());
    return out;
  }
  for (int k = 0; k < 8; ++k) {
    const double theta = 2 * std::numbers::pi * k / 8;
    const Eigen::Vector3d dir = std::cos(theta) * j.f() + std::sin(theta) * j.a;
    const Eigen::Vector3d axis = j.n.cross(dir).normalized();
    for (double frac : {0.5, 1.0})
      out.push_back(Eigen::AngleAxisd(frac * j.cone.at(theta), axis).toRotationMatrix());
  }
  for (double twist : {-std::numbers::pi / 4, std::numbers::pi / 4})
    out.push_back(Eigen::AngleAxisd(twist, j.n).toRotationMatrix());
  return out;
}

}  // namespace

Result<PartTree> part_tree(const std::vector<CarvedPart>& parts, const std::vector<Joint>& joints) {
  PartTree t;
  std::vector<std::unique_ptr<geometry::MeshProximity>> inside;
  for (const CarvedPart& p : parts) {
    HC_ASSIGN_OR_RETURN(geometry::MeshProximity tree, geometry::MeshProximity::build(p.mesh));
    inside.push_back(std::make_unique<geometry::MeshProximity>(std::move(tree)));
  }
  const auto piece_of = [&](const Eigen::Vector3d& x) {
    for (std::size_t k = 0; k < inside.size(); ++k)
      if (inside[k]->contains(x)) return static_cast<int>(k);
    return -1;
  };
  t.joint_parent_part.assign(joints.size(), -1);
  t.joint_child_part.assign(joints.size(), -1);
  t.moving.assign(joints.size(), {});
  std::vector<char> is_child(parts.size(), 0);
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].excluded) continue;
    t.joint_parent_part[i] = piece_of(parent_probe(joints[i]));
    t.joint_child_part[i] = piece_of(child_probe(joints[i]));
    if (t.joint_child_part[i] >= 0) is_child[static_cast<std::size_t>(t.joint_child_part[i])] = 1;
  }
  for (std::size_t p = 0; p < parts.size(); ++p)
    if (!is_child[p]) {
      t.root = static_cast<int>(p);
      break;
    }
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (t.joint_child_part[i] < 0 || t.joint_parent_part[i] < 0) continue;
    std::vector<int> set{t.joint_child_part[i]};
    for (std::size_t k = 0; k < set.size(); ++k)
      for (std::size_t e = 0; e < joints.size(); ++e)
        if (t.joint_parent_part[e] == set[k] && t.joint_child_part[e] >= 0 &&
            t.joint_child_part[e] != t.joint_parent_part[i] &&
            std::find(set.begin(), set.end(), t.joint_child_part[e]) == set.end())
          set.push_back(t.joint_child_part[e]);
    t.moving[i] = set;
  }
  return t;
}

namespace {

// Every part closed, manifold and free of self-intersections; as many parts as a tree of the
// accepted joints has.
Status check_parts(const std::vector<CarvedPart>& parts, const std::vector<Joint>& joints,
                   const VerificationOptions& options, ProgressTask* task, VerificationReport* r) {
  r->parts_valid = !parts.empty();
  for (const CarvedPart& p : parts) {
    fabrication::MeshCheckOptions check;
    check.check_self_intersections = options.check_self_intersections;
    HC_ASSIGN_OR_RETURN(const fabrication::MeshCheckReport c,
                        fabrication::check_mesh(p.mesh, check));
    PartCheck pc{p.name, c.closed, c.manifold,
                 c.self_intersections_checked ? c.self_intersecting_pairs : -1, c.volume};
    if (!c.closed || !c.manifold || pc.self_intersecting_pairs > 0) {
      r->parts_valid = false;
      r->problems.push_back(fmt::format("part {} is not a valid solid", p.name));
    }
    r->parts.push_back(pc);
    task->advance();
  }
  int accepted = 0;
  for (const Joint& j : joints) accepted += j.excluded ? 0 : 1;
  r->expected_parts = accepted + 1;
  if (static_cast<int>(parts.size()) != r->expected_parts)
    r->problems.push_back(fmt::format("{} parts for {} joints (a tree has {})", parts.size(),
                                      accepted, r->expected_parts));
  return {};
}

// The closest approach of any two parts (searched within 2 d), a problem below the clearance d.
Status check_clearance(const std::vector<CarvedPart>& parts,
                       const std::vector<std::unique_ptr<geometry::MeshProximity>>& trees, double d,
                       VerificationReport* r) {
  for (std::size_t a = 0; a < parts.size(); ++a)
    for (std::size_t b = a + 1; b < parts.size(); ++b) {
      HC_ASSIGN_OR_RETURN(const geometry::ClosestApproach c,
                          trees[b]->closest_approach(parts[a].mesh, 2 * d));
      if (c.found && (r->min_part_distance_m < 0 || c.distance < r->min_part_distance_m)) {
        r->min_part_distance_m = c.distance;
        r->closest_parts = parts[a].name + "/" + parts[b].name;
      }
    }
  if (r->min_part_distance_m >= 0 && r->min_part_distance_m < 0.99 * d)
    r->problems.push_back(fmt::format("parts {} are {:.3f} mm apart (clearance {:.3f} mm)",
                                      r->closest_parts, r->min_part_distance_m * 1e3, d * 1e3));
  return {};
}

// The largest factor in [0.1, 1] of a range for which `clean(factor)` holds, assuming that less
// range collides less: 0.1 first (false: nothing found), then three halvings of [0.1, 1), so to
// about 0.1. `clean(1)` is known to be false.
template <typename Clean>
Result<bool> largest_clean_factor(Clean clean, double* factor) {
  HC_ASSIGN_OR_RETURN(bool ok, clean(0.1));
  if (!ok) return false;
  double good = 0.1, bad = 1.0;
  for (int k = 0; k < 3; ++k) {
    const double mid = 0.5 * (good + bad);
    HC_ASSIGN_OR_RETURN(ok, clean(mid));
    (ok ? good : bad) = mid;
  }
  *factor = good;
  return true;
}

// What one joint's check needs besides the joint.
struct JointCheckInput {
  const std::vector<CarvedPart>& parts;
  const std::vector<std::unique_ptr<geometry::MeshProximity>>& trees;
  const std::vector<JointHull>& hulls;
  const PartTree& tree;
  const VerificationOptions& options;
  double bump_zone;
};

// Joint i: its sides are separate parts, a ball cannot be pulled out of its socket, and the
// moving side does not cross the rest anywhere in the joint's range.
Result<JointCheck> check_joint(const JointCheckInput& in, const Joint& j, std::size_t i,
                               std::vector<std::string>* problems) {
  JointCheck jc;
  jc.joint = static_cast<int>(i);
  jc.parent_part = in.tree.joint_parent_part[i];
  jc.child_part = in.tree.joint_child_part[i];
  if (jc.parent_part < 0 || jc.child_part < 0 || jc.parent_part == jc.child_part) {
    problems->push_back(
        fmt::format("joint {} -> {} did not separate its sides", j.parent_name, j.child_name));
    return jc;
  }
  if (j.type == JointType::kBall) {
    // Pull a ball (radius r' less a hair) out along n: the lip must stop it.
    jc.ball_held = false;
    const TriangleMesh ball = sphere_mesh(j.ball.ball_radius * 0.995, 32, Facet::kInscribed);
    for (double t = j.ball.r / 16; t <= 2 * j.ball.r && !jc.ball_held; t += j.ball.r / 16) {
      TriangleMesh at = ball;
      at.vertices.rowwise() += (j.centre + t * j.n).transpose();
      HC_ASSIGN_OR_RETURN(const auto hit,
                          in.trees[static_cast<std::size_t>(jc.parent_part)]->crossings(at, 1));
      jc.ball_held = !hit.empty();
    }
    if (!jc.ball_held)
      problems->push_back(
          fmt::format("ball {} -> {} can leave its socket", j.parent_name, j.child_name));
  }
  if (in.options.sweeps) {
    const Sets sets = split_sets(in.parts, in.tree.moving[i]);
    HC_ASSIGN_OR_RETURN(const geometry::MeshProximity fixed,
                        geometry::MeshProximity::build(sets.fixed));
    // Range poses of `range` whose moving side crosses the rest, and how many poses there were.
    const auto sweep = [&](const Joint& range) -> Result<std::pair<int, int>> {
      int poses = 0, collisions = 0;
      for (const Eigen::Matrix3d& rot : sweep_rotations(range, in.options.sweep_step_rad)) {
        const Eigen::Isometry3d pose = rotation_about(range.centre, rot);
        ++poses;
        HC_ASSIGN_OR_RETURN(const auto hits, fixed.crossings(moved(sets.moving, pose), 64));
        std::vector<Eigen::Vector3d> bumps;
        for (const auto& b : in.hulls[i].bumps) bumps.push_back(pose * b);
        if (real_crossing(hits, bumps, in.bump_zone)) ++collisions;
      }
      return std::pair{poses, collisions};
    };
    HC_ASSIGN_OR_RETURN(const auto designed, sweep(j));
    std::tie(jc.sweep_poses, jc.sweep_collisions) = designed;
    bool narrowed = false;
    if (jc.sweep_collisions > 0 && in.options.narrow_ranges) {
      const auto clean = [&](double factor) -> Result<bool> {
        Joint range = j;
        narrow_range(range, factor);
        HC_ASSIGN_OR_RETURN(const auto s, sweep(range));
        return s.second == 0;
      };
      HC_ASSIGN_OR_RETURN(narrowed, largest_clean_factor(clean, &jc.range_factor));
    }
    if (jc.sweep_collisions > 0 && !narrowed)
      problems->push_back(
          fmt::format("joint {} -> {}: {} of {} range poses collide{}", j.parent_name, j.child_name,
                      jc.sweep_collisions, jc.sweep_poses,
                      in.options.narrow_ranges ? ", also at 10 % of the range" : ""));
  }
  return jc;
}

// Forward kinematics over the part tree for one frame: root fixed, each child turned about its
// joint by the links' relative rotation, clamped to the joint's range.
std::vector<Eigen::Isometry3d> frame_poses(const PartTree& tree, const std::vector<Joint>& joints,
                                           std::size_t num_parts,
                                           const std::vector<Eigen::Isometry3d>& frame) {
  std::vector<Eigen::Isometry3d> pose(num_parts, Eigen::Isometry3d::Identity());
  std::vector<char> done(num_parts, 0);
  done[static_cast<std::size_t>(tree.root)] = 1;
  for (bool progress_made = true; progress_made;) {
    progress_made = false;
    for (std::size_t i = 0; i < joints.size(); ++i) {
      const int pp = tree.joint_parent_part[i], cp = tree.joint_child_part[i];
      if (joints[i].excluded || pp < 0 || cp < 0 || !done[static_cast<std::size_t>(pp)] ||
          done[static_cast<std::size_t>(cp)])
        continue;
      const Eigen::Matrix3d rel =
          frame[static_cast<std::size_t>(joints[i].parent_link)].linear().transpose() *
          frame[static_cast<std::size_t>(joints[i].child_link)].linear();
      pose[static_cast<std::size_t>(cp)] =
          pose[static_cast<std::size_t>(pp)] *
          rotation_about(joints[i].centre, clamp_to_range(joints[i], rel));
      done[static_cast<std::size_t>(cp)] = 1;
      progress_made = true;
    }
  }
  return pose;
}

// One clip replayed on the rigid parts (at most options.max_frames_per_clip frames): the share
// of frames in which no two parts cross, and the pairs that did.
Result<ClipReplay> replay_clip(const std::vector<CarvedPart>& parts,
                               const std::vector<Joint>& joints,
                               const std::vector<JointHull>& hulls, const PartTree& tree,
                               const std::vector<std::vector<Eigen::Isometry3d>>& frames,
                               const std::string& name, int max_frames, double bump_zone) {
  ClipReplay replay;
  replay.clip = name;
  const int n = static_cast<int>(frames.size());
  const int stride = std::max(1, n / max_frames);
  std::set<std::pair<int, int>> pairs_seen;
  for (int f = 0; f < n; f += stride) {
    const std::vector<Eigen::Isometry3d> pose =
        frame_poses(tree, joints, parts.size(), frames[static_cast<std::size_t>(f)]);
    std::vector<Eigen::Vector3d> bumps;
    for (std::size_t i = 0; i < joints.size(); ++i)
      if (!joints[i].excluded && tree.joint_child_part[i] >= 0)
        for (const auto& b : hulls[i].bumps)
          bumps.push_back(pose[static_cast<std::size_t>(tree.joint_child_part[i])] * b);
    bool collided = false;
    std::vector<TriangleMesh> posed;
    for (std::size_t p = 0; p < parts.size(); ++p) posed.push_back(moved(parts[p].mesh, pose[p]));
    for (std::size_t a = 0; a < parts.size(); ++a)
      for (std::size_t b = a + 1; b < parts.size(); ++b) {
        const Eigen::AlignedBox3d ba(posed[a].vertices.colwise().minCoeff().transpose(),
                                     posed[a].vertices.colwise().maxCoeff().transpose());
        const Eigen::AlignedBox3d bb(posed[b].vertices.colwise().minCoeff().transpose(),
                                     posed[b].vertices.colwise().maxCoeff().transpose());
        if (!ba.intersects(bb)) continue;
        HC_ASSIGN_OR_RETURN(const geometry::MeshProximity pb,
                            geometry::MeshProximity::build(posed[b]));
        HC_ASSIGN_OR_RETURN(const auto hits, pb.crossings(posed[a], 64));
        if (real_crossing(hits, bumps, bump_zone)) {
          collided = true;
          pairs_seen.insert({static_cast<int>(a), static_cast<int>(b)});
        }
      }
    ++replay.frames;
    if (!collided) ++replay.collision_free;
  }
  replay.share = replay.frames > 0 ? double(replay.collision_free) / replay.frames : 1.0;
  for (const auto& [a, b] : pairs_seen) {
    replay.colliding_parts.emplace_back(a, b);
    replay.colliding_pairs.push_back(parts[static_cast<std::size_t>(a)].name + "/" +
                                     parts[static_cast<std::size_t>(b)].name);
  }
  return replay;
}

struct ReplayInput {
  const std::vector<CarvedPart>& parts;
  const std::vector<JointHull>& hulls;
  const PartTree& tree;
  const LinkMotion& motion;
  const std::vector<Clip>& clips;
  const VerificationOptions& options;
  double bump_zone;
};

// Every clip replayed with the joints' ranges as given: the clips' reports and the share of
// collision-free frames over all of them.
Result<double> replay_clips(const ReplayInput& in, const std::vector<Joint>& joints,
                            std::vector<ClipReplay>* out) {
  out->clear();
  int frames = 0, free = 0;
  for (std::size_t c = 0; c < in.clips.size() && c < in.motion.transforms.size(); ++c) {
    HC_ASSIGN_OR_RETURN(
        ClipReplay replay,
        replay_clip(in.parts, joints, in.hulls, in.tree, in.motion.transforms[c], in.clips[c].name,
                    in.options.max_frames_per_clip, in.bump_zone));
    frames += replay.frames;
    free += replay.collision_free;
    out->push_back(std::move(replay));
  }
  return frames > 0 ? double(free) / frames : 1.0;
}

// The replay at the designed ranges fell short: the joints between the parts that collided
// (one side of them moves with the joint, the other does not) lose range together. The
// largest factor in [0.1, 1] that reaches the required share, by bisection assuming that less
// range collides less: 0.1 first (if even that fails, nothing is narrowed), then three halvings.
// Returns whether it tried (some joint lies between colliding parts).
Result<bool> narrow_for_replay(const ReplayInput& in, const std::vector<Joint>& joints,
                               VerificationReport* r) {
  std::set<std::size_t> culprits;
  for (const ClipReplay& c : r->clips)
    for (const auto& [a, b] : c.colliding_parts)
      for (std::size_t i = 0; i < joints.size(); ++i) {
        if (joints[i].excluded || i >= in.tree.moving.size()) continue;
        const auto& m = in.tree.moving[i];
        const bool has_a = std::find(m.begin(), m.end(), a) != m.end();
        const bool has_b = std::find(m.begin(), m.end(), b) != m.end();
        if (has_a != has_b) culprits.insert(i);
      }
  if (culprits.empty()) return false;
  const double required = in.options.replay_required_share;
  std::vector<ClipReplay> clips, good_clips;
  const auto clean = [&](double factor) -> Result<bool> {
    std::vector<Joint> narrowed = joints;
    for (std::size_t i : culprits) narrow_range(narrowed[i], factor);
    HC_ASSIGN_OR_RETURN(const double share, replay_clips(in, narrowed, &clips));
    if (share >= required) good_clips = clips;
    return share >= required;
  };
  double factor = 1.0;
  HC_ASSIGN_OR_RETURN(const bool found, largest_clean_factor(clean, &factor));
  if (!found) return true;
  r->clips = std::move(good_clips);
  int frames = 0, free = 0;
  for (const ClipReplay& c : r->clips) {
    frames += c.frames;
    free += c.collision_free;
  }
  r->replay_share = frames > 0 ? double(free) / frames : 1.0;
  for (std::size_t i : culprits) {
    auto it = std::find_if(r->narrowed.begin(), r->narrowed.end(),
                           [&](const RangeNarrowing& n) { return n.joint == static_cast<int>(i); });
    if (it == r->narrowed.end()) it = r->narrowed.insert(r->narrowed.end(), {static_cast<int>(i)});
    it->factor *= factor;
    it->by_replay = true;
  }
  return true;
}

}  // namespace

void narrow_range(Joint& joint, double factor) {
  joint.swing.forward *= factor;
  joint.swing.backward *= factor;
  joint.cone.phi_f *= factor;
  joint.cone.phi_a *= factor;
}

Result<VerificationReport> verify_articulation(
    const std::vector<CarvedPart>& parts, const std::vector<Joint>& joints,
    const std::vector<JointHull>& hulls, const LinkMotion* motion, const std::vector<Clip>& clips,
    const VerificationOptions& options, ProgressReporter* progress) {
  VerificationReport r;
  const double d = options.clearance_m;
  ProgressTask task(progress, "verification", parts.size() + joints.size());
  HC_RETURN_IF_ERROR(check_parts(parts, joints, options, &task, &r));
  std::vector<std::unique_ptr<geometry::MeshProximity>> trees;
  for (const CarvedPart& p : parts) {
    HC_ASSIGN_OR_RETURN(geometry::MeshProximity t, geometry::MeshProximity::build(p.mesh));
    trees.push_back(std::make_unique<geometry::MeshProximity>(std::move(t)));
  }
  double bump_zone = 0.0;
  for (std::size_t i = 0; i < joints.size(); ++i)
    if (!joints[i].excluded && i < hulls.size())
      bump_zone = std::max(bump_zone, 1.2 * (hulls[i].bump_radius_m + d));
  HC_RETURN_IF_ERROR(check_clearance(parts, trees, d, &r));

  HC_ASSIGN_OR_RETURN(const PartTree tree, part_tree(parts, joints));
  const JointCheckInput in{parts, trees, hulls, tree, options, bump_zone};
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].excluded) continue;
    task.advance();
    HC_ASSIGN_OR_RETURN(JointCheck jc, check_joint(in, joints[i], i, &r.problems));
    r.joints.push_back(jc);
  }
  // The clips replay on the ranges the sweeps left.
  std::vector<Joint> usable = joints;
  for (const JointCheck& jc : r.joints) {
    if (jc.range_factor >= 1.0) continue;
    narrow_range(usable[static_cast<std::size_t>(jc.joint)], jc.range_factor);
    r.narrowed.push_back({jc.joint, jc.range_factor, true, false});
  }

  bool narrowing_tried = false;
  if (options.replay && motion != nullptr) {
    const ReplayInput replay{parts, hulls, tree, *motion, clips, options, bump_zone};
    HC_ASSIGN_OR_RETURN(r.replay_share, replay_clips(replay, usable, &r.clips));
    r.replay_share_before_narrowing = r.replay_share;
    if (r.replay_share < options.replay_required_share && options.narrow_ranges) {
      HC_ASSIGN_OR_RETURN(narrowing_tried, narrow_for_replay(replay, usable, &r));
    }
  }
  if (r.replay_share < options.replay_required_share)
    r.problems.push_back(fmt::format(
        "clip replay: {:.0f} % of frames without collision (< {:.0f} %){}", 100 * r.replay_share,
        100 * options.replay_required_share,
        narrowing_tried ? ", even with the ranges of the joints between the colliding parts at 10 %"
                        : ""));
  r.ok = r.problems.empty();
  return r;
}

}  // namespace hc::articulation
