// One example of a base-material fit (base_fit.cpp): its FEM, its (possibly augmented) forces, the
// measured dofs and targets, and the held state (rotations and the RBF weights of every element)
// under which the Levenberg-Marquardt residuals and Jacobians are linear solves.
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "common/status.h"
#include "fabrication/composite/base_material.h"
#include "fabrication/composite/composite.h"
#include "processing/fem/corotational.h"
#include "processing/material/samples.h"

namespace hc::composite {

class FitExample {
 public:
  // invalid_argument when the example has no fixed node, no measured free node or no force.
  static Result<FitExample> create(const material::Samples& samples, std::size_t index,
                                   BaseModel model, const ForwardOptions& forward);

  // Holds the rest state (rotations identity, zero strain) or the last full simulation's state
  // (its rotations and strains), with the RBF weights of `material`'s centres.
  void hold_state(const BaseMaterial& material, bool at_rest);
  // Full quasi-static simulation with `material` everywhere; its positions become the state.
  Status simulate_full(const BaseMaterial& material);
  const MatrixX3d& state() const { return state_; }
  // Strain features of every element at the state (after simulate_full or hold_state).
  const std::vector<Eigen::VectorXd>& features() const { return features_; }

  // Measured coordinates minus targets (m) of the linear co-rotational solve at the held state.
  Status residual(const BaseMaterial& material, Eigen::VectorXd* r);
  // d(measured coordinates)/d(centre values), rows as residual(), columns centre-major
  // (j |p| + k for value k of centre j), at the last residual()'s solution.
  Status jacobian(const BaseMaterial& material, Eigen::MatrixXd* j);

  // (u . u, u . ubar) for the linear displacements u under `unit` at rest and the measured ones.
  Result<std::pair<double, double>> unit_displacement_dots(const BaseMaterial& unit);
  // All known nodal forces parallel to their sum (within `tolerance` relative).
  bool forces_parallel(double tolerance) const;
  // Sec. 5.4: probed nodes held at their measured positions under `material`; the reactions'
  // components perpendicular to the measured force are added to the known forces.
  Status recover_tangential_forces(const BaseMaterial& material);

  // RMS node distance of the states to the measurements over all examples.
  static double rms_error(const std::vector<FitExample>& examples);

 private:
  FitExample(const material::Samples* samples, std::size_t index, BaseModel model,
             ForwardOptions forward, fem::CorotationalFem fem)
      : samples_(samples), index_(index), model_(model), forward_(forward), fem_(std::move(fem)) {}
  const material::Example& example() const { return samples_->examples[index_]; }
  void set_material(const BaseMaterial& material);

  const material::Samples* samples_;
  std::size_t index_;
  BaseModel model_;
  ForwardOptions forward_;
  fem::CorotationalFem fem_;
  MatrixX3d forces_;
  std::vector<int> dofs_;    // measured free dofs
  Eigen::VectorXd target_;   // their measured coordinates
  Eigen::VectorXd rest_;     // their rest coordinates
  MatrixX3d state_;
  std::vector<Eigen::VectorXd> features_;
  Eigen::MatrixXd weights_;  // #T by P at the held state
};

}  // namespace hc::composite
