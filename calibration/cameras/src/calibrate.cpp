#include "calibration/cameras/calibrate.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <fmt/format.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <array>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "common/openmp.h"

namespace hc::calib {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

constexpr int kIntrinsics = 9;  // fx fy cx cy k1 k2 p1 p2 k3
// Views per camera for the single-camera OpenCV calibration that initialises calibrate_rig.
constexpr int kInitViews = 10;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

int opencv_flags(const CalibrationOptions& o) {
  int flags = 0;
  if (o.fix_aspect_ratio) flags |= cv::CALIB_FIX_ASPECT_RATIO;
  if (o.fix_k3) flags |= cv::CALIB_FIX_K3;
  if (o.zero_tangential) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  return flags;
}

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

struct OpenCvCalibration {
  cv::Mat K, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_intrinsics, per_view_errors;
  double rms = 0.0;
  std::vector<int> views;  // view number of each rvec
  std::vector<int> points;
};

// max_views > 0: calibrateCamera on at most that many views spread through the list, then every
// view's pose by solvePnP with those intrinsics (an initial guess for the bundle adjustment:
// calibrateCamera's dense Levenberg-Marquardt over 9 + 6 N parameters took 17 s for 7 cameras x
// ~45 views, 20 views plus solvePnP 3.2 s; 10 views halved bench_calibration's initialisation
// again). The joint solve refines everything: the synthetic rig tests reach the same optimum
// (identical errors and iteration counts) from either start.
Result<OpenCvCalibration> run_opencv(const CameraObservations& cam, const BoardSpec& board,
                                     const CalibrationOptions& options, int max_views = 0) {
  if (cam.width <= 0 || cam.height <= 0)
    return invalid_argument(fmt::format("camera '{}': image size unknown", cam.name));
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
  OpenCvCalibration out;
  std::set<int> seen;
  for (const ViewObservation& v : cam.views) {
    if (v.ids.size() != v.pixels.size())
      return invalid_argument(
          fmt::format("camera '{}' view {}: ids and pixels differ in length", cam.name, v.view));
    if (!seen.insert(v.view).second)
      return invalid_argument(fmt::format("camera '{}': view {} given twice", cam.name, v.view));
    if (static_cast<int>(v.ids.size()) < options.min_points_per_view) continue;
    std::vector<cv::Point3f> o;
    std::vector<cv::Point2f> p;
    for (std::size_t i = 0; i < v.ids.size(); ++i) {
      if (v.ids[i] < 0 || v.ids[i] >= board.corner_count())
        return invalid_argument(fmt::format("camera '{}' view {}: corner id {} is not on the board",
                                            cam.name, v.view, v.ids[i]));
      if (!v.pixels[i].allFinite())
        return invalid_argument(
            fmt::format("camera '{}' view {}: corner pixel is not finite", cam.name, v.view));
      const Eigen::Vector3d X = board.corner(v.ids[i]);
      o.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()), 0.0f);
      p.emplace_back(static_cast<float>(v.pixels[i].x()), static_cast<float>(v.pixels[i].y()));
    }
    object.push_back(std::move(o));
    image.push_back(std::move(p));
    out.views.push_back(v.view);
    out.points.push_back(static_cast<int>(v.ids.size()));
  }
  if (static_cast<int>(object.size()) < options.min_views_per_camera)
    return invalid_argument(fmt::format(
        "camera '{}': the board was found in {} view(s) with at least {} corners; need {}",
        cam.name, object.size(), options.min_points_per_view, options.min_views_per_camera));
  const bool subset = max_views > 0 && static_cast<int>(object.size()) > max_views;
  std::vector<std::vector<cv::Point3f>> object_subset;
  std::vector<std::vector<cv::Point2f>> image_subset;
  if (subset)
    for (int k = 0; k < max_views; ++k) {
      const std::size_t i =
          static_cast<std::size_t>(k) * object.size() / static_cast<std::size_t>(max_views);
      object_subset.push_back(object[i]);
      image_subset.push_back(image[i]);
    }
  try {
    out.K = cv::Mat::eye(3, 3, CV_64F);
    out.dist = cv::Mat::zeros(1, 5, CV_64F);
    cv::Mat std_ext;
    out.rms = cv::calibrateCamera(  // the overload with std devs and per-view errors
        subset ? object_subset : object, subset ? image_subset : image,
        cv::Size(cam.width, cam.height), out.K, out.dist, out.rvecs, out.tvecs, out.std_intrinsics,
        std_ext, out.per_view_errors, opencv_flags(options),
        // OpenCV's default criteria (as its samples that produced the reference results).
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, DBL_EPSILON));
    if (subset) {
      out.rvecs.assign(object.size(), cv::Mat());
      out.tvecs.assign(object.size(), cv::Mat());
      for (std::size_t i = 0; i < object.size(); ++i)
        cv::solvePnP(object[i], image[i], out.K, out.dist, out.rvecs[i], out.tvecs[i]);
      out.per_view_errors = cv::Mat();  // not computed for the views outside the subset
    }
  } catch (const cv::Exception& e) {
    return invalid_argument(
        fmt::format("camera '{}': OpenCV calibrateCamera failed: {}", cam.name, e.what()));
  }
  if (!std::isfinite(out.rms) || !cv::checkRange(out.K) || !cv::checkRange(out.dist))
    return invalid_argument(fmt::format("camera '{}': OpenCV calibrateCamera diverged", cam.name));
  return out;
}

