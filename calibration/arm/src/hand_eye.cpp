#include "calibration/arm/hand_eye.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <fmt/format.h>

#include <Eigen/SVD>
#include <chrono>
#include <cmath>
#include <numbers>

namespace hc::calib {
namespace {

// r = p - R0^T Exp(-dq) (T o - t): the observed rig-frame point minus the tool point mapped into
// the rig frame. dq is a world-frame rotation perturbation of the initial rotation R0.
struct HandEyeResidual {
  HandEyeResidual(const Eigen::Matrix3d& r0, const Eigen::Isometry3d& tool,
                  const Eigen::Vector3d& p)
      : r0_(r0), tool_(tool), p_(p) {}
  template <typename T>
  bool operator()(const T* dq, const T* t, const T* o, T* r) const {
    using V3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const V3> off(o);
    const V3 world = tool_.linear().cast<T>() * off + tool_.translation().cast<T>();
    const V3 w = world - Eigen::Map<const V3>(t);
    const T minus_dq[3] = {-dq[0], -dq[1], -dq[2]};
    T rotated[3];
    const T wp[3] = {w[0], w[1], w[2]};
    ceres::AngleAxisRotatePoint(minus_dq, wp, rotated);
    const V3 rig = r0_.transpose().cast<T>() * Eigen::Map<const V3>(rotated);
    for (int k = 0; k < 3; ++k) r[k] = T(p_[k]) - rig[k];
    return true;
  }
  Eigen::Matrix3d r0_;
  Eigen::Isometry3d tool_;
  Eigen::Vector3d p_;
};

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& v) {
  const double a = v.norm();
  if (a < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, v / a).toRotationMatrix();
}

// Marker j's offset when the options give it.
std::optional<Eigen::Vector3d> known_offset(const HandEyeOptions& options, std::size_t j) {
  if (options.known_offsets_m.empty()) return std::nullopt;
  return options.known_offsets_m[j];
}

// What the observations cover: per marker how often it is seen, per pose whether it is used.
struct Coverage {
  std::vector<int> marker_count;
  std::vector<bool> pose_used;
  std::size_t n_poses = 0;
};

// The problem's poses and observations are well formed and cover enough to solve.
Result<Coverage> check_problem(const HandEyeProblem& problem, const HandEyeOptions& options) {
  const std::size_t n_markers = problem.markers;
  const auto& poses = problem.world_from_tool;
  const auto& obs = problem.observations;
  if (n_markers == 0) return invalid_argument("hand-eye: no markers");
  if (!options.known_offsets_m.empty() && options.known_offsets_m.size() != n_markers)
    return invalid_argument(fmt::format("hand-eye: {} known offsets for {} markers",
                                        options.known_offsets_m.size(), n_markers));
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Matrix3d& r = poses[i].linear();
    if (!poses[i].matrix().allFinite() ||
        (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 || r.determinant() < 0.0)
      return invalid_argument(fmt::format("hand-eye: pose {} is not a rigid transform", i));
  }
  Coverage c;
  c.marker_count.assign(n_markers, 0);
  c.pose_used.assign(poses.size(), false);
  for (std::size_t k = 0; k < obs.size(); ++k) {
    if (obs[k].pose >= poses.size() || obs[k].marker >= n_markers)
      return invalid_argument(
          fmt::format("hand-eye: observation {} names pose {} / marker {} "
                      "({} poses, {} markers)",
                      k, obs[k].pose, obs[k].marker, poses.size(), n_markers));
    if (!obs[k].p_rig_m.allFinite())
      return invalid_argument(fmt::format("hand-eye: observation {} is not finite", k));
    ++c.marker_count[obs[k].marker];
    c.pose_used[obs[k].pose] = true;
  }
  for (std::size_t j = 0; j < n_markers; ++j)
    if (c.marker_count[j] == 0 && !known_offset(options, j))
      return failed_precondition(fmt::format("hand-eye: marker {} is never observed", j));
  for (bool u : c.pose_used) c.n_poses += u ? 1 : 0;
  if (obs.size() < 4 || c.n_poses < 3)
    return failed_precondition(fmt::format(
        "hand-eye: {} observations at {} poses; need at least 4 observations at 3 poses",
        obs.size(), c.n_poses));
  return c;
}

// Observability of the offsets against world_from_rig's translation: how the tool rotates
// (out.rotation_excitation), and which constraint the options add when that is not enough
// (out.constraint).
Status check_rotations(const HandEyeProblem& problem, const HandEyeOptions& options,
                       const std::vector<bool>& pose_used, HandEyeResult& out) {
  const auto& poses = problem.world_from_tool;
  std::size_t first = 0;
  while (!pose_used[first]) ++first;
  std::vector<Eigen::Vector3d> axes;  // tool frame
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (!pose_used[i]) continue;
    const Eigen::AngleAxisd aa(poses[first].linear().transpose() * poses[i].linear());
    if (aa.angle() > options.min_rotation_rad) axes.push_back(aa.axis());
  }
  bool single_axis = !axes.empty();
  for (const Eigen::Vector3d& a : axes)
    if (a.cross(axes.front()).norm() > 1e-3) single_axis = false;
  const bool have_known0 = known_offset(options, 0).has_value();
  if (axes.empty()) {
    out.rotation_excitation = "none";
    if (!have_known0)
      return failed_precondition(
          "hand-eye: the tool never rotates (pure translation): the markers' tool-frame offsets "
          "and world_from_rig's translation are not separately observable; give marker 0's offset "
          "(known_offsets_m) or rotate the tool");
    out.constraint = "marker 0 offset known (pure translation)";
  } else if (single_axis) {
    out.rotation_excitation = "single axis";
    const bool axis_is_z = std::abs(axes.front().z()) > 1.0 - 1e-6;
    if (have_known0) {
      out.constraint = "marker 0 offset known";
    } else if (options.marker0_tool_z_m && axis_is_z) {
      out.constraint = fmt::format(
          "marker 0 tool z = {} m (rotation about tool z only: the offsets' z and "
          "world_from_rig's translation along the axis are not separately observable)",
          *options.marker0_tool_z_m);
    } else {
      return failed_precondition(fmt::format(
          "hand-eye: every rotation is about one axis (tool [{:.3f}, {:.3f}, {:.3f}]; a 4-DOF arm "
          "turns only in yaw): a shift of the marker offsets along it is indistinguishable from a "
          "shift of world_from_rig; give marker 0's offset along it ({}) or rotate about a "
          "second axis",
          axes.front().x(), axes.front().y(), axes.front().z(),
          axis_is_z ? "marker0_tool_z_m" : "known_offsets_m"));
    }
  } else {
    out.rotation_excitation = "multiple axes";
    out.constraint = have_known0 ? "marker 0 offset known" : "none needed";
  }
  return {};
}

