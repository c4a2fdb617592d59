// calibrate_rig (see calibrate.h): single-camera OpenCV calibrations chained along the cameras'
// shared views, then the joint bundle adjustment (Ceres).
#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <fmt/format.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>

#include "calibration/cameras/calibrate.h"
#include "common/openmp.h"
#include "opencv_calibration.h"

namespace hc::calib {

namespace {

// Views per camera for the single-camera OpenCV calibration that initialises calibrate_rig.
constexpr int kInitViews = 10;

// Pose as x_out = R x_in + t.
struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Pose inverse() const { return {R.transpose(), -R.transpose() * t}; }
  Pose operator*(const Pose& o) const { return {R * o.R, R * o.t + t}; }
};

Pose pose_from_rvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat Rm;
  cv::Rodrigues(rvec, Rm);
  Pose p;
  cv::Mat Rd, td;
  Rm.convertTo(Rd, CV_64F);
  tvec.convertTo(td, CV_64F);
  cv::cv2eigen(Rd, p.R);
  for (int i = 0; i < 3; ++i) p.t(i) = td.at<double>(i);
  return p;
}

void to_params(const Pose& p, double* out6) {
  ceres::RotationMatrixToAngleAxis(ceres::ColumnMajorAdapter3x3(p.R.data()), out6);
  for (int i = 0; i < 3; ++i) out6[3 + i] = p.t(i);
}

Pose from_params(const double* in6) {
  Pose p;
  ceres::AngleAxisToRotationMatrix(in6, ceres::ColumnMajorAdapter3x3(p.R.data()));
  p.t = Eigen::Vector3d(in6[3], in6[4], in6[5]);
  return p;
}

// Mean of poses (rotation: normalised quaternion mean with signs aligned to the first; fine for
// the nearby estimates of an initial guess).
Pose average(const std::vector<Pose>& poses) {
  Eigen::Vector4d q_sum = Eigen::Vector4d::Zero();
  Eigen::Vector3d t_sum = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q0(poses.front().R);
  for (const Pose& p : poses) {
    Eigen::Quaterniond q(p.R);
    if (q.coeffs().dot(q0.coeffs()) < 0.0) q.coeffs() *= -1.0;
    q_sum += q.coeffs();
    t_sum += p.t;
  }
  Eigen::Quaterniond q;
  q.coeffs() = q_sum.normalized();
  return {q.toRotationMatrix(), t_sum / static_cast<double>(poses.size())};
}

// OpenCV's distortion model (k1 k2 p1 p2 k3), as CameraModel::distort_normalized.
template <typename T>
void project(const T* intr, bool fix_aspect, const T* xc, T* uv) {
  const T x = xc[0] / xc[2], y = xc[1] / xc[2];
  const T r2 = x * x + y * y;
  const T radial = T(1.0) + r2 * (intr[4] + r2 * (intr[5] + r2 * intr[8]));
  const T xd = x * radial + T(2.0) * intr[6] * x * y + intr[7] * (r2 + T(2.0) * x * x);
  const T yd = y * radial + intr[6] * (r2 + T(2.0) * y * y) + T(2.0) * intr[7] * x * y;
  const T fy = fix_aspect ? intr[0] : intr[1];
  uv[0] = intr[0] * xd + intr[2];
  uv[1] = fy * yd + intr[3];
}

struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector3d& X, const Eigen::Vector2d& obs, bool fix_aspect)
      : X_(X), obs_(obs), fix_aspect_(fix_aspect) {}
  // cam: rig -> camera (angle-axis, t); view: board -> rig.
  template <typename T>
  bool operator()(const T* intr, const T* cam, const T* view, T* residual) const {
    const T Xb[3] = {T(X_.x()), T(X_.y()), T(X_.z())};
    T Xr[3], Xc[3];
    ceres::AngleAxisRotatePoint(view, Xb, Xr);
    for (int i = 0; i < 3; ++i) Xr[i] += view[3 + i];
    ceres::AngleAxisRotatePoint(cam, Xr, Xc);
    for (int i = 0; i < 3; ++i) Xc[i] += cam[3 + i];
    T uv[2];
    project(intr, fix_aspect_, Xc, uv);
    residual[0] = uv[0] - T(obs_.x());
    residual[1] = uv[1] - T(obs_.y());
    return true;
  }
  Eigen::Vector3d X_;
  Eigen::Vector2d obs_;
  bool fix_aspect_;
};

// ---- the steps of calibrate_rig ----