CameraModel model_from(const std::string& name, int w, int h, const double* intr, bool fix_aspect) {
  CameraModel m;
  m.name = name;
  m.width = w;
  m.height = h;
  m.fx = intr[0];
  m.fy = fix_aspect ? intr[0] : intr[1];
  m.cx = intr[2];
  m.cy = intr[3];
  m.distortion = {intr[4], intr[5], intr[6], intr[7], intr[8]};
  return m;
}

}  // namespace

std::vector<ViewReport> CalibrationSummary::outliers() const {
  std::vector<ViewReport> out;
  for (const ViewReport& v : views)
    if (v.outlier) out.push_back(v);
  return out;
}

Result<CalibrationSummary> calibrate_camera_opencv(const CameraObservations& camera,
                                                   const BoardSpec& board,
                                                   const CalibrationOptions& options) {
  const auto t0 = Clock::now();
  HC_ASSIGN_OR_RETURN(OpenCvCalibration cv_cal, run_opencv(camera, board, options));
  CalibrationSummary s;
  double intr[kIntrinsics];
  intr[0] = cv_cal.K.at<double>(0, 0);
  intr[1] = cv_cal.K.at<double>(1, 1);
  intr[2] = cv_cal.K.at<double>(0, 2);
  intr[3] = cv_cal.K.at<double>(1, 2);
  for (int i = 0; i < 5; ++i) intr[4 + i] = cv_cal.dist.at<double>(i);
  CameraModel m = model_from(camera.name, camera.width, camera.height, intr, false);
  m.rms_px = cv_cal.rms;
  s.rig.cameras.push_back(m);
  CameraReport r;
  r.name = camera.name;
  r.views = static_cast<int>(cv_cal.views.size());
  r.rms_px = r.initial_rms_px = cv_cal.rms;
  for (int i = 0; i < kIntrinsics && i < cv_cal.std_intrinsics.rows; ++i)
    r.intrinsics_std.push_back(cv_cal.std_intrinsics.at<double>(i));
  // With a fixed aspect ratio OpenCV reports the deviation on one of fx / fy only.
  if (options.fix_aspect_ratio && r.intrinsics_std.size() >= 2)
    r.intrinsics_std[0] = r.intrinsics_std[1] = std::max(r.intrinsics_std[0], r.intrinsics_std[1]);
  std::vector<double> rms;
  for (std::size_t i = 0; i < cv_cal.views.size(); ++i) {
    ViewReport v{camera.name, cv_cal.views[i], cv_cal.points[i],
                 cv_cal.per_view_errors.at<double>(static_cast<int>(i)), false};
    r.points += v.points;
    rms.push_back(v.rms_px);
    s.views.push_back(v);
  }
  const double med = median(rms);
  for (ViewReport& v : s.views) v.outlier = v.rms_px > options.outlier_factor * med;
  s.cameras.push_back(r);
  s.joint_rms_px = s.initial_joint_rms_px = cv_cal.rms;
  s.observations = r.points;
  s.board_poses = r.views;
  s.init_time_s = seconds_since(t0);
  return s;
}

