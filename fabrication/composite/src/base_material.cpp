#include "fabrication/composite/base_material.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

namespace hc::composite {
namespace {

constexpr double kSqrt2 = 1.4142135623730951;
constexpr double kMaxConditionInverse = 1e-9;

// K / mu for a Poisson's ratio: K / mu = 2 (1 + nu) / (3 (1 - 2 nu)), increasing in nu.
double bulk_to_shear(double nu) { return 2.0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu)); }

Eigen::VectorXd project_isotropic(const Eigen::VectorXd& p, const FeasibilityLimits& l) {
  const double mu_floor = l.min_modulus_pa / (2.0 * (1.0 + l.min_poisson));
  double mu = p(1);
  double k = p(0) + 2.0 * mu / 3.0;
  if (!std::isfinite(mu) || !std::isfinite(k)) {
    mu = mu_floor;
    k = bulk_to_shear(std::clamp(0.3, l.min_poisson, l.max_poisson)) * mu;
  } else if (!(mu > 0) || !(k > 0)) {
    // (E, nu) are not defined for a non-positive shear or bulk modulus: keep the shear modulus
    // (at least the floor's) and bring the bulk modulus into the allowed ratio range.
    mu = std::max(mu, mu_floor);
    k = std::clamp(k, bulk_to_shear(l.min_poisson) * mu, bulk_to_shear(l.max_poisson) * mu);
  }
  // The thesis's projection: compute (E, nu), clamp them to feasible values, convert back.
  double e = 9.0 * k * mu / (3.0 * k + mu);
  double nu = (3.0 * k - 2.0 * mu) / (2.0 * (3.0 * k + mu));
  nu = std::clamp(nu, l.min_poisson, l.max_poisson);
  e = std::max(e, l.min_modulus_pa);
  Eigen::VectorXd out(2);
  out << e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu));
  return out;
}

Eigen::VectorXd project_transverse(const Eigen::VectorXd& p, const FeasibilityLimits& l) {
  const double f = l.min_modulus_pa;
  if (!p.allFinite()) {
    Eigen::VectorXd out(5);
    out << f, 0, 0, f, f;  // E11 - E12 = f, block diag(f, f), E44 = f
    return out;
  }
  // Invariant subspaces of a transversely isotropic E: (1,-1,0,0,0,0)/sqrt2 with stiffness
  // b = E11 - E12 (and the xy shear, b/2), the span of (1,1,0)/sqrt2 and (0,0,1) with the block
  // [[a, c], [c, d]], a = E11 + E12, c = sqrt2 E13, d = E33, and the xz/yz shears E44.
  double a = p(0) + p(1);
  double c = kSqrt2 * p(2);
  double d = p(3);
  Eigen::Matrix2d m;
  m << a, c, c, d;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(m);
  // Every eigenvalue also stays above a tiny fraction of the largest, so the stiffness keeps a
  // condition number that double precision resolves (1e9; printed materials stay below 1e4):
  // otherwise a stiffness with one modulus of 1e30 Pa is positive definite only on paper.
  const double largest = std::max({std::abs(p(0) - p(1)), std::abs(p(4)),
                                   es.eigenvalues().cwiseAbs().maxCoeff()});
  const double floor = std::max(f, kMaxConditionInverse * largest);
  const double b = std::max(p(0) - p(1), floor);
  const double e44 = std::max(p(4), floor);
  if (es.eigenvalues().minCoeff() < floor) {
    const Eigen::Vector2d lam = es.eigenvalues().cwiseMax(floor);
    m = es.eigenvectors() * lam.asDiagonal() * es.eigenvectors().transpose();
    a = m(0, 0);
    c = 0.5 * (m(0, 1) + m(1, 0));
    d = m(1, 1);
  }
  Eigen::VectorXd out(5);
  out << 0.5 * (a + b), 0.5 * (a - b), c / kSqrt2, d, e44;
  return out;
}

}  // namespace

std::string_view to_string(BaseModel model) {
  return model == BaseModel::kIsotropic ? "isotropic" : "transverse";
}