Status check_rig_input(const std::vector<CameraObservations>& cameras, const BoardSpec& board) {
  if (cameras.empty()) return invalid_argument("calibrate_rig: no cameras");
  if (board.corner_count() <= 0) return invalid_argument("calibrate_rig: empty board");
  std::set<std::string> names;
  for (const CameraObservations& c : cameras)
    if (c.name.empty() || !names.insert(c.name).second)
      return invalid_argument("calibrate_rig: camera name '" + c.name + "' empty or repeated");
  return {};
}

// 1. Single-camera calibrations (OpenCV) give the intrinsics and camera_from_board per view.
Status calibrate_each_camera(const std::vector<CameraObservations>& cameras, const BoardSpec& board,
                             const CalibrationOptions& options,
                             std::vector<OpenCvCalibration>& single,
                             std::vector<std::map<int, Pose>>& cam_from_board) {
  const std::size_t nc = cameras.size();
  ProgressTask task(options.progress, "intrinsics per camera", nc);
  for (std::size_t c = 0; c < nc; ++c) {
    HC_ASSIGN_OR_RETURN(single[c], run_opencv(cameras[c], board, options, kInitViews));
    for (std::size_t i = 0; i < single[c].views.size(); ++i)
      cam_from_board[c][single[c].views[i]] =
          pose_from_rvec(single[c].rvecs[i], single[c].tvecs[i]);
    task.advance();
  }
  return {};
}

// A chessboard with cols + rows even looks the same after a half turn, so cameras may number its
// corners in opposite orders (board.h, canonical_order); `flip` is that half turn in the board
// frame (corner id k <-> N-1-k).
struct BoardSymmetry {
  bool symmetric = false;
  Pose flip;
};

BoardSymmetry board_symmetry(const BoardSpec& board, std::size_t nc) {
  BoardSymmetry b;
  b.symmetric =
      board.kind == BoardKind::kChessboard && (board.cols + board.rows) % 2 == 0 && nc > 1;
  b.flip.R = Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal();
  b.flip.t =
      Eigen::Vector3d((board.cols - 1) * board.square_m, (board.rows - 1) * board.square_m, 0.0);
  return b;
}

// An edge of the visibility graph: cameras a and b saw the board in `shared` same views.
struct Edge {
  int a = -1, b = -1, shared = 0;
};

// The edge with most shared views from a placed camera to one not yet placed (b < 0: none).
Edge strongest_edge(const std::vector<std::map<int, Pose>>& cam_from_board,
                    const std::vector<bool>& placed) {
  Edge best;
  const std::size_t nc = cam_from_board.size();
  for (std::size_t a = 0; a < nc; ++a) {
    if (!placed[a]) continue;
    for (std::size_t b = 0; b < nc; ++b) {
      if (placed[b]) continue;
      int n = 0;
      for (const auto& [view, pose] : cam_from_board[b]) n += cam_from_board[a].count(view) ? 1 : 0;
      if (n > best.shared) {
        best.shared = n;
        best.a = static_cast<int>(a);
        best.b = static_cast<int>(b);
      }
    }
  }
  return best;
}

// A half-turn-symmetric board: each shared view gives two candidate relative poses (`rel` and
// `rel_flipped`); keep the candidate most views agree with (rotation within 5 degrees, translation
// within 10 %) and, per view, whichever of its two candidates is nearer to it.
std::vector<Pose> choose_board_orientations(const std::vector<Pose>& rel,
                                            const std::vector<Pose>& rel_flipped) {
  std::vector<Pose> all = rel;
  all.insert(all.end(), rel_flipped.begin(), rel_flipped.end());
  const auto close = [](const Pose& p, const Pose& q) {
    const double angle = Eigen::AngleAxisd(p.R * q.R.transpose()).angle();
    return angle < 5.0 * 3.14159265358979 / 180.0 &&
           (p.t - q.t).norm() < 0.1 * std::max(p.t.norm(), q.t.norm()) + 1e-9;
  };
  std::size_t best = 0;
  int best_votes = -1;
  for (std::size_t i = 0; i < all.size(); ++i) {
    int votes = 0;
    for (const Pose& q : all) votes += close(all[i], q) ? 1 : 0;
    if (votes > best_votes) {
      best_votes = votes;
      best = i;
    }
  }
  std::vector<Pose> chosen;
  for (std::size_t i = 0; i < rel.size(); ++i) {
    const double d0 = Eigen::AngleAxisd(rel[i].R * all[best].R.transpose()).angle();
    const double d1 = Eigen::AngleAxisd(rel_flipped[i].R * all[best].R.transpose()).angle();
    chosen.push_back(d0 <= d1 ? rel[i] : rel_flipped[i]);
  }
  return chosen;
}

