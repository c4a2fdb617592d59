#include "processing/tracking/triangulation.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>

namespace hc::tracking {
namespace {

Status check_views(const std::vector<View>& views) {
  if (views.size() < 2)
    return invalid_argument(
        fmt::format("triangulation needs at least 2 views, got {}", views.size()));
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (views[i].camera == nullptr)
      return invalid_argument(fmt::format("view {} has no camera", i));
    if (!views[i].pixel_px.allFinite())
      return invalid_argument(fmt::format("view {} pixel is not finite", i));
  }
  return {};
}

// d(pixel)/d(normalised point) of the distortion model by central differences: the model
// (CameraModel::distort_normalized) is not templated for autodiff, and a 2x2 difference quotient at
// step 1e-7 of normalised coordinates (~1e-4 px) is accurate to ~1e-8 relative, far below what the
// Gauss-Newton step needs.
Eigen::Matrix2d distortion_jacobian(const CameraModel& cam, const Eigen::Vector2d& xn) {
  constexpr double kH = 1e-7;
  Eigen::Matrix2d J;
  for (int k = 0; k < 2; ++k) {
    Eigen::Vector2d a = xn, b = xn;
    a[k] += kH;
    b[k] -= kH;
    J.col(k) = (cam.distort_normalized(a) - cam.distort_normalized(b)) / (2 * kH);
  }
  return J;
}

}  // namespace

Status TriangulationOptions::validate() const {
  if (max_iterations < 0 || max_iterations > 1000)
    return invalid_argument(fmt::format("max_iterations {} is not in [0, 1000]", max_iterations));
  if (!(step_tolerance_m > 0.0) || !std::isfinite(step_tolerance_m))
    return invalid_argument("step_tolerance_m must be positive and finite");
  return {};
}

double reprojection_error_px(const View& view, const Eigen::Vector3d& point_m) {
  const auto p = view.camera->project(point_m);
  if (!p) return std::numeric_limits<double>::infinity();
  return (*p - view.pixel_px).norm();
}

Result<Eigen::Vector3d> triangulate_linear(const std::vector<View>& views) {
  HC_RETURN_IF_ERROR(check_views(views));
  const auto n = static_cast<Eigen::Index>(views.size());
  Eigen::MatrixXd A(2 * n, 4);
  for (Eigen::Index i = 0; i < n; ++i) {
    const CameraModel& cam = *views[static_cast<std::size_t>(i)].camera;
    const Eigen::Vector2d xn =
        cam.undistort_to_normalized(views[static_cast<std::size_t>(i)].pixel_px);
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = cam.R;
    P.col(3) = cam.t_m;
    A.row(2 * i) = xn.x() * P.row(2) - P.row(0);
    A.row(2 * i + 1) = xn.y() * P.row(2) - P.row(1);
    for (int r = 0; r < 2; ++r) {
      const double norm = A.row(2 * i + r).norm();
      if (norm > 0) A.row(2 * i + r) /= norm;
    }
  }
  // Condition the homogeneous coordinate: translate to the mean camera centre and scale by the
  // mean distance so the 4th column is commensurate with the others (H&Z Sec. 4.4.4).
  Eigen::Vector3d mean_c = Eigen::Vector3d::Zero();
  for (const View& v : views) mean_c += v.camera->center_m();
  mean_c /= static_cast<double>(n);
  double scale = 0;
  for (const View& v : views) scale += (v.camera->center_m() - mean_c).norm();
  scale = scale > 0 ? scale / static_cast<double>(n) : 1.0;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();  // X = T X'
  T.topLeftCorner<3, 3>() *= scale;
  T.topRightCorner<3, 1>() = mean_c;
  // The null vector of A T: the eigenvector of the smallest eigenvalue of the 4x4 normal matrix
  // (its rows and columns conditioned above; a dynamic-size SVD per point was 38 % of
  // `calib hand-eye`).
  const Eigen::Matrix<double, Eigen::Dynamic, 4> At = A * T;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> normal(At.transpose() * At);
  const Eigen::Vector4d Xh = T * normal.eigenvectors().col(0);
  if (std::abs(Xh[3]) < 1e-12 * Xh.head<3>().norm() || Xh[3] == 0.0)
    return failed_precondition("triangulation is degenerate (point at infinity: parallel rays)");
  const Eigen::Vector3d X = Xh.head<3>() / Xh[3];
  if (!X.allFinite()) return failed_precondition("triangulation is degenerate (not finite)");
  for (std::size_t i = 0; i < views.size(); ++i) {
    const Eigen::Vector3d xc = views[i].camera->R * X + views[i].camera->t_m;
    if (xc.z() <= 0)
      return failed_precondition(fmt::format(
          "triangulated point is behind camera '{}' (inconsistent views)", views[i].camera->name));
  }
  return X;
}

