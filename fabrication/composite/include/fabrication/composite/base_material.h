// Base materials (thesis Sec. 5.3-5.4, 5.7): one homogeneous, non-linear data-driven material per
// printable (or purchasable) base material, represented by P parameter vectors p_i at P strain-space
// centres and interpolated in between with the biharmonic RBF of Eq. 5.3 (phi(r) = r plus a
// constant, so that a constant material is reproduced exactly).
//
// Two models:
// * isotropic (Sec. 5.3.1): p = (lambda, mu), the Lame parameters (Pa), a function of the three
//   strain invariants. The features are (I1, sqrt(J2), cbrt(J3)): the trace and the deviatoric
//   invariants J2 = I1^2/3 - I2 >= 0 and J3 = I3 - I1 I2 / 3 + 2 I1^3 / 27 of the strain tensor.
//   They are functions of (I1, I2, I3) and back (a change of coordinates), chosen because all three
//   then carry the units of strain, so the RBF's Euclidean distance weighs them alike (I2 and I3 are
//   quadratic and cubic in the strain and would vanish next to I1).
// * transverse (Sec. 5.7.2): p = (E11, E12, E13, E33, E44) of Eq. 5.6 (Pa), a function of the
//   rotated-frame strain 6-vector. The symmetry axis is the material's z (the printer's build
//   direction, along which the tubes run). Eq. 5.6 writes the shear rows in Voigt order (yz, xz,
//   xy); in Hardcopy's Eq. 4.1 order (xy, xz, yz) the in-plane shear xy gets (E11 - E12)/2 and the
//   out-of-plane shears xz and yz get E44 (engineering shear strains, see
//   processing/fem/corotational.h).
//
// Feasibility by projection (Sec. 5.4): isotropic values are moved to E >= min_modulus_pa and
// min_poisson <= nu <= max_poisson; transversely isotropic ones onto the closed-form positive-
// definiteness conditions of transverse isotropy (E44 > 0, E11 > |E12|, E33 > 0,
// E33 (E11 + E12) > 2 E13^2) with a margin min_modulus_pa, by projecting in the matrix's invariant
// subspaces (see project_feasible), which keeps the transversely isotropic structure. The thesis
// used Rebonato & Jaeckel's spectral method for this; applied to the full 6x6 matrix that method
// returns a matrix that is no longer transversely isotropic.
#pragma once

#include <Eigen/Core>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "processing/fem/corotational.h"

namespace hc::composite {

using fem::Matrix6d;
using fem::Vector6d;

enum class BaseModel { kIsotropic, kTransverse };

// "isotropic" / "transverse".
std::string_view to_string(BaseModel model);
// invalid_argument for anything else, naming the value.
Result<BaseModel> base_model_from_string(std::string_view name);

// |p|: 2 (lambda, mu) or 5 (E11, E12, E13, E33, E44).
int parameter_count(BaseModel model);
// Dimension of the RBF's domain: 3 (invariant features) or 6 (strain).
int feature_count(BaseModel model);
// Default number of RBF centres (thesis Sec. 5.8.1): 6 isotropic, 12 transverse.
int default_centres(BaseModel model);

// The RBF's coordinates of a rotated-frame strain 6-vector (Eq. 4.1 order, engineering shears).
Eigen::VectorXd strain_features(BaseModel model, const Vector6d& strain);

// The 6x6 elasticity matrix of a parameter vector (linear in p), and dE/dp_j (constant).
Matrix6d elasticity_matrix(BaseModel model, const Eigen::VectorXd& p);
Matrix6d elasticity_derivative(BaseModel model, int j);

struct FeasibilityLimits {
  // Isotropic: Young's modulus floor; transverse: the floor of the invariant-subspace stiffnesses
  // (E11 - E12, E44 and the eigenvalues of [[E11 + E12, sqrt2 E13], [sqrt2 E13, E33]]). Pa, > 0.
  double min_modulus_pa = 1.0;
  // Isotropic Poisson's ratio range, inside (-1, 0.5).
  double min_poisson = -0.9;
  double max_poisson = 0.49;

