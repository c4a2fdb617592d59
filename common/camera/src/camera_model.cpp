#include "camera/camera_model.h"

#include <fmt/format.h>

#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/file_io.h"

namespace hc {

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

Eigen::Isometry3d CameraModel::camera_from_reference() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t_m;
  return T;
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
    const Eigen::Vector2d at_x = distort_normalized(x);
    const Eigen::Vector2d f = at_x - target;
    if (f.norm() < 1e-10) break;
    constexpr double h = 1e-7;
    Eigen::Matrix2d J;
    J.col(0) = (distort_normalized(x + Eigen::Vector2d(h, 0.0)) - at_x) / h;
    J.col(1) = (distort_normalized(x + Eigen::Vector2d(0.0, h)) - at_x) / h;
    const Eigen::Vector2d step = J.inverse() * f;  // closed-form 2x2; singular -> not finite
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

// Names the file's top level uses for itself; a camera cannot have them.
bool reserved_name(std::string_view name) {
  return name == "camera_names" || name == "joint_rms_px" || name == "world_from_rig";
}

// Reads the !!opencv-matrix under `key` (rows, cols, dt, data in row-major order) into `out`,
// which must be exactly rows x cols (cols < 0: 1 x N, N >= 0). False (error recorded) otherwise.
bool read_matrix(ConfigNode parent, std::string_view key, int rows, int cols,
                 Eigen::MatrixXd& out) {
  std::optional<ConfigNode> node = parent.find(key);
  if (!node) {
    parent.error(key, "required matrix is missing");
    return false;
  }
  int r = 0, c = 0;
  std::string dt;
  std::vector<double> data;
  // Declared sizes are bounded before anything is sized from them.
  bool ok = node->required("rows", r, Bounds::between(0, 64));
  ok = node->required("cols", c, Bounds::between(0, 64)) && ok;
  ok = node->required("dt", dt, {"d", "f", "i", "u", "s", "w", "c"}) && ok;
  ok = node->required("data", data) && ok;
  if (!ok) return false;
  if (static_cast<std::size_t>(r) * static_cast<std::size_t>(c) != data.size()) {
    node->error(fmt::format("'{}' is not a well-formed matrix: {}x{} declared, {} values", key, r,
                            c, data.size()));
    return false;
  }
  const bool any_row_vector = rows == 1 && cols < 0;
  if (!(any_row_vector && data.empty()) && (r != rows || (cols >= 0 && c != cols))) {
    node->error(fmt::format("'{}' is {}x{}, expected {}x{}", key, r, c, rows,
                            cols < 0 ? std::string("N") : std::to_string(cols)));
    return false;
  }
  if (data.empty()) {
    out.resize(1, 0);
    return true;
  }
  out = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      data.data(), r, c);
  return true;
}

void read_file_camera(ConfigNode node, CameraModel& c) {
  node.required("image_width", c.width, Bounds::between(1, 1e6));
  node.required("image_height", c.height, Bounds::between(1, 1e6));
  Eigen::MatrixXd K, d, R, t;
  if (read_matrix(node, "camera_matrix", 3, 3, K)) {
    c.fx = K(0, 0);
    c.fy = K(1, 1);
    c.cx = K(0, 2);
    c.cy = K(1, 2);
  }
  if (read_matrix(node, "distortion_coefficients", 1, -1, d))
    c.distortion.assign(d.data(), d.data() + d.size());
  if (read_matrix(node, "R", 3, 3, R)) c.R = R;
  if (read_matrix(node, "t", 3, 1, t)) c.t_m = t;
  node.optional("rms_px", c.rms_px, Bounds::non_negative());
  if (!node.status().ok()) return;
  if (const Status s = validate(c); !s.ok()) node.error(s.message());
}

Status parse(ConfigNode root, RigCalibration& rig) {
  std::vector<std::string> names;
  if (!root.required("camera_names", names)) return root.status();
  if (names.empty()) {
    root.error("camera_names", "'camera_names' must name at least one camera");
    return root.status();
  }
  std::set<std::string> seen;
  for (const std::string& name : names) {
    if (name.empty() || reserved_name(name) || !seen.insert(name).second) {
      root.error("camera_names", fmt::format("camera name '{}' is empty, reserved or repeated",
                                             name.substr(0, 64)));
      return root.status();
    }
  }
  for (const std::string& name : names) {
    CameraModel c;
    c.name = name;
    std::optional<ConfigNode> node = root.find(name);
    if (!node) {
      root.error(name, fmt::format("camera '{}' is listed in camera_names but has no map",
                                   name.substr(0, 64)));
      continue;
    }
    read_file_camera(*node, c);
    rig.cameras.push_back(std::move(c));
  }
  root.optional("joint_rms_px", rig.joint_rms_px, Bounds::non_negative());
  Eigen::MatrixXd T;
  if (root.has("world_from_rig") && read_matrix(root, "world_from_rig", 4, 4, T)) {
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    if ((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0.0 ||
        (T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-12)
      root.error("world_from_rig", "'world_from_rig' is not a rigid transform");
    else
      rig.world_from_rig.matrix() = T;
  }
  return root.status();
}

}  // namespace

Status write_rig_calibration(const std::filesystem::path& path, const RigCalibration& rig) {
  if (rig.cameras.empty()) return invalid_argument("rig calibration without cameras");
  std::set<std::string> seen;
  for (const CameraModel& c : rig.cameras) {
    HC_RETURN_IF_ERROR(validate(c));
    if (!seen.insert(c.name).second || reserved_name(c.name))
      return invalid_argument("camera name '" + c.name + "' is repeated or reserved");
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

// Read with yaml-cpp through common/config (bounded and fuzzed), not with OpenCV's FileStorage:
// OpenCV 4.6's YAML parser loops forever on some malformed input (found by fuzz_rig_calibration,
// e.g. "%YAML:1.0\n   -l\n:\nx"). OpenCV still writes the files and reads ours (tested).
Result<RigCalibration> read_rig_calibration(const std::filesystem::path& path) {
  constexpr std::size_t kMaxBytes = 16u << 20;
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, kMaxBytes));
  const std::string file = path.string();
  if (text.find_first_not_of(" \t\r\n") == std::string::npos)
    return invalid_argument(file + ": empty calibration file");
  // OpenCV's "%YAML:1.0" is not a YAML 1.2 directive; blank it (keeping the line count).
  if (text.starts_with("%YAML:")) text.replace(0, std::min(text.find('\n'), text.size()), "");
  HC_ASSIGN_OR_RETURN(Config config, parse_config(text, file));
  RigCalibration rig;
  HC_RETURN_IF_ERROR(
      read_config(config, [&](ConfigNode root) { return parse(root, rig); }));
  return rig;
}

}  // namespace hc