Result<Triangulation> triangulate(const std::vector<View>& views,
                                  const TriangulationOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  HC_ASSIGN_OR_RETURN(Eigen::Vector3d X, triangulate_linear(views));
  Triangulation out;
  out.converged = true;
  const auto n = views.size();
  const auto residuals = [&](const Eigen::Vector3d& P, Eigen::VectorXd& r) {
    r.resize(static_cast<Eigen::Index>(2 * n));
    for (std::size_t i = 0; i < n; ++i) {
      const auto p = views[i].camera->project(P);
      if (!p) return false;
      r.segment<2>(static_cast<Eigen::Index>(2 * i)) = *p - views[i].pixel_px;
    }
    return true;
  };
  if (options.refine) {
    out.converged = false;
    Eigen::VectorXd r;
    residuals(X, r);
    double cost = r.squaredNorm();
    double lambda = 1e-6;
    Eigen::MatrixXd J(static_cast<Eigen::Index>(2 * n), 3);
    for (int it = 0; it < options.max_iterations; ++it) {
      out.iterations = it + 1;
      for (std::size_t i = 0; i < n; ++i) {
        const CameraModel& cam = *views[i].camera;
        const Eigen::Vector3d xc = cam.R * X + cam.t_m;
        const double iz = 1.0 / xc.z();
        const Eigen::Vector2d xn(xc.x() * iz, xc.y() * iz);
        Eigen::Matrix<double, 2, 3> dxn;
        dxn << iz, 0, -xc.x() * iz * iz, 0, iz, -xc.y() * iz * iz;
        J.block<2, 3>(static_cast<Eigen::Index>(2 * i), 0) =
            distortion_jacobian(cam, xn) * dxn * cam.R;
      }
      const Eigen::Matrix3d H = J.transpose() * J;
      const Eigen::Vector3d g = J.transpose() * r;
      bool improved = false;
      for (int tries = 0; tries < 10 && !improved; ++tries) {
        Eigen::Matrix3d Hd = H;
        Hd.diagonal() *= (1.0 + lambda);
        const Eigen::Vector3d dx = -Hd.ldlt().solve(g);
        if (!dx.allFinite()) break;
        const Eigen::Vector3d Xn = X + dx;
        Eigen::VectorXd rn;
        if (residuals(Xn, rn) && rn.squaredNorm() <= cost) {
          X = Xn;
          r = rn;
          cost = rn.squaredNorm();
          lambda = std::max(1e-9, lambda * 0.1);
          improved = true;
          if (dx.norm() < options.step_tolerance_m) out.converged = true;
        } else {
          lambda *= 10.0;
        }
      }
      if (!improved) {
        out.converged = true;  // no descent step left: at a (local) minimum
        break;
      }
      if (out.converged) break;
    }
  }
  out.point_m = X;
  out.residual_px.resize(n);
  double ss = 0;
  for (std::size_t i = 0; i < n; ++i) {
    out.residual_px[i] = reprojection_error_px(views[i], X);
    ss += out.residual_px[i] * out.residual_px[i];
  }
  out.rms_px = std::sqrt(ss / static_cast<double>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      const Eigen::Vector3d a = (X - views[i].camera->center_m()).normalized();
      const Eigen::Vector3d b = (X - views[j].camera->center_m()).normalized();
      out.max_ray_angle_rad =
          std::max(out.max_ray_angle_rad, std::atan2(a.cross(b).norm(), a.dot(b)));
    }
  return out;
}

}  // namespace hc::tracking