// Observability of world_from_rig's rotation: the observed points must not lie on a line.
Status check_spread(const std::vector<HandEyeObservation>& obs, const HandEyeOptions& options) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& o : obs) mean += o.p_rig_m;
  mean /= static_cast<double>(obs.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& o : obs) cov += (o.p_rig_m - mean) * (o.p_rig_m - mean).transpose();
  const Eigen::Vector3d sv =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov / static_cast<double>(obs.size()))
          .eigenvalues();  // ascending
  if (std::sqrt(std::max(0.0, sv[1])) < options.min_spread_m)
    return failed_precondition(fmt::format(
        "hand-eye: the observed marker positions are collinear (second principal spread {:.2e} "
        "m < {} m): world_from_rig's rotation about that line is not observable; move the arm "
        "off the line",
        std::sqrt(std::max(0.0, sv[1])), options.min_spread_m));
  return {};
}

// world_from_rig and the marker offsets.
struct HandEyeEstimate {
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> off;
};

double rms_of(const HandEyeProblem& problem, const HandEyeEstimate& e) {
  double ss = 0.0;
  for (const auto& o : problem.observations)
    ss += (o.p_rig_m - e.x.inverse() * (problem.world_from_tool[o.pose] * e.off[o.marker]))
              .squaredNorm();
  return std::sqrt(ss / static_cast<double>(problem.observations.size()));
}