// b_from_a in each view both cameras saw.
std::vector<Pose> relative_poses(const std::map<int, Pose>& a_from_board,
                                 const std::map<int, Pose>& b_from_board,
                                 const BoardSymmetry& board) {
  std::vector<Pose> rel;          // b_from_a
  std::vector<Pose> rel_flipped;  // the same with b's corners numbered the other way round
  for (const auto& [view, pose_b] : b_from_board) {
    const auto it = a_from_board.find(view);
    if (it == a_from_board.end()) continue;
    rel.push_back(pose_b * it->second.inverse());
    rel_flipped.push_back(pose_b * board.flip * it->second.inverse());
  }
  return board.symmetric ? choose_board_orientations(rel, rel_flipped) : rel;
}

// The cameras placed one at a time along the spanning tree, camera 0 first.
struct CameraTree {
  std::vector<Pose> cam_from_rig;
  std::vector<std::size_t> placement = {0};
  std::vector<int> parent, shared_with_parent;
};

// 2. Visibility graph: cameras are nodes, an edge joins two cameras that saw the same board pose
// (weight = shared views). A maximum spanning tree from camera 0 (Prim) chains relative poses,
// each averaged over the shared views.
Result<CameraTree> chain_cameras(const std::vector<CameraObservations>& cameras,
                                 const std::vector<std::map<int, Pose>>& cam_from_board,
                                 const BoardSymmetry& board) {
  const std::size_t nc = cameras.size();
  CameraTree tree;
  tree.cam_from_rig.resize(nc);
  tree.parent.assign(nc, -1);
  tree.shared_with_parent.assign(nc, 0);
  std::vector<bool> placed(nc, false);
  placed[0] = true;
  for (std::size_t step = 1; step < nc; ++step) {
    const Edge e = strongest_edge(cam_from_board, placed);
    if (e.b < 0) {
      std::string missing;
      for (std::size_t b = 0; b < nc; ++b)
        if (!placed[b]) missing += (missing.empty() ? "'" : ", '") + cameras[b].name + "'";
      return invalid_argument(
          fmt::format("camera(s) {} never see the board in the same view as camera '{}' or any "
                      "camera connected to it: no chain of shared views to calibrate them",
                      missing, cameras[0].name));
    }
    const auto a = static_cast<std::size_t>(e.a), b = static_cast<std::size_t>(e.b);
    const std::vector<Pose> rel = relative_poses(cam_from_board[a], cam_from_board[b], board);
    tree.cam_from_rig[b] = average(rel) * tree.cam_from_rig[a];
    tree.placement.push_back(b);
    placed[b] = true;
    tree.parent[b] = e.a;
    tree.shared_with_parent[b] = e.shared;
  }
  return tree;
}

// 3. Board poses in the rig frame (rig_from_board parameters per view): from the first camera (in
// placement order) that saw each view; on a symmetric board the later cameras' corner order is
// matched to it (their cam_from_board turned by the half turn). Returns the views each camera
// numbers the other way round.
std::vector<std::set<int>> board_poses_in_rig(const CameraTree& tree, const BoardSymmetry& board,
                                              std::vector<std::map<int, Pose>>& cam_from_board,
                                              std::map<int, std::array<double, 6>>& view_params) {
  std::vector<std::set<int>> flipped(cam_from_board.size());
  for (std::size_t c : tree.placement)
    for (auto& [view, pose] : cam_from_board[c]) {
      const Pose rig_from_board = tree.cam_from_rig[c].inverse() * pose;
      const auto it = view_params.find(view);
      if (it == view_params.end()) {
        std::array<double, 6> p;
        to_params(rig_from_board, p.data());
        view_params[view] = p;
      } else if (board.symmetric) {
        const Pose known = from_params(it->second.data());
        const Pose other = rig_from_board * board.flip;
        if (Eigen::AngleAxisd(other.R * known.R.transpose()).angle() <
            Eigen::AngleAxisd(rig_from_board.R * known.R.transpose()).angle()) {
          flipped[c].insert(view);
          pose = pose * board.flip;
        }
      }
    }
  return flipped;
}

ceres::Problem::Options joint_problem_options() {
  ceres::Problem::Options o;
  o.enable_fast_removal = false;
  return o;
}

