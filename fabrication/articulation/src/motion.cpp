#include "fabrication/articulation/motion.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace hc::articulation {
namespace {

// The bone's core vertices: weight >= core, else the vertices it dominates.
std::vector<std::vector<Eigen::Index>> core_vertices(const SkinnedCharacter& c, double core) {
  const Eigen::MatrixXd w = c.dense_weights();
  std::vector<std::vector<Eigen::Index>> strong(c.bones.size()), dominated(c.bones.size());
  for (Eigen::Index v = 0; v < w.rows(); ++v) {
    Eigen::Index best = 0;
    const double top = w.row(v).maxCoeff(&best);
    dominated[static_cast<std::size_t>(best)].push_back(v);
    for (Eigen::Index b = 0; b < w.cols(); ++b)
      if (w(v, b) >= core) strong[static_cast<std::size_t>(b)].push_back(v);
    (void)top;
  }
  for (std::size_t b = 0; b < strong.size(); ++b)
    if (strong[b].size() < 4) strong[b] = dominated[b];
  return strong;
}

Eigen::Isometry3d rigid_part(const Eigen::Affine3d& a) {
  Eigen::Matrix3d rotation, scaling;
  a.computeRotationScaling(&rotation, &scaling);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = rotation;
  out.translation() = a.translation();
  return out;
}

}  // namespace

Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  double angle = aa.angle();
  Eigen::Vector3d axis = aa.axis();
  if (angle > std::numbers::pi) angle -= 2 * std::numbers::pi;
  return axis * angle;
}

Status MotionOptions::validate() const {
  if (!(core_weight > 0 && core_weight <= 1))
    return invalid_argument(fmt::format("core_weight must be in (0, 1], got {}", core_weight));
  if (!(fused_below_rad >= 0) || !(hinge_off_axis_fraction > 0) || !(hinge_off_axis_rad > 0))
    return invalid_argument("motion thresholds must be positive");
  return {};
}

Result<LinkMotion> fit_link_motion(const SkinnedCharacter& c, const MotionOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const auto cores = core_vertices(c, options.core_weight);
  LinkMotion out;
  const MatrixX3d& rest = c.mesh.vertices;
  for (const Clip& clip : c.clips) {
    std::vector<std::vector<Eigen::Isometry3d>> frames;
    for (const auto& globals : clip.bone_globals) {
      const MatrixX3d posed = c.pose(globals);
      std::vector<Eigen::Isometry3d> bones(c.bones.size());
      for (std::size_t b = 0; b < c.bones.size(); ++b) {
        const auto& core = cores[b];
        if (core.size() < 3) {
          // Skinning transform of the bone in the model frame: scale/shift conjugated.
          Eigen::Affine3d m = Eigen::Affine3d::Identity();
          m = Eigen::Translation3d(c.shift) * Eigen::Scaling(c.scale) * globals[b] *
              c.rest_bone_globals[b].inverse() * Eigen::Scaling(1.0 / c.scale) *
              Eigen::Translation3d(-c.shift);
          bones[b] = rigid_part(m);
          continue;
        }
        Eigen::Matrix3Xd src(3, core.size()), dst(3, core.size());
        for (std::size_t k = 0; k < core.size(); ++k) {
          src.col(static_cast<Eigen::Index>(k)) = rest.row(core[k]).transpose();
          dst.col(static_cast<Eigen::Index>(k)) = posed.row(core[k]).transpose();
        }
        Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
        t.matrix() = Eigen::umeyama(src, dst, false);
        const double rms = std::sqrt(((t * src) - dst).colwise().squaredNorm().mean());
        out.max_fit_rms_m = std::max(out.max_fit_rms_m, rms);
        bones[b] = t;
      }
      frames.push_back(std::move(bones));
    }
    out.transforms.push_back(std::move(frames));
  }
  return out;
}

