// Strain-dependent material parameters p(eps) per element (thesis Sec. 4.2.3): the interface the
// incremental solver queries, plus a constant and a linear-in-strain model and the (E, nu) <->
// (lambda, alpha) conversions of Eq. 4.7. processing/material's RBF material implements
// MaterialModel.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "common/status.h"
#include "processing/fem/corotational.h"

namespace hc::fem {

struct YoungsPoisson {
  double youngs_pa = 0;
  double poisson = 0;
};

// lambda = E / ((1 + nu)(1 - 2 nu)), alpha = lambda nu (Eq. 4.7). Precondition nu != 0.5, nu != -1.
LambdaAlpha lambda_alpha_from_youngs_poisson(double youngs_pa, double poisson);
inline LambdaAlpha lambda_alpha_from(const YoungsPoisson& m) {
  return lambda_alpha_from_youngs_poisson(m.youngs_pa, m.poisson);
}
// Inverse: nu = alpha / lambda, E = lambda (1 + nu)(1 - 2 nu). Precondition lambda != 0.
YoungsPoisson youngs_poisson_from_lambda_alpha(const LambdaAlpha& p);
// Lame parameters: shear modulus mu = lambda/2 - alpha, first Lame parameter = alpha.
inline double shear_modulus(const LambdaAlpha& p) { return 0.5 * p.lambda - p.alpha; }
// invalid_argument unless E > 0 and -1 < nu < 0.5 (finite).
Status validate_youngs_poisson(double youngs_pa, double poisson);
// Physically valid (lambda, alpha): E > 0 and -1 < nu < 0.5, i.e. lambda > 0 and -lambda < alpha <
// lambda/2.
bool is_physically_valid(const LambdaAlpha& p);

class MaterialModel {
 public:
  virtual ~MaterialModel() = default;
  // (lambda, alpha) of element `element` at the rotated-frame strain 6-vector `strain` (Eq. 4.1
  // order, engineering shears, see corotational.h). Must be thread-compatible (const, no shared
  // mutation).
  virtual LambdaAlpha params(Eigen::Index element, const Vector6d& strain) const = 0;
  // false when params() ignores the strain (the incremental solver may then skip the updates).
  virtual bool strain_dependent() const { return true; }
  // true for models that are not isotropic (thesis Sec. 5.7.2): the solvers then take the full
  // elasticity() per element (CorotationalFem::set_elasticity), and params() need only be an
  // isotropic stand-in of similar stiffness.
  virtual bool anisotropic() const { return false; }
  // The 6x6 elasticity matrix E (Eq. 4.2; Eq. 4.1 order, engineering shears) of `element` at
  // `strain`; symmetric positive definite for a physically valid material.
  virtual Matrix6d elasticity(Eigen::Index element, const Vector6d& strain) const {
    return elasticity_matrix(params(element, strain));
  }
  // Number of elements this model describes, or -1 when it applies to any element index.
  virtual Eigen::Index num_elements() const { return -1; }
};

// Strain-independent parameters: one for all elements, or one per element.
class ConstantMaterial final : public MaterialModel {
 public:
  explicit ConstantMaterial(const LambdaAlpha& p) : uniform_(p) {}
  explicit ConstantMaterial(std::vector<LambdaAlpha> per_element)
      : per_element_(std::move(per_element)) {}
  LambdaAlpha params(Eigen::Index element, const Vector6d& strain) const override;
  bool strain_dependent() const override { return false; }
  Eigen::Index num_elements() const override;

 private:
  LambdaAlpha uniform_;
  std::vector<LambdaAlpha> per_element_;
};

// p(eps) = p0 + [d lambda / d eps, d alpha / d eps] eps, the same for all elements: the simplest
// strain-dependent model (stiffening or softening), used to test incremental loading. The result is
// clamped to is_physically_valid() by keeping nu and limiting E to >= min_youngs_pa.
class LinearStrainMaterial final : public MaterialModel {
 public:
  LinearStrainMaterial(const LambdaAlpha& p0, const Vector6d& dlambda_deps,
                       const Vector6d& dalpha_deps, double min_youngs_pa = 1.0)
      : p0_(p0), dlambda_(dlambda_deps), dalpha_(dalpha_deps), min_youngs_pa_(min_youngs_pa) {}
  LambdaAlpha params(Eigen::Index element, const Vector6d& strain) const override;

 private:
  LambdaAlpha p0_;
  Vector6d dlambda_;
  Vector6d dalpha_;
  double min_youngs_pa_;
};

}  // namespace hc::fem