Result<CalibrationSummary> stereo_calibrate_opencv(const CameraObservations& a,
                                                   const CameraObservations& b,
                                                   const BoardSpec& board,
                                                   const CalibrationOptions& options) {
  const auto t0 = Clock::now();
  HC_ASSIGN_OR_RETURN(OpenCvCalibration ca, run_opencv(a, board, options));
  HC_ASSIGN_OR_RETURN(OpenCvCalibration cb, run_opencv(b, board, options));
  std::map<int, const ViewObservation*> vb;
  for (const ViewObservation& v : b.views) vb[v.view] = &v;
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> pa, pb;
  for (const ViewObservation& v : a.views) {
    const auto it = vb.find(v.view);
    if (it == vb.end()) continue;
    std::map<int, Eigen::Vector2d> in_b;
    for (std::size_t i = 0; i < it->second->ids.size(); ++i)
      in_b[it->second->ids[i]] = it->second->pixels[i];
    std::vector<cv::Point3f> o;
    std::vector<cv::Point2f> qa, qb;
    for (std::size_t i = 0; i < v.ids.size(); ++i) {
      const auto jt = in_b.find(v.ids[i]);
      if (jt == in_b.end()) continue;
      const Eigen::Vector3d X = board.corner(v.ids[i]);
      o.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()), 0.0f);
      qa.emplace_back(static_cast<float>(v.pixels[i].x()), static_cast<float>(v.pixels[i].y()));
      qb.emplace_back(static_cast<float>(jt->second.x()), static_cast<float>(jt->second.y()));
    }
    if (static_cast<int>(o.size()) < options.min_points_per_view) continue;
    object.push_back(std::move(o));
    pa.push_back(std::move(qa));
    pb.push_back(std::move(qb));
  }
  if (object.empty())
    return invalid_argument(fmt::format("cameras '{}' and '{}' share no view", a.name, b.name));
  cv::Mat R, T, E, F;
  double rms = 0.0;
  try {
    rms = cv::stereoCalibrate(
        object, pa, pb, ca.K, ca.dist, cb.K, cb.dist, cv::Size(a.width, a.height), R, T, E, F,
        cv::CALIB_USE_INTRINSIC_GUESS | opencv_flags(options),
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-6));
  } catch (const cv::Exception& e) {
    return invalid_argument(std::string("OpenCV stereoCalibrate failed: ") + e.what());
  }
  CalibrationSummary s;
  for (int k = 0; k < 2; ++k) {
    const OpenCvCalibration& c = k == 0 ? ca : cb;
    const CameraObservations& o = k == 0 ? a : b;
    double intr[kIntrinsics];
    intr[0] = c.K.at<double>(0, 0);
    intr[1] = c.K.at<double>(1, 1);
    intr[2] = c.K.at<double>(0, 2);
    intr[3] = c.K.at<double>(1, 2);
    for (int i = 0; i < 5; ++i) intr[4 + i] = c.dist.at<double>(i);
    s.rig.cameras.push_back(model_from(o.name, o.width, o.height, intr, false));
  }
  cv::Mat Rd, Td;
  R.convertTo(Rd, CV_64F);
  T.convertTo(Td, CV_64F);
  cv::cv2eigen(Rd, s.rig.cameras[1].R);
  for (int i = 0; i < 3; ++i) s.rig.cameras[1].t_m(i) = Td.at<double>(i);
  s.joint_rms_px = s.rig.joint_rms_px = rms;
  s.board_poses = static_cast<int>(object.size());
  s.solve_time_s = seconds_since(t0);
  return s;
}

