// calibrate_camera_opencv / stereo_calibrate_opencv (see calibrate.h), and the single-camera OpenCV
// calibration (opencv_calibration.h) that calibrate_rig (calibrate_rig.cpp) starts from.
#include "calibration/cameras/calibrate.h"

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

#include "opencv_calibration.h"

namespace hc::calib {

namespace {

int opencv_flags(const CalibrationOptions& o) {
  int flags = 0;
  if (o.fix_aspect_ratio) flags |= cv::CALIB_FIX_ASPECT_RATIO;
  if (o.fix_k3) flags |= cv::CALIB_FIX_K3;
  if (o.zero_tangential) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  return flags;
}

}  // namespace

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

Result<OpenCvCalibration> run_opencv(const CameraObservations& cam, const BoardSpec& board,
                                     const CalibrationOptions& options, int max_views) {
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

std::vector<ViewReport> CalibrationSummary::outliers() const {
  std::vector<ViewReport> out;
  for (const ViewReport& v : views)
    if (v.outlier) out.push_back(v);
  return out;
}

Result<CalibrationSummary> calibrate_camera_opencv(const CameraObservations& camera,
                                                   const BoardSpec& board,
                                                   const CalibrationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
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
  const auto t0 = std::chrono::steady_clock::now();
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

}  // namespace hc::calib