// 1. Alternation from a closed form: world_from_rig by Umeyama for the current offsets, then
// each unknown offset as the mean of its observations mapped into the tool frame.
HandEyeEstimate alternate(const HandEyeProblem& problem, const HandEyeOptions& options,
                          const std::vector<int>& marker_count) {
  const std::size_t n_markers = problem.markers;
  const auto& poses = problem.world_from_tool;
  const auto& obs = problem.observations;
  HandEyeEstimate e;
  e.off.assign(n_markers, Eigen::Vector3d::Zero());
  for (std::size_t j = 0; j < n_markers; ++j)
    if (known_offset(options, j)) e.off[j] = *known_offset(options, j);
  if (!known_offset(options, 0) && options.marker0_tool_z_m)
    e.off[0].z() = *options.marker0_tool_z_m;
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(obs.size()));
  Eigen::Matrix3Xd dst(3, static_cast<Eigen::Index>(obs.size()));
  for (int round = 0; round < options.alternation_rounds; ++round) {
    for (std::size_t k = 0; k < obs.size(); ++k) {
      src.col(static_cast<Eigen::Index>(k)) = obs[k].p_rig_m;
      dst.col(static_cast<Eigen::Index>(k)) = poses[obs[k].pose] * e.off[obs[k].marker];
    }
    e.x.matrix() = Eigen::umeyama(src, dst, false);
    std::vector<Eigen::Vector3d> sum(n_markers, Eigen::Vector3d::Zero());
    for (const auto& o : obs) sum[o.marker] += poses[o.pose].inverse() * (e.x * o.p_rig_m);
    for (std::size_t j = 0; j < n_markers; ++j) {
      if (known_offset(options, j) || marker_count[j] == 0) continue;
      const Eigen::Vector3d m = sum[j] / marker_count[j];
      if (j == 0 && options.marker0_tool_z_m)
        e.off[j] = Eigen::Vector3d(m.x(), m.y(), *options.marker0_tool_z_m);
      else
        e.off[j] = m;
    }
  }
  return e;
}

// 2. The Ceres refinement: world_from_rig's rotation as a perturbation dq of r0 (the alternation's)
// and its translation t, the offsets o. Ceres holds pointers to these parameter blocks.
struct Refinement {
  Refinement(const HandEyeEstimate& e, std::size_t n_markers)
      : r0(e.x.linear()),
        t{e.x.translation().x(), e.x.translation().y(), e.x.translation().z()},
        o(n_markers) {
    for (std::size_t j = 0; j < n_markers; ++j) o[j] = {e.off[j].x(), e.off[j].y(), e.off[j].z()};
  }
  const Eigen::Matrix3d r0;
  double dq[3] = {0.0, 0.0, 0.0};
  double t[3];
  std::vector<std::array<double, 3>> o;
  ceres::Problem pb;
};

void add_residuals(const HandEyeProblem& problem, const HandEyeOptions& options, Refinement& r) {
  for (const auto& ob : problem.observations)
    r.pb.AddResidualBlock(
        new ceres::AutoDiffCostFunction<HandEyeResidual, 3, 3, 3, 3>(
            new HandEyeResidual(r.r0, problem.world_from_tool[ob.pose], ob.p_rig_m)),
        new ceres::HuberLoss(options.huber_m), r.dq, r.t, r.o[ob.marker].data());
  for (std::size_t j = 0; j < problem.markers; ++j) {
    if (!r.pb.HasParameterBlock(r.o[j].data())) continue;
    if (known_offset(options, j))
      r.pb.SetParameterBlockConstant(r.o[j].data());
    else if (j == 0 && options.marker0_tool_z_m)
      r.pb.SetManifold(r.o[j].data(), new ceres::SubsetManifold(3, {2}));
  }
}

// Gross outliers (mismatched dots) still pull a Huber fit by huber_m each: drop residuals past
// 3 huber_m (true when any was).
bool drop_gross_outliers(const HandEyeProblem& problem, const HandEyeOptions& options,
                         Refinement& r) {
  const auto& obs = problem.observations;
  const Eigen::Matrix3d rr = exp_so3(Eigen::Vector3d(r.dq[0], r.dq[1], r.dq[2])) * r.r0;
  const Eigen::Vector3d tt(r.t[0], r.t[1], r.t[2]);
  std::vector<ceres::ResidualBlockId> ids;
  r.pb.GetResidualBlocks(&ids);
  bool dropped = false;
  for (std::size_t k = 0; k < obs.size() && ids.size() == obs.size(); ++k) {
    const auto& ob = obs[k];
    const Eigen::Vector3d oj(r.o[ob.marker][0], r.o[ob.marker][1], r.o[ob.marker][2]);
    const double e =
        (ob.p_rig_m - rr.transpose() * (problem.world_from_tool[ob.pose] * oj - tt)).norm();
    if (e > 3.0 * options.huber_m) {
      r.pb.RemoveResidualBlock(ids[k]);
      dropped = true;
    }
  }
  return dropped;
}