MotionEstimate estimate_joint_motion(const LinkMotion& motion, int parent, int child,
                                     const Eigen::Vector3d& n, const Eigen::Vector3d& prior_centre,
                                     const std::vector<Clip>& clips, const MotionOptions& options) {
  MotionEstimate out;
  std::vector<Eigen::Vector3d> omegas;
  std::vector<Eigen::Isometry3d> tp, tc;
  for (std::size_t k = 0; k < motion.transforms.size(); ++k) {
    double clip_max = 0.0;
    for (const auto& frame : motion.transforms[k]) {
      const Eigen::Isometry3d& a = frame[static_cast<std::size_t>(parent)];
      const Eigen::Isometry3d& b = frame[static_cast<std::size_t>(child)];
      const Eigen::Vector3d w = rotation_vector(a.linear().transpose() * b.linear());
      omegas.push_back(w);
      tp.push_back(a);
      tc.push_back(b);
      clip_max = std::max(clip_max, w.norm());
    }
    if (clip_max > options.fused_below_rad && k < clips.size()) out.clips.push_back(clips[k].name);
    out.max_angle_rad = std::max(out.max_angle_rad, clip_max);
  }
  out.frames = static_cast<int>(omegas.size());
  out.centre = prior_centre;
  out.centre_free_directions = 3;
  if (omegas.empty() || out.max_angle_rad <= options.fused_below_rad) return out;

  // Principal axis of the rotation vectors (uncentred: a hinge's vectors lie on one line
  // through 0).
  Eigen::MatrixX3d omega(static_cast<Eigen::Index>(omegas.size()), 3);
  for (std::size_t i = 0; i < omegas.size(); ++i)
    omega.row(static_cast<Eigen::Index>(i)) = omegas[i].transpose();
  const Eigen::JacobiSVD<Eigen::MatrixX3d> svd(omega, Eigen::ComputeThinV);
  Eigen::Vector3d axis = svd.matrixV().col(0);
  const Eigen::VectorXd along = omega * axis;
  const Eigen::MatrixX3d off = omega - along * axis.transpose();
  out.on_axis_rms_rad = std::sqrt(along.squaredNorm() / along.size());
  out.off_axis_rms_rad = std::sqrt(off.squaredNorm() / along.size());
  const bool one_axis =
      out.off_axis_rms_rad < options.hinge_off_axis_fraction * out.on_axis_rms_rad &&
      out.off_axis_rms_rad < options.hinge_off_axis_rad;
  const bool twist = std::abs(axis.dot(n)) > std::cos(options.twist_axis_within_rad);
  if (one_axis && !twist) {
    out.type = MotionJointType::kHinge;
    if (along.maxCoeff() < -along.minCoeff()) axis = -axis;  // the larger swing is forward
    out.axis = axis;
    const Eigen::VectorXd angle = omega * axis;
    out.swing_forward_rad = std::max(0.0, angle.maxCoeff());
    out.swing_backward_rad = std::max(0.0, -angle.minCoeff());
  } else {
    out.type = MotionJointType::kBall;
    // Tilts of n, as vectors angle * direction in the plane perpendicular to n.
    std::vector<Eigen::Vector3d> tilts;
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (std::size_t i = 0; i < tp.size(); ++i) {
      const Eigen::Vector3d m = (tp[i].linear().transpose() * tc[i].linear()) * n;
      const Eigen::Vector3d side = m - m.dot(n) * n;
      const double angle = std::atan2(side.norm(), m.dot(n));
      const Eigen::Vector3d t = side.norm() > 1e-12 ? Eigen::Vector3d(angle * side.normalized())
                                                    : Eigen::Vector3d::Zero();
      tilts.push_back(t);
      scatter += t * t.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
    Eigen::Vector3d major = eig.eigenvectors().col(2);
    major = (major - major.dot(n) * n).normalized();
    const Eigen::Vector3d minor = n.cross(major);
    double a = 1e-6, b = 1e-6;
    for (const Eigen::Vector3d& t : tilts) {
      a = std::max(a, std::abs(t.dot(major)));
      b = std::max(b, std::abs(t.dot(minor)));
    }
    // Grow the ellipse until it covers every tilt.
    double grow = 1.0;
    for (const Eigen::Vector3d& t : tilts) {
      const double x = t.dot(major) / a, y = t.dot(minor) / b;
      grow = std::max(grow, std::hypot(x, y));
    }
    out.tilt_direction = major;
    out.cone_major_rad = a * grow;
    out.cone_minor_rad = b * grow;
  }

  // Least-squares centre: (R_p - R_c) c = t_c - t_p over the frames, min-norm change from the
  // prior along the directions the motion does not fix.
  Eigen::MatrixXd A(3 * static_cast<Eigen::Index>(tp.size()), 3);
  Eigen::VectorXd rhs(A.rows());
  for (std::size_t i = 0; i < tp.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(3 * i);
    A.block<3, 3>(r, 0) = tp[i].linear() - tc[i].linear();
    rhs.segment<3>(r) = tc[i].translation() - tp[i].translation();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> csvd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd s = csvd.singularValues();
  const Eigen::VectorXd residual = rhs - A * prior_centre;
  Eigen::Vector3d step = Eigen::Vector3d::Zero();
  out.centre_free_directions = 0;
  for (int k = 0; k < 3; ++k) {
    if (s(k) <= options.centre_singular_cutoff * s(0) || s(k) <= 0) {
      ++out.centre_free_directions;
      continue;
    }
    step += csvd.matrixV().col(k) * (csvd.matrixU().col(k).dot(residual) / s(k));
  }
  out.centre = prior_centre + step;
  out.centre_rms_m =
      std::sqrt((A * out.centre - rhs).squaredNorm() / static_cast<double>(tp.size()));
  return out;
}

}  // namespace hc::articulation
