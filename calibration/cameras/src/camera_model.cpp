#include "calibration/cameras/camera_model.h"

#include <fmt/format.h>

#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <cmath>
#include <set>

#include "common/file_io.h"

namespace hc::calib {

Eigen::Matrix3d CameraModel::K() const {
  Eigen::Matrix3d k = Eigen::Matrix3d::Identity();
  k(0, 0) = fx;
  k(1, 1) = fy;
  k(0, 2) = cx;
  k(1, 2) = cy;
  return k;
}

Eigen::Matrix<double, 3, 4> CameraModel::projection() const {
  Eigen::Matrix<double, 3, 4> rt;
  rt.leftCols<3>() = R;
  rt.col(3) = t_m;
  return K() * rt;
}

Eigen::Vector2d CameraModel::distort_normalized(const Eigen::Vector2d& xn) const {
  const double x = xn.x(), y = xn.y();
  double k[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  for (std::size_t i = 0; i < distortion.size() && i < 8; ++i) k[i] = distortion[i];
  const double r2 = x * x + y * y;
  const double num = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
  const double den = 1.0 + r2 * (k[5] + r2 * (k[6] + r2 * k[7]));
  const double radial = num / den;
  const double xd = x * radial + 2.0 * k[2] * x * y + k[3] * (r2 + 2.0 * x * x);
  const double yd = y * radial + k[2] * (r2 + 2.0 * y * y) + 2.0 * k[3] * x * y;
  return {fx * xd + cx, fy * yd + cy};
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& x_rig_m) const {
  const Eigen::Vector3d pc = R * x_rig_m + t_m;
  if (!(pc.z() > 0.0)) return std::nullopt;
  return distort_normalized(Eigen::Vector2d(pc.x() / pc.z(), pc.y() / pc.z()));
}

Eigen::Vector2d CameraModel::undistort_to_normalized(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d xd((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  if (distortion.empty()) return xd;
  // Newton on distort(x) = pixel with a numerical 2x2 Jacobian; starts from the distorted point
  // (OpenCV's cv::undistortPoints uses plain fixed-point iteration, which diverges for strong
  // barrel distortion near the corners).
  Eigen::Vector2d x = xd;
  const Eigen::Vector2d target = pixel;
  for (int it = 0; it < 20; ++it) {
    const Eigen::Vector2d f = distort_normalized(x) - target;
    if (f.norm() < 1e-10) break;
    constexpr double h = 1e-7;
    Eigen::Matrix2d J;
    J.col(0) = (distort_normalized(x + Eigen::Vector2d(h, 0.0)) - distort_normalized(x)) / h;
    J.col(1) = (distort_normalized(x + Eigen::Vector2d(0.0, h)) - distort_normalized(x)) / h;
    const Eigen::Vector2d step = J.colPivHouseholderQr().solve(f);
    if (!step.allFinite()) break;
    x -= step;
  }
  return x;
}

Eigen::Vector3d CameraModel::ray_rig(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d xn = undistort_to_normalized(pixel);
  return (R.transpose() * Eigen::Vector3d(xn.x(), xn.y(), 1.0)).normalized();
}

const CameraModel* RigCalibration::find(std::string_view name) const {
  for (const CameraModel& c : cameras)
    if (c.name == name) return &c;
  return nullptr;
}

Status validate(const CameraModel& c) {
  const auto bad = [&](std::string_view what) {
    return invalid_argument(fmt::format("camera '{}': {}", c.name, what));
  };
  if (c.name.empty()) return invalid_argument("camera with an empty name");
  if (c.width <= 0 || c.height <= 0) return bad("image size must be positive");
  if (!(std::isfinite(c.fx) && std::isfinite(c.fy) && c.fx > 0.0 && c.fy > 0.0))
    return bad("focal lengths must be positive and finite");
  if (!(std::isfinite(c.cx) && std::isfinite(c.cy))) return bad("principal point is not finite");
  const std::size_t n = c.distortion.size();
  if (n != 0 && n != 4 && n != 5 && n != 8)
    return bad(fmt::format("{} distortion coefficients (expected 0, 4, 5 or 8)", n));
  for (double d : c.distortion)
    if (!std::isfinite(d)) return bad("distortion coefficient is not finite");
  if (!c.R.allFinite() || !c.t_m.allFinite()) return bad("R or t is not finite");
  if ((c.R * c.R.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      c.R.determinant() < 0.0)
    return bad("R must be a rotation (orthonormal, determinant +1)");
  return {};
}

namespace {

cv::Mat to_cv(const Eigen::MatrixXd& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}

// Reads a matrix node of exactly rows x cols (cols < 0: any column count when rows == 1).
Result<Eigen::MatrixXd> read_matrix(const cv::FileNode& node, std::string_view key, int rows,
                                    int cols, const std::string& where) {
  if (node.empty() || !node.isMap())
    return invalid_argument(fmt::format("{}: '{}' missing or not a matrix", where, key));
  // The declared size must match the data before OpenCV allocates rows x cols (found by
  // fuzz_rig_calibration: "rows: (3" made cv::Mat try to allocate 48 GB).
  {
    const cv::FileNode r = node["rows"], c = node["cols"], data = node["data"];
    if (!r.isInt() || !c.isInt() || !data.isSeq() || static_cast<int>(r) < 0 ||
        static_cast<int>(c) < 0 ||
        static_cast<std::size_t>(static_cast<int>(r)) *
                static_cast<std::size_t>(static_cast<int>(c)) !=
            data.size())
      return invalid_argument(fmt::format(
          "{}: '{}' is not a well-formed matrix (rows, cols and data disagree)", where, key));
  }
  cv::Mat m;
  node >> m;
  if (m.empty() && !(rows == 1 && cols < 0))
    return invalid_argument(fmt::format("{}: '{}' is empty", where, key));
  if (!m.empty() && (m.rows != rows || (cols >= 0 && m.cols != cols)))
    return invalid_argument(fmt::format("{}: '{}' is {}x{}, expected {}x{}", where, key, m.rows,
                                        m.cols, rows,
                                        cols < 0 ? std::string("N") : std::to_string(cols)));
  Eigen::MatrixXd e;
  if (!m.empty()) {
    cv::Mat d;
    m.convertTo(d, CV_64F);
    cv::cv2eigen(d, e);
  }
  if (!e.allFinite()) return invalid_argument(fmt::format("{}: '{}' is not finite", where, key));
  return e;
}

Result<double> read_number(const cv::FileNode& node, std::string_view key,
                           const std::string& where) {
  if (node.empty() || !(node.isReal() || node.isInt()))
    return invalid_argument(fmt::format("{}: '{}' missing or not a number", where, key));
  const double v = static_cast<double>(node);
  if (!std::isfinite(v)) return invalid_argument(fmt::format("{}: '{}' is not finite", where, key));
  return v;
}

Result<RigCalibration> parse(const cv::FileStorage& fs, const std::string& file) {
  RigCalibration rig;
  const cv::FileNode names = fs["camera_names"];
  if (names.empty() || !names.isSeq() || names.size() == 0)
    return invalid_argument(file + ": 'camera_names' missing or not a non-empty sequence");
  std::set<std::string> seen;
  for (const cv::FileNode& n : names) {
    if (!n.isString()) return invalid_argument(file + ": 'camera_names' holds a non-string");
    const std::string name = static_cast<std::string>(n);
    if (name.empty() || !seen.insert(name).second)
      return invalid_argument(file + ": camera name '" + name + "' is empty or repeated");
    const cv::FileNode node = fs[name];
    const std::string where = file + ": " + name;
    if (node.empty() || !node.isMap()) return invalid_argument(where + ": missing camera map");
    CameraModel c;
    c.name = name;
    HC_ASSIGN_OR_RETURN(double w, read_number(node["image_width"], "image_width", where));
    HC_ASSIGN_OR_RETURN(double h, read_number(node["image_height"], "image_height", where));
    if (w < 1 || h < 1 || w > 1e6 || h > 1e6 || w != std::floor(w) || h != std::floor(h))
      return invalid_argument(where + ": image size must be positive integers");
    c.width = static_cast<int>(w);
    c.height = static_cast<int>(h);
    HC_ASSIGN_OR_RETURN(Eigen::MatrixXd K,
                        read_matrix(node["camera_matrix"], "camera_matrix", 3, 3, where));
    c.fx = K(0, 0);
    c.fy = K(1, 1);
    c.cx = K(0, 2);
    c.cy = K(1, 2);
    HC_ASSIGN_OR_RETURN(Eigen::MatrixXd d, read_matrix(node["distortion_coefficients"],
                                                       "distortion_coefficients", 1, -1, where));
    c.distortion.assign(d.data(), d.data() + d.size());
    HC_ASSIGN_OR_RETURN(Eigen::MatrixXd R, read_matrix(node["R"], "R", 3, 3, where));
    HC_ASSIGN_OR_RETURN(Eigen::MatrixXd t, read_matrix(node["t"], "t", 3, 1, where));
    c.R = R;
    c.t_m = t;
    if (!node["rms_px"].empty()) {
      HC_ASSIGN_OR_RETURN(c.rms_px, read_number(node["rms_px"], "rms_px", where));
    }
    const Status s = validate(c);
    if (!s.ok()) return invalid_argument(file + ": " + s.message());
    rig.cameras.push_back(std::move(c));
  }
  if (!fs["joint_rms_px"].empty()) {
    HC_ASSIGN_OR_RETURN(rig.joint_rms_px, read_number(fs["joint_rms_px"], "joint_rms_px", file));
  }
  if (!fs["world_from_rig"].empty()) {
    HC_ASSIGN_OR_RETURN(Eigen::MatrixXd T,
                        read_matrix(fs["world_from_rig"], "world_from_rig", 4, 4, file));
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    if ((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0.0 ||
        (T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-12)
      return invalid_argument(file + ": 'world_from_rig' is not a rigid transform");
    rig.world_from_rig.matrix() = T;
  }
  return rig;
}

}  // namespace

Status write_rig_calibration(const std::filesystem::path& path, const RigCalibration& rig) {
  if (rig.cameras.empty()) return invalid_argument("rig calibration without cameras");
  std::set<std::string> seen;
  for (const CameraModel& c : rig.cameras) {
    HC_RETURN_IF_ERROR(validate(c));
    if (!seen.insert(c.name).second)
      return invalid_argument("camera name '" + c.name + "' is repeated");
    // FileStorage keys: a letter or '_' first, then letters, digits, '_' or '-'.
    const bool ok_first = std::isalpha(static_cast<unsigned char>(c.name[0])) || c.name[0] == '_';
    bool ok_rest = true;
    for (char ch : c.name)
      ok_rest = ok_rest && (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-');
    if (!ok_first || !ok_rest)
      return invalid_argument("camera name '" + c.name +
                              "' is not a valid YAML key (letters, digits, '_', '-')");
  }
  std::string text;
  try {
    cv::FileStorage fs(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    fs.writeComment("Hardcopy rig calibration: x_cam = R * x_rig + t (metres, pixels)");
    fs << "camera_names"
       << "[";
    for (const CameraModel& c : rig.cameras) fs << c.name;
    fs << "]";
    fs << "joint_rms_px" << rig.joint_rms_px;
    fs << "world_from_rig" << to_cv(rig.world_from_rig.matrix());
    for (const CameraModel& c : rig.cameras) {
      fs << c.name << "{";
      fs << "image_width" << c.width << "image_height" << c.height;
      fs << "camera_matrix" << to_cv(c.K());
      Eigen::RowVectorXd d(static_cast<Eigen::Index>(c.distortion.size()));
      for (std::size_t i = 0; i < c.distortion.size(); ++i)
        d(static_cast<Eigen::Index>(i)) = c.distortion[i];
      fs << "distortion_coefficients" << to_cv(d);
      fs << "R" << to_cv(c.R) << "t" << to_cv(c.t_m);
      fs << "rms_px" << c.rms_px;
      fs << "}";
    }
    text = fs.releaseAndGetString();
  } catch (const cv::Exception& e) {
    return internal_error(std::string("OpenCV FileStorage: ") + e.what());
  }
  return write_file_atomic(path, text);
}

Result<RigCalibration> read_rig_calibration(const std::filesystem::path& path) {
  constexpr std::size_t kMaxBytes = 16u << 20;
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, kMaxBytes));
  const std::string file = path.string();
  if (text.find_first_not_of(" \t\r\n") == std::string::npos)
    return invalid_argument(file + ": empty calibration file");
  try {
    cv::FileStorage fs(
        text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
    if (!fs.isOpened()) return invalid_argument(file + ": not an OpenCV YAML file");
    return parse(fs, file);
  } catch (const cv::Exception& e) {
    // OpenCV reports parse errors by exception; keep its first line (it names the line).
    std::string what = e.what();
    if (const auto nl = what.find('\n', 1); nl != std::string::npos && nl > 0) what.resize(nl);
    return invalid_argument(file + ": malformed YAML: " + what);
  } catch (const std::exception& e) {
    // OpenCV's parser also lets standard exceptions escape on some malformed input (found by
    // fuzz_rig_calibration: std::length_error from a string it sizes from garbage).
    return invalid_argument(file + ": malformed YAML (" + e.what() + ")");
  }
}

}  // namespace hc::calib