Result<BaseModel> base_model_from_string(std::string_view name) {
  if (name == "isotropic") return BaseModel::kIsotropic;
  if (name == "transverse") return BaseModel::kTransverse;
  return invalid_argument(
      fmt::format("unknown base-material model '{}' (expected isotropic or transverse)", name));
}

int parameter_count(BaseModel model) { return model == BaseModel::kIsotropic ? 2 : 5; }
int feature_count(BaseModel model) { return model == BaseModel::kIsotropic ? 3 : 6; }
int default_centres(BaseModel model) { return model == BaseModel::kIsotropic ? 6 : 12; }

Eigen::VectorXd strain_features(BaseModel model, const Vector6d& s) {
  if (model == BaseModel::kTransverse) return s;
  Eigen::Matrix3d t;
  t << s(0), 0.5 * s(3), 0.5 * s(4), 0.5 * s(3), s(1), 0.5 * s(5), 0.5 * s(4), 0.5 * s(5), s(2);
  const double i1 = t.trace();
  const Eigen::Matrix3d dev = t - (i1 / 3.0) * Eigen::Matrix3d::Identity();
  const double j2 = 0.5 * dev.squaredNorm();
  const double j3 = dev.determinant();
  Eigen::VectorXd f(3);
  f << i1, std::sqrt(std::max(j2, 0.0)), std::cbrt(j3);
  return f;
}

Matrix6d elasticity_matrix(BaseModel model, const Eigen::VectorXd& p) {
  Matrix6d e = Matrix6d::Zero();
  if (model == BaseModel::kIsotropic) {
    const double lambda = p(0), mu = p(1);
    e.topLeftCorner<3, 3>().setConstant(lambda);
    e.diagonal() += (Vector6d() << 2 * mu, 2 * mu, 2 * mu, mu, mu, mu).finished();
    return e;
  }
  const double e11 = p(0), e12 = p(1), e13 = p(2), e33 = p(3), e44 = p(4);
  e.topLeftCorner<3, 3>() << e11, e12, e13, e12, e11, e13, e13, e13, e33;
  e(3, 3) = 0.5 * (e11 - e12);  // xy: in-plane shear (Eq. 5.6's last row, in Eq. 4.1 order)
  e(4, 4) = e44;                // xz
  e(5, 5) = e44;                // yz
  return e;
}

Matrix6d elasticity_derivative(BaseModel model, int j) {
  Eigen::VectorXd unit = Eigen::VectorXd::Zero(parameter_count(model));
  unit(j) = 1.0;
  return elasticity_matrix(model, unit);  // E is linear in p
}

Status FeasibilityLimits::validate() const {
  if (!(std::isfinite(min_modulus_pa) && min_modulus_pa > 0))
    return invalid_argument(fmt::format("min_modulus_pa must be > 0, got {}", min_modulus_pa));
  if (!(min_poisson > -1.0 && min_poisson < max_poisson && max_poisson < 0.5))
    return invalid_argument(fmt::format(
        "Poisson's ratio limits must satisfy -1 < min_poisson < max_poisson < 0.5, got {} and {}",
        min_poisson, max_poisson));
  return {};
}

Eigen::VectorXd project_feasible(BaseModel model, const Eigen::VectorXd& p,
                                 const FeasibilityLimits& limits) {
  return model == BaseModel::kIsotropic ? project_isotropic(p, limits)
                                        : project_transverse(p, limits);
}

bool is_feasible(BaseModel model, const Eigen::VectorXd& p, const FeasibilityLimits& limits) {
  if (!p.allFinite()) return false;
  const Eigen::VectorXd q = project_feasible(model, p, limits);
  return (q - p).norm() <= 1e-9 * std::max(p.norm(), limits.min_modulus_pa);
}