Result<CalibrationSummary> calibrate_rig(const std::vector<CameraObservations>& cameras,
                                         const BoardSpec& board,
                                         const CalibrationOptions& options) {
  if (cameras.empty()) return invalid_argument("calibrate_rig: no cameras");
  if (board.corner_count() <= 0) return invalid_argument("calibrate_rig: empty board");
  {
    std::set<std::string> names;
    for (const CameraObservations& c : cameras)
      if (c.name.empty() || !names.insert(c.name).second)
        return invalid_argument("calibrate_rig: camera name '" + c.name + "' empty or repeated");
  }
  const auto t_init = Clock::now();
  const std::size_t nc = cameras.size();
  CalibrationSummary s;

  // 1. Single-camera calibrations (OpenCV) give the intrinsics and camera_from_board per view.
  std::vector<OpenCvCalibration> single(nc);
  std::vector<std::map<int, Pose>> cam_from_board(nc);
  {
    ProgressTask task(options.progress, "intrinsics per camera", nc);
    for (std::size_t c = 0; c < nc; ++c) {
      HC_ASSIGN_OR_RETURN(single[c], run_opencv(cameras[c], board, options, kInitViews));
      for (std::size_t i = 0; i < single[c].views.size(); ++i)
        cam_from_board[c][single[c].views[i]] =
            pose_from_rvec(single[c].rvecs[i], single[c].tvecs[i]);
      task.advance();
    }
  }

  // 2. Visibility graph: cameras are nodes, an edge joins two cameras that saw the same board pose
  // (weight = shared views). A maximum spanning tree from camera 0 (Prim) chains relative poses,
  // each averaged over the shared views.
  std::vector<Pose> cam_from_rig(nc);
  // A chessboard with cols + rows even looks the same after a half turn, so cameras may number
  // its corners in opposite orders (board.h, canonical_order); `flip` is that half turn in the
  // board frame (corner id k <-> N-1-k).
  const bool symmetric =
      board.kind == BoardKind::kChessboard && (board.cols + board.rows) % 2 == 0 && nc > 1;
  Pose flip;
  flip.R = Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal();
  flip.t =
      Eigen::Vector3d((board.cols - 1) * board.square_m, (board.rows - 1) * board.square_m, 0.0);
  std::vector<std::size_t> placement = {0};
  std::vector<std::set<int>> flipped(nc);
  std::vector<bool> placed(nc, false);
  std::vector<int> parent(nc, -1), shared_with_parent(nc, 0);
  placed[0] = true;
  for (std::size_t step = 1; step < nc; ++step) {
    int best_a = -1, best_b = -1, best_n = 0;
    for (std::size_t a = 0; a < nc; ++a) {
      if (!placed[a]) continue;
      for (std::size_t b = 0; b < nc; ++b) {
        if (placed[b]) continue;
        int n = 0;
        for (const auto& [view, pose] : cam_from_board[b])
          n += cam_from_board[a].count(view) ? 1 : 0;
        if (n > best_n) {
          best_n = n;
          best_a = static_cast<int>(a);
          best_b = static_cast<int>(b);
        }
      }
    }
    if (best_b < 0) {
      std::string missing;
      for (std::size_t b = 0; b < nc; ++b)
        if (!placed[b]) missing += (missing.empty() ? "'" : ", '") + cameras[b].name + "'";
      return invalid_argument(
          fmt::format("camera(s) {} never see the board in the same view as camera '{}' or any "
                      "camera connected to it: no chain of shared views to calibrate them",
                      missing, cameras[0].name));
    }
    const auto a = static_cast<std::size_t>(best_a), b = static_cast<std::size_t>(best_b);
    std::vector<Pose> rel;          // b_from_a
    std::vector<Pose> rel_flipped;  // the same with b's corners numbered the other way round
    for (const auto& [view, pose_b] : cam_from_board[b]) {
      const auto it = cam_from_board[a].find(view);
      if (it == cam_from_board[a].end()) continue;
      rel.push_back(pose_b * it->second.inverse());
      rel_flipped.push_back(pose_b * flip * it->second.inverse());
    }
    if (symmetric) {
      // A half-turn-symmetric board: each shared view gives two candidate relative poses; keep
      // the candidate most views agree with (rotation within 5 degrees, translation within 10 %)
      // and, per view, whichever of its two candidates is nearer to it.
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
      rel = chosen;
    }
    cam_from_rig[b] = average(rel) * cam_from_rig[a];
    placement.push_back(b);
    placed[b] = true;
    parent[b] = best_a;
    shared_with_parent[b] = best_n;
  }

  // 3. Board poses in the rig frame: from the first camera (in placement order) that saw each
  // view; on a symmetric board the later cameras' corner order is matched to it.
  std::map<int, std::array<double, 6>> view_params;
  for (std::size_t c : placement)
    for (auto& [view, pose] : cam_from_board[c]) {
      const Pose rig_from_board = cam_from_rig[c].inverse() * pose;
      const auto it = view_params.find(view);
      if (it == view_params.end()) {
        std::array<double, 6> p;
        to_params(rig_from_board, p.data());
        view_params[view] = p;
      } else if (symmetric) {
        const Pose known = from_params(it->second.data());
        const Pose other = rig_from_board * flip;
        if (Eigen::AngleAxisd(other.R * known.R.transpose()).angle() <
            Eigen::AngleAxisd(rig_from_board.R * known.R.transpose()).angle()) {
          flipped[c].insert(view);
          pose = pose * flip;
        }
      }
    }

  // 4. The joint problem.
  std::vector<std::array<double, kIntrinsics>> intr(nc);
  std::vector<std::array<double, 6>> cam_params(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    const OpenCvCalibration& o = single[c];
    intr[c] = {o.K.at<double>(0, 0), o.K.at<double>(1, 1), o.K.at<double>(0, 2),
               o.K.at<double>(1, 2), o.dist.at<double>(0), o.dist.at<double>(1),
               o.dist.at<double>(2), o.dist.at<double>(3), o.dist.at<double>(4)};
    to_params(cam_from_rig[c], cam_params[c].data());
  }
  ceres::Problem::Options problem_options;
  problem_options.enable_fast_removal = false;
  ceres::Problem problem(problem_options);
  struct Residual {
    std::size_t camera;
    int view;
    ceres::ResidualBlockId id;
  };
  std::vector<Residual> residuals;
  for (std::size_t c = 0; c < nc; ++c) {
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
        residuals.push_back(
            {c, v.view,
             problem.AddResidualBlock(cost, loss, intr[c].data(), cam_params[c].data(),
                                      view_params[v.view].data())});
      }
    }
  }
  std::vector<int> fixed;
  if (options.fix_aspect_ratio) fixed.push_back(1);
  if (options.zero_tangential) {
    fixed.push_back(6);
    fixed.push_back(7);
  }
  if (options.fix_k3) fixed.push_back(8);
  for (std::size_t c = 0; c < nc; ++c) {
    if (options.fix_aspect_ratio) intr[c][1] = intr[c][0];
    if (!fixed.empty())
      problem.SetManifold(intr[c].data(), new ceres::SubsetManifold(kIntrinsics, fixed));
  }
  problem.SetParameterBlockConstant(cam_params[0].data());

  const auto rms_of = [&](const std::vector<const Residual*>& set) {
    double sum = 0.0;
    for (const Residual* r : set) {
      double res[2];
      const std::array<double, 6>& vp = view_params[r->view];
      const double* blocks[3] = {intr[r->camera].data(), cam_params[r->camera].data(), vp.data()};
      problem.GetCostFunctionForResidualBlock(r->id)->Evaluate(blocks, res, nullptr);
      sum += res[0] * res[0] + res[1] * res[1];
    }
    return set.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(set.size()));
  };
  std::vector<const Residual*> all;
  for (const Residual& r : residuals) all.push_back(&r);
  s.initial_joint_rms_px = rms_of(all);
  s.init_time_s = seconds_since(t_init);

  const auto t_solve = Clock::now();
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
    ceres::Solve(so, &problem, &summary);
  }
  s.solve_time_s = seconds_since(t_solve);
  s.iterations = static_cast<int>(summary.iterations.size());
  s.converged = summary.termination_type == ceres::CONVERGENCE;
  s.termination = summary.message;
  if (!summary.IsSolutionUsable())
    return invalid_argument("joint bundle adjustment failed: " + summary.message);

  // 5. Reports.
  s.joint_rms_px = rms_of(all);
  s.observations = static_cast<int>(residuals.size());
  s.board_poses = static_cast<int>(view_params.size());
  std::vector<double> view_rms;
  for (std::size_t c = 0; c < nc; ++c) {
    CameraReport r;
    r.name = cameras[c].name;
    r.initial_rms_px = single[c].rms;
    r.parent = parent[c] >= 0 ? cameras[static_cast<std::size_t>(parent[c])].name : "";
    r.shared_views_with_parent = shared_with_parent[c];
    std::vector<const Residual*> cam_set;
    std::map<int, std::vector<const Residual*>> per_view;
    for (const Residual& res : residuals)
      if (res.camera == c) {
        cam_set.push_back(&res);
        per_view[res.view].push_back(&res);
      }
    r.rms_px = rms_of(cam_set);
    r.points = static_cast<int>(cam_set.size());
    r.views = static_cast<int>(per_view.size());
    for (const auto& [view, set] : per_view) {
      ViewReport v{cameras[c].name, view, static_cast<int>(set.size()), rms_of(set), false};
      view_rms.push_back(v.rms_px);
      s.views.push_back(v);
    }
    CameraModel m = model_from(cameras[c].name, cameras[c].width, cameras[c].height, intr[c].data(),
                               options.fix_aspect_ratio);
    const Pose p = from_params(cam_params[c].data());
    m.R = p.R;
    m.t_m = p.t;
    m.rms_px = r.rms_px;
    s.rig.cameras.push_back(std::move(m));
    s.cameras.push_back(std::move(r));
  }
  const double med = median(view_rms);
  for (ViewReport& v : s.views) v.outlier = v.rms_px > options.outlier_factor * med;
  s.rig.joint_rms_px = nc > 1 ? s.joint_rms_px : 0.0;

  // 6. Standard deviations from the Ceres covariance, scaled by the residual variance
  // sigma^2 = sum r^2 / (residuals - free parameters) as OpenCV's calibrateCameraExtended does.
  if (options.compute_std_devs) {
    const auto t_cov = Clock::now();
    ProgressTask task(options.progress, "parameter covariance", 0);
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::SPARSE_QR;  // (DENSE_SVD measured 4x slower at 600 parameters)
    co.num_threads = std::max(1, options.threads);
    ceres::Covariance covariance(co);
    std::vector<std::pair<const double*, const double*>> blocks;
    for (std::size_t c = 0; c < nc; ++c) {
      blocks.emplace_back(intr[c].data(), intr[c].data());
      if (c > 0) blocks.emplace_back(cam_params[c].data(), cam_params[c].data());
    }
    bool computed = false;
    {
      SerialOpenMpScope serial_openmp;  // SPARSE_QR goes through SuiteSparseQR / CHOLMOD too
      computed = covariance.Compute(blocks, &problem);
    }
    if (computed) {
      const int free_params = problem.NumParameters() - 6 - static_cast<int>(nc * fixed.size());
      const int dof = 2 * s.observations - free_params;
      double sq = 0.0;
      for (const Residual* r : all) {
        double res[2];
        const double* b[3] = {intr[r->camera].data(), cam_params[r->camera].data(),
                              view_params[r->view].data()};
        problem.GetCostFunctionForResidualBlock(r->id)->Evaluate(b, res, nullptr);
        sq += res[0] * res[0] + res[1] * res[1];
      }
      const double sigma2 = dof > 0 ? sq / dof : 0.0;
      for (std::size_t c = 0; c < nc; ++c) {
        Eigen::Matrix<double, kIntrinsics, kIntrinsics, Eigen::RowMajor> ci;
        covariance.GetCovarianceBlock(intr[c].data(), intr[c].data(), ci.data());
        s.cameras[c].intrinsics_std.resize(kIntrinsics);
        for (int i = 0; i < kIntrinsics; ++i)
          s.cameras[c].intrinsics_std[static_cast<std::size_t>(i)] =
              std::sqrt(std::max(0.0, ci(i, i) * sigma2));
        if (options.fix_aspect_ratio)
          s.cameras[c].intrinsics_std[1] = s.cameras[c].intrinsics_std[0];
        s.cameras[c].pose_std.assign(6, 0.0);
        s.cameras[c].center_std_m.assign(3, 0.0);
        if (c > 0) {
          Eigen::Matrix<double, 6, 6, Eigen::RowMajor> cp;
          covariance.GetCovarianceBlock(cam_params[c].data(), cam_params[c].data(), cp.data());
          for (int i = 0; i < 6; ++i)
            s.cameras[c].pose_std[static_cast<std::size_t>(i)] =
                std::sqrt(std::max(0.0, cp(i, i) * sigma2));
          // Centre = -R(w)^T t: first-order propagation with a numerical Jacobian.
          Eigen::Matrix<double, 3, 6> J;
          const auto centre = [](const std::array<double, 6>& q) {
            const Pose p = from_params(q.data());
            return Eigen::Vector3d(-p.R.transpose() * p.t);
          };
          const Eigen::Vector3d c0 = centre(cam_params[c]);
          for (int k = 0; k < 6; ++k) {
            std::array<double, 6> q = cam_params[c];
            const double h = 1e-7;
            q[static_cast<std::size_t>(k)] += h;
            J.col(k) = (centre(q) - c0) / h;
          }
          const Eigen::Matrix3d cc = J * cp * J.transpose() * sigma2;
          s.cameras[c].center_std_m = {std::sqrt(std::max(0.0, cc(0, 0))),
                                       std::sqrt(std::max(0.0, cc(1, 1))),
                                       std::sqrt(std::max(0.0, cc(2, 2)))};
        }
      }
    } else {
      s.covariance_note = "covariance not computed (rank-deficient Jacobian)";
    }
    s.covariance_time_s = seconds_since(t_cov);
  }
  return s;
}

}  // namespace hc::calib