  Status validate() const;
};

// The feasible point nearest to `p` as described in the header comment. Isotropic: (E, nu) of p are
// clamped (a non-positive shear or bulk modulus first goes to the floor / to the smallest ratio);
// transverse: b = E11 - E12 and E44 are clamped at the floor and the 2x2 block
// [[E11 + E12, sqrt2 E13], [sqrt2 E13, E33]] has its eigenvalues clamped at the floor: the Frobenius
// norm of E splits into these three parts, so this is E's Frobenius-nearest transversely isotropic
// matrix with the margins. Non-finite input gives the floor material.
Eigen::VectorXd project_feasible(BaseModel model, const Eigen::VectorXd& p,
                                 const FeasibilityLimits& limits);
// True when p already satisfies the limits (projection would not move it beyond round-off).
bool is_feasible(BaseModel model, const Eigen::VectorXd& p, const FeasibilityLimits& limits);

// Cardinal weights of the biharmonic RBF with a constant term over fixed centres: for features f,
// l(f) (size P) with sum l = 1 and l(c_i) = e_i, so p(f) = sum_i l_i(f) p_i interpolates the centre
// values. Centres must be distinct.
class CardinalRbf {
 public:
  // invalid_argument for no centres, mixed dimensions, non-finite or repeated centres.
  static Result<CardinalRbf> create(const Eigen::MatrixXd& centres);  // P by d
  Eigen::Index size() const { return centres_.rows(); }
  const Eigen::MatrixXd& centres() const { return centres_; }
  Eigen::VectorXd weights(const Eigen::VectorXd& features) const;

 private:
  Eigen::MatrixXd centres_;  // P by d
  Eigen::MatrixXd inverse_;  // (P+1) by (P+1) inverse of [[Phi, 1], [1^T, 0]]
};

// One fitted base material: the model, its centres and values, the limits, and where it came
// from. Thread-compatible (evaluation is const).
class BaseMaterial {
 public:
  // invalid_argument when sizes do not match the model (centres P by feature_count, values P by
  // parameter_count), P < 1, non-finite numbers, repeated centres, or invalid limits.
  static Result<BaseMaterial> create(BaseModel model, Eigen::MatrixXd centres,
                                     Eigen::MatrixXd values, const FeasibilityLimits& limits);

  BaseModel model() const { return model_; }
  const Eigen::MatrixXd& centres() const { return rbf_.centres(); }
  const Eigen::MatrixXd& values() const { return values_; }  // P by |p| (Pa)
  const FeasibilityLimits& limits() const { return limits_; }
  Eigen::Index num_centres() const { return rbf_.size(); }

  // Projected parameters and the elasticity matrix at a rotated-frame strain.
  Eigen::VectorXd params(const Vector6d& strain) const;
  // Projected parameters at a point of the RBF's feature space (strain_features()).
  Eigen::VectorXd params_at_features(const Eigen::VectorXd& features) const;
  Matrix6d elasticity(const Vector6d& strain) const;
  // The RBF's cardinal weights at a strain (for the fit's Jacobian).
  Eigen::VectorXd weights(const Vector6d& strain) const;
  // A copy with other centre values (same centres), projected onto the limits.
  BaseMaterial with_values(const Eigen::MatrixXd& values) const;

 private:
  BaseMaterial(BaseModel model, CardinalRbf rbf, Eigen::MatrixXd values, FeasibilityLimits limits)
      : model_(model), rbf_(std::move(rbf)), values_(std::move(values)), limits_(limits) {}
  BaseModel model_;
  CardinalRbf rbf_;
  Eigen::MatrixXd values_;
  FeasibilityLimits limits_;
};

// The (lambda, alpha) of thesis Eq. 4.6 of an isotropic elasticity matrix, and an isotropic
// stand-in for any other (what fem::MaterialModel::params() returns for anisotropic models): from
// the mean normal stiffness (lambda - alpha) and the mean normal coupling (alpha).
fem::LambdaAlpha isotropic_stand_in(const Matrix6d& e);

}  // namespace hc::composite