// 4. The joint problem: per camera its intrinsics and camera_from_rig, per view rig_from_board,
// one residual per corner seen. Ceres holds pointers to the parameter blocks kept here.
struct JointProblem {
  struct Residual {
    std::size_t camera;
    int view;
    ceres::ResidualBlockId id;
  };
  std::vector<std::array<double, kIntrinsics>> intr;
  std::vector<std::array<double, 6>> cam_params;
  std::map<int, std::array<double, 6>> view_params;
  std::vector<int> fixed;  // intrinsics held constant, the same for every camera
  ceres::Problem problem{joint_problem_options()};
  std::vector<Residual> residuals;

  std::vector<const Residual*> all() const {
    std::vector<const Residual*> out;
    for (const Residual& r : residuals) out.push_back(&r);
    return out;
  }
  double sum_squares(const std::vector<const Residual*>& set) {
    double sum = 0.0;
    for (const Residual* r : set) {
      double res[2];
      const std::array<double, 6>& vp = view_params[r->view];
      const double* blocks[3] = {intr[r->camera].data(), cam_params[r->camera].data(), vp.data()};
      problem.GetCostFunctionForResidualBlock(r->id)->Evaluate(blocks, res, nullptr);
      sum += res[0] * res[0] + res[1] * res[1];
    }
    return sum;
  }
  double rms(const std::vector<const Residual*>& set) {
    const double sum = sum_squares(set);
    return set.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(set.size()));
  }
};

// The starting point: each camera's OpenCV intrinsics and its pose along the tree.
void init_joint_parameters(const std::vector<OpenCvCalibration>& single,
                           const std::vector<Pose>& cam_from_rig, JointProblem& joint) {
  const std::size_t nc = single.size();
  joint.intr.resize(nc);
  joint.cam_params.resize(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    const OpenCvCalibration& o = single[c];
    joint.intr[c] = {o.K.at<double>(0, 0), o.K.at<double>(1, 1), o.K.at<double>(0, 2),
                     o.K.at<double>(1, 2), o.dist.at<double>(0), o.dist.at<double>(1),
                     o.dist.at<double>(2), o.dist.at<double>(3), o.dist.at<double>(4)};
    to_params(cam_from_rig[c], joint.cam_params[c].data());
  }
}

void add_corner_residuals(const std::vector<CameraObservations>& cameras, const BoardSpec& board,
                          const CalibrationOptions& options,
                          const std::vector<std::map<int, Pose>>& cam_from_board,
                          const std::vector<std::set<int>>& flipped, JointProblem& joint) {
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    for (const ViewObservation& v : cameras[c].views) {
      if (!cam_from_board[c].count(v.view)) continue;  // dropped (too few corners)
      const bool flip_view = flipped[c].count(v.view) > 0;
      for (std::size_t i = 0; i < v.ids.size(); ++i) {
        const int id = flip_view ? board.corner_count() - 1 - v.ids[i] : v.ids[i];
        auto* cost = new ceres::AutoDiffCostFunction<ReprojectionCost, 2, kIntrinsics, 6, 6>(
            new ReprojectionCost(board.corner(id), v.pixels[i], options.fix_aspect_ratio));
        ceres::LossFunction* loss = nullptr;
        if (options.loss == RobustLoss::kHuber)
          loss = new ceres::HuberLoss(options.loss_scale_px);
        else if (options.loss == RobustLoss::kCauchy)
          loss = new ceres::CauchyLoss(options.loss_scale_px);
        joint.residuals.push_back({c, v.view,
                                   joint.problem.AddResidualBlock(
                                       cost, loss, joint.intr[c].data(), joint.cam_params[c].data(),
                                       joint.view_params[v.view].data())});
      }
    }
  }
}

// The intrinsics the options fix, and camera 0's pose (it defines the rig frame).
void hold_fixed_parameters(const CalibrationOptions& options, JointProblem& joint) {
  if (options.fix_aspect_ratio) joint.fixed.push_back(1);
  if (options.zero_tangential) {
    joint.fixed.push_back(6);
    joint.fixed.push_back(7);
  }
  if (options.fix_k3) joint.fixed.push_back(8);
  for (auto& intr : joint.intr) {
    if (options.fix_aspect_ratio) intr[1] = intr[0];
    if (!joint.fixed.empty())
      joint.problem.SetManifold(intr.data(), new ceres::SubsetManifold(kIntrinsics, joint.fixed));
  }
  joint.problem.SetParameterBlockConstant(joint.cam_params[0].data());
}