// Solves, drops the gross outliers and solves again (one round; the Huber loss handles the rest).
// Returns world_from_rig and the offsets.
Result<HandEyeEstimate> refine(const HandEyeProblem& problem, const HandEyeOptions& options,
                               Refinement& r, HandEyeResult& out) {
  add_residuals(problem, options, r);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = 1e-14;
  so.parameter_tolerance = 1e-14;
  so.gradient_tolerance = 1e-16;
  ceres::Solver::Summary ss;
  ceres::Solve(so, &r.pb, &ss);
  if (drop_gross_outliers(problem, options, r)) ceres::Solve(so, &r.pb, &ss);
  out.iterations = static_cast<int>(ss.iterations.size());
  out.converged = ss.termination_type == ceres::CONVERGENCE;
  HandEyeEstimate e;
  e.x.linear() = exp_so3(Eigen::Vector3d(r.dq[0], r.dq[1], r.dq[2])) * r.r0;
  e.x.translation() = Eigen::Vector3d(r.t[0], r.t[1], r.t[2]);
  for (std::size_t j = 0; j < problem.markers; ++j)
    e.off.emplace_back(r.o[j][0], r.o[j][1], r.o[j][2]);
  if (!e.x.matrix().allFinite())
    return failed_precondition("hand-eye: the refinement diverged: " + ss.BriefReport());
  return e;
}

// Residual statistics of the solution in `out` (max, outliers, inlier RMS); returns the inliers'
// sum of squares.
Result<double> score_fit(const HandEyeProblem& problem, const HandEyeOptions& options,
                         HandEyeResult& out) {
  const auto& obs = problem.observations;
  double sq = 0.0;  // over the inliers
  for (const auto& ob : obs) {
    const double e =
        (ob.p_rig_m - out.world_from_rig.inverse() *
                          (problem.world_from_tool[ob.pose] * out.offsets_m[ob.marker]))
            .norm();
    out.max_m = std::max(out.max_m, e);
    if (e > 3.0 * options.huber_m)
      ++out.outliers;
    else
      sq += e * e;
  }
  const std::size_t inliers = obs.size() - out.outliers;
  if (inliers < 4)
    return failed_precondition(fmt::format("hand-eye: only {} of {} observations fit within {} m",
                                           inliers, obs.size(), 3.0 * options.huber_m));
  out.rms_m = std::sqrt(sq / static_cast<double>(inliers));
  return sq;
}

// 3. Standard deviations from the covariance, scaled by the inliers' residual variance.
Status add_std_devs(const HandEyeProblem& problem, const HandEyeOptions& options,
                    const std::vector<int>& marker_count, double sq, Refinement& r,
                    HandEyeResult& out) {
  const std::size_t n_markers = problem.markers;
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks{{r.dq, r.dq}, {r.t, r.t}};
  for (std::size_t j = 0; j < n_markers; ++j)
    if (r.pb.HasParameterBlock(r.o[j].data()) && !known_offset(options, j))
      blocks.emplace_back(r.o[j].data(), r.o[j].data());
  if (!cov.Compute(blocks, &r.pb))
    return failed_precondition(
        "hand-eye: the poses leave part of world_from_rig or of the marker offsets unobservable "
        "(rank-deficient Jacobian); vary the arm's position in all three directions and its yaw");
  int free_params = 6;
  for (std::size_t j = 0; j < n_markers; ++j)
    if (!known_offset(options, j) && marker_count[j] > 0)
      free_params += (j == 0 && options.marker0_tool_z_m) ? 2 : 3;
  const std::size_t inliers = problem.observations.size() - out.outliers;
  const double dof = std::max(1.0, 3.0 * static_cast<double>(inliers) - free_params);
  const double s2 = sq / dof;
  double c[9];
  cov.GetCovarianceBlock(r.dq, r.dq, c);
  for (int k = 0; k < 3; ++k) out.rotation_std_rad[k] = std::sqrt(std::max(0.0, c[4 * k] * s2));
  cov.GetCovarianceBlock(r.t, r.t, c);
  for (int k = 0; k < 3; ++k) out.translation_std_m[k] = std::sqrt(std::max(0.0, c[4 * k] * s2));
  out.offsets_std_m.assign(n_markers, Eigen::Vector3d::Zero());
  for (std::size_t j = 0; j < n_markers; ++j) {
    if (known_offset(options, j) || !r.pb.HasParameterBlock(r.o[j].data())) continue;
    cov.GetCovarianceBlock(r.o[j].data(), r.o[j].data(), c);
    for (int k = 0; k < 3; ++k) out.offsets_std_m[j][k] = std::sqrt(std::max(0.0, c[4 * k] * s2));
  }
  return {};
}

}  // namespace