Result<CardinalRbf> CardinalRbf::create(const Eigen::MatrixXd& centres) {
  const Eigen::Index n = centres.rows();
  if (n < 1 || centres.cols() < 1) return invalid_argument("RBF: needs at least one centre");
  if (!centres.allFinite()) return invalid_argument("RBF: centres must be finite");
  double scale = 0;
  for (Eigen::Index i = 0; i < n; ++i) scale = std::max(scale, centres.row(i).norm());
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n + 1, n + 1);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      a(i, j) = (centres.row(i) - centres.row(j)).norm();
      if (i < j && a(i, j) <= 1e-12 * std::max(scale, 1e-12))
        return invalid_argument(fmt::format("RBF: centres {} and {} coincide", i, j));
    }
    a(i, n) = a(n, i) = 1.0;
  }
  CardinalRbf rbf;
  rbf.centres_ = centres;
  // [[Phi, 1], [1^T, 0]] is invertible for distinct centres (phi(r) = r is conditionally positive
  // definite of order 1; Carr et al. 2001). Small: a dense LU.
  rbf.inverse_ = a.fullPivLu().inverse();
  if (!rbf.inverse_.allFinite()) return invalid_argument("RBF: singular centre configuration");
  return rbf;
}

Eigen::VectorXd CardinalRbf::weights(const Eigen::VectorXd& features) const {
  const Eigen::Index n = centres_.rows();
  Eigen::VectorXd phi(n + 1);
  for (Eigen::Index i = 0; i < n; ++i) phi(i) = (centres_.row(i).transpose() - features).norm();
  phi(n) = 1.0;
  return inverse_.topRows(n) * phi;
}

Result<BaseMaterial> BaseMaterial::create(BaseModel model, Eigen::MatrixXd centres,
                                          Eigen::MatrixXd values, const FeasibilityLimits& limits) {
  HC_RETURN_IF_ERROR(limits.validate());
  if (centres.rows() < 1)
    return invalid_argument("base material: needs at least one RBF centre");
  if (centres.cols() != feature_count(model))
    return invalid_argument(fmt::format("base material: {} centres have {} coordinates, expected {}",
                                        to_string(model), centres.cols(), feature_count(model)));
  if (values.rows() != centres.rows() || values.cols() != parameter_count(model))
    return invalid_argument(fmt::format(
        "base material: values are {} by {}, expected {} by {} (one {} parameter vector per "
        "centre)",
        values.rows(), values.cols(), centres.rows(), parameter_count(model), to_string(model)));
  if (!values.allFinite()) return invalid_argument("base material: values must be finite");
  HC_ASSIGN_OR_RETURN(CardinalRbf rbf, CardinalRbf::create(centres));
  return BaseMaterial(model, std::move(rbf), std::move(values), limits);
}

Eigen::VectorXd BaseMaterial::weights(const Vector6d& strain) const {
  return rbf_.weights(strain_features(model_, strain));
}

Eigen::VectorXd BaseMaterial::params(const Vector6d& strain) const {
  return params_at_features(strain_features(model_, strain));
}

Eigen::VectorXd BaseMaterial::params_at_features(const Eigen::VectorXd& features) const {
  const Eigen::VectorXd raw = values_.transpose() * rbf_.weights(features);
  return project_feasible(model_, raw, limits_);
}

Matrix6d BaseMaterial::elasticity(const Vector6d& strain) const {
  return elasticity_matrix(model_, params(strain));
}

BaseMaterial BaseMaterial::with_values(const Eigen::MatrixXd& values) const {
  Eigen::MatrixXd v = values;
  for (Eigen::Index i = 0; i < v.rows(); ++i)
    v.row(i) = project_feasible(model_, v.row(i).transpose(), limits_).transpose();
  return BaseMaterial(model_, rbf_, std::move(v), limits_);
}

fem::LambdaAlpha isotropic_stand_in(const Matrix6d& e) {
  // Eq. 4.6: E = lambda G + alpha H has normal entries lambda - alpha and couplings alpha.
  const double normal = e.diagonal().head<3>().mean();
  const double coupling = (e(0, 1) + e(0, 2) + e(1, 2)) / 3.0;
  // Keep it physically valid (-lambda < alpha < lambda / 2, Eq. 4.7).
  const double lambda = std::max(normal + coupling, std::numeric_limits<double>::min());
  return {lambda, std::clamp(coupling, -0.9 * lambda, 0.49 * lambda)};
}

}  // namespace hc::composite