Status solve_joint(const CalibrationOptions& options, JointProblem& joint, CalibrationSummary& s) {
  const auto t_solve = std::chrono::steady_clock::now();
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_SCHUR;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = std::max(1, options.threads);
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  {
    ProgressTask task(options.progress, "joint bundle adjustment", 0);
    // SPARSE_SCHUR factorises through CHOLMOD, whose OpenMP team thrashes on 2 vCPUs
    // (common/openmp.h).
    SerialOpenMpScope serial_openmp;
    ceres::Solve(so, &joint.problem, &summary);
  }
  s.solve_time_s = seconds_since(t_solve);
  s.iterations = static_cast<int>(summary.iterations.size());
  s.converged = summary.termination_type == ceres::CONVERGENCE;
  s.termination = summary.message;
  if (!summary.IsSolutionUsable())
    return invalid_argument("joint bundle adjustment failed: " + summary.message);
  return {};
}

// 5. Reports: per camera, per (camera, view), and the solved rig.
void report_cameras(const std::vector<CameraObservations>& cameras,
                    const std::vector<OpenCvCalibration>& single, const CameraTree& tree,
                    const CalibrationOptions& options, JointProblem& joint, CalibrationSummary& s) {
  const std::size_t nc = cameras.size();
  s.joint_rms_px = joint.rms(joint.all());
  s.observations = static_cast<int>(joint.residuals.size());
  s.board_poses = static_cast<int>(joint.view_params.size());
  std::vector<double> view_rms;
  for (std::size_t c = 0; c < nc; ++c) {
    CameraReport r;
    r.name = cameras[c].name;
    r.initial_rms_px = single[c].rms;
    r.parent = tree.parent[c] >= 0 ? cameras[static_cast<std::size_t>(tree.parent[c])].name : "";
    r.shared_views_with_parent = tree.shared_with_parent[c];
    std::vector<const JointProblem::Residual*> cam_set;
    std::map<int, std::vector<const JointProblem::Residual*>> per_view;
    for (const JointProblem::Residual& res : joint.residuals)
      if (res.camera == c) {
        cam_set.push_back(&res);
        per_view[res.view].push_back(&res);
      }
    r.rms_px = joint.rms(cam_set);
    r.points = static_cast<int>(cam_set.size());
    r.views = static_cast<int>(per_view.size());
    for (const auto& [view, set] : per_view) {
      ViewReport v{cameras[c].name, view, static_cast<int>(set.size()), joint.rms(set), false};
      view_rms.push_back(v.rms_px);
      s.views.push_back(v);
    }
    CameraModel m = model_from(cameras[c].name, cameras[c].width, cameras[c].height,
                               joint.intr[c].data(), options.fix_aspect_ratio);
    const Pose p = from_params(joint.cam_params[c].data());
    m.R = p.R;
    m.t_m = p.t;
    m.rms_px = r.rms_px;
    s.rig.cameras.push_back(std::move(m));
    s.cameras.push_back(std::move(r));
  }
  const double med = median(view_rms);
  for (ViewReport& v : s.views) v.outlier = v.rms_px > options.outlier_factor * med;
  s.rig.joint_rms_px = nc > 1 ? s.joint_rms_px : 0.0;
}

// One camera's standard deviations from its covariance blocks (pose and centre: not for camera 0,
// which is held constant).
void camera_std_devs(ceres::Covariance& covariance, std::size_t c, double sigma2,
                     const CalibrationOptions& options, JointProblem& joint, CameraReport& r) {
  Eigen::Matrix<double, kIntrinsics, kIntrinsics, Eigen::RowMajor> ci;
  covariance.GetCovarianceBlock(joint.intr[c].data(), joint.intr[c].data(), ci.data());
  r.intrinsics_std.resize(kIntrinsics);
  for (int i = 0; i < kIntrinsics; ++i)
    r.intrinsics_std[static_cast<std::size_t>(i)] = std::sqrt(std::max(0.0, ci(i, i) * sigma2));
  if (options.fix_aspect_ratio) r.intrinsics_std[1] = r.intrinsics_std[0];
  r.pose_std.assign(6, 0.0);
  r.center_std_m.assign(3, 0.0);
  if (c == 0) return;
  Eigen::Matrix<double, 6, 6, Eigen::RowMajor> cp;
  covariance.GetCovarianceBlock(joint.cam_params[c].data(), joint.cam_params[c].data(), cp.data());
  for (int i = 0; i < 6; ++i)
    r.pose_std[static_cast<std::size_t>(i)] = std::sqrt(std::max(0.0, cp(i, i) * sigma2));
  // Centre = -R(w)^T t: first-order propagation with a numerical Jacobian.
  Eigen::Matrix<double, 3, 6> J;
  const auto centre = [](const std::array<double, 6>& q) {
    const Pose p = from_params(q.data());
    return Eigen::Vector3d(-p.R.transpose() * p.t);
  };
  const Eigen::Vector3d c0 = centre(joint.cam_params[c]);
  for (int k = 0; k < 6; ++k) {
    std::array<double, 6> q = joint.cam_params[c];
    const double h = 1e-7;
    q[static_cast<std::size_t>(k)] += h;
    J.col(k) = (centre(q) - c0) / h;
  }
  const Eigen::Matrix3d cc = J * cp * J.transpose() * sigma2;
  r.center_std_m = {std::sqrt(std::max(0.0, cc(0, 0))), std::sqrt(std::max(0.0, cc(1, 1))),
                    std::sqrt(std::max(0.0, cc(2, 2)))};
}