Eigen::Isometry3d arm_pose_transform(double x_m, double y_m, double z_m, double yaw_rad) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(x_m, y_m, z_m);
  return t;
}

Status HandEyeOptions::validate() const {
  if (!(huber_m > 0.0) || !std::isfinite(huber_m)) return invalid_argument("huber_m must be > 0");
  if (max_iterations < 1) return invalid_argument("max_iterations must be >= 1");
  if (alternation_rounds < 1) return invalid_argument("alternation_rounds must be >= 1");
  if (!(min_rotation_rad > 0.0)) return invalid_argument("min_rotation_rad must be > 0");
  if (!(min_spread_m > 0.0)) return invalid_argument("min_spread_m must be > 0");
  if (marker0_tool_z_m && !std::isfinite(*marker0_tool_z_m))
    return invalid_argument("marker0_tool_z_m must be finite");
  for (const auto& k : known_offsets_m)
    if (k && !k->allFinite()) return invalid_argument("known offsets must be finite");
  return {};
}

Json HandEyeResult::to_json() const {
  Json offsets = Json::array(), offsets_std = Json::array();
  for (const auto& o : offsets_m) offsets.push_back(eigen_to_json(o));
  for (const auto& o : offsets_std_m) offsets_std.push_back(eigen_to_json(o));
  const Eigen::AngleAxisd aa(world_from_rig.linear());
  return Json{{"world_from_rig", eigen_to_json(world_from_rig.matrix())},
              {"rotation_deg", aa.angle() * 180.0 / std::numbers::pi},
              {"translation_m", eigen_to_json(world_from_rig.translation())},
              {"rotation_std_deg", eigen_to_json(rotation_std_rad * 180.0 / std::numbers::pi)},
              {"translation_std_m", eigen_to_json(translation_std_m)},
              {"marker_offsets_m", offsets},
              {"marker_offsets_std_m", offsets_std},
              {"rms_m", rms_m},
              {"max_m", max_m},
              {"initial_rms_m", initial_rms_m},
              {"observations", observations},
              {"poses", poses},
              {"outliers", outliers},
              {"rotation_excitation", rotation_excitation},
              {"constraint", constraint},
              {"iterations", iterations},
              {"converged", converged},
              {"time_s", time_s}};
}

Result<HandEyeResult> solve_hand_eye(const HandEyeProblem& problem, const HandEyeOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_ASSIGN_OR_RETURN(const Coverage coverage, check_problem(problem, options));
  HandEyeResult out;
  out.observations = problem.observations.size();
  out.poses = coverage.n_poses;
  HC_RETURN_IF_ERROR(check_rotations(problem, options, coverage.pose_used, out));
  HC_RETURN_IF_ERROR(check_spread(problem.observations, options));

  const HandEyeEstimate initial = alternate(problem, options, coverage.marker_count);
  out.initial_rms_m = rms_of(problem, initial);
  Refinement r(initial, problem.markers);
  HC_ASSIGN_OR_RETURN(const HandEyeEstimate refined, refine(problem, options, r, out));
  out.world_from_rig = refined.x;
  out.offsets_m = refined.off;
  HC_ASSIGN_OR_RETURN(const double sq, score_fit(problem, options, out));
  HC_RETURN_IF_ERROR(add_std_devs(problem, options, coverage.marker_count, sq, r, out));
  out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace hc::calib