// 6. Standard deviations from the Ceres covariance, scaled by the residual variance
// sigma^2 = sum r^2 / (residuals - free parameters) as OpenCV's calibrateCameraExtended does.
void add_std_devs(const CalibrationOptions& options, JointProblem& joint, CalibrationSummary& s) {
  const std::size_t nc = joint.intr.size();
  const auto t_cov = std::chrono::steady_clock::now();
  ProgressTask task(options.progress, "parameter covariance", 0);
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::SPARSE_QR;  // (DENSE_SVD measured 4x slower at 600 parameters)
  co.num_threads = std::max(1, options.threads);
  ceres::Covariance covariance(co);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (std::size_t c = 0; c < nc; ++c) {
    blocks.emplace_back(joint.intr[c].data(), joint.intr[c].data());
    if (c > 0) blocks.emplace_back(joint.cam_params[c].data(), joint.cam_params[c].data());
  }
  bool computed = false;
  {
    SerialOpenMpScope serial_openmp;  // SPARSE_QR goes through SuiteSparseQR / CHOLMOD too
    computed = covariance.Compute(blocks, &joint.problem);
  }
  if (computed) {
    const int free_params =
        joint.problem.NumParameters() - 6 - static_cast<int>(nc * joint.fixed.size());
    const int dof = 2 * s.observations - free_params;
    const double sq = joint.sum_squares(joint.all());
    const double sigma2 = dof > 0 ? sq / dof : 0.0;
    for (std::size_t c = 0; c < nc; ++c)
      camera_std_devs(covariance, c, sigma2, options, joint, s.cameras[c]);
  } else {
    s.covariance_note = "covariance not computed (rank-deficient Jacobian)";
  }
  s.covariance_time_s = seconds_since(t_cov);
}

}  // namespace

Result<CalibrationSummary> calibrate_rig(const std::vector<CameraObservations>& cameras,
                                         const BoardSpec& board,
                                         const CalibrationOptions& options) {
  HC_RETURN_IF_ERROR(check_rig_input(cameras, board));
  const auto t_init = std::chrono::steady_clock::now();
  const std::size_t nc = cameras.size();
  CalibrationSummary s;

  std::vector<OpenCvCalibration> single(nc);
  std::vector<std::map<int, Pose>> cam_from_board(nc);
  HC_RETURN_IF_ERROR(calibrate_each_camera(cameras, board, options, single, cam_from_board));
  const BoardSymmetry symmetry = board_symmetry(board, nc);
  HC_ASSIGN_OR_RETURN(const CameraTree tree, chain_cameras(cameras, cam_from_board, symmetry));
  JointProblem joint;
  const std::vector<std::set<int>> flipped =
      board_poses_in_rig(tree, symmetry, cam_from_board, joint.view_params);

  init_joint_parameters(single, tree.cam_from_rig, joint);
  add_corner_residuals(cameras, board, options, cam_from_board, flipped, joint);
  hold_fixed_parameters(options, joint);
  s.initial_joint_rms_px = joint.rms(joint.all());
  s.init_time_s = seconds_since(t_init);
  HC_RETURN_IF_ERROR(solve_joint(options, joint, s));

  report_cameras(cameras, single, tree, options, joint, s);
  if (options.compute_std_devs) add_std_devs(options, joint, s);
  return s;
}

}  // namespace hc::calib
