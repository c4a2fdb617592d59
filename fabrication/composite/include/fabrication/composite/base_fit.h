// Fitting a base material to all of its examples at once (thesis Sec. 5.4, Eq. 5.4):
//
//   w = argmin_w  sum_i || x_i(p, F_i) - xbar_i ||^2
//
// over the P parameter vectors p_j at the RBF centres (so |p| P unknowns, 12 isotropic or 60
// transverse at the thesis's P), x_i the positions of example i's visible, non-fixed nodes under
// its nodal forces. The examples may come from several specimens of the same material (e.g. blocks
// of different thickness).
//
// The thesis's procedure, with its steps made explicit:
// 1. A homogeneous linear material (one parameter vector, P = 1) is fitted first (linear solves,
//    rotations at rest), started from the stiffness that best scales a unit material's
//    displacements onto the measured ones.
// 2. Missing tangential probe forces (Sec. 5.4): when an example's known forces are all parallel
//    (normal forces from a force sensor), its probed nodes are held at their measured positions
//    in a simulation with the current material, and the components of the reactions there that
//    are perpendicular to the measured force are added to the known forces.
// 3. Passes: simulate every example with the current material (quasi-static, self-consistent
//    incremental loading, processing/fem), record the element strains, place the P centres over
//    their range (the zero strain, then farthest-point sampling of the strain features, leaving
//    out the farthest 1 % as outliers), and fit the centre values by Levenberg-Marquardt with the
//    rotations and the strains (hence the RBF weights of each element) held at the simulated
//    state: each residual evaluation is one linear co-rotational solve per example and the
//    Jacobian is Appendix A's (Eq. A.2) through the RBF weights, dx/dp_jk = -K^-1 sum_e l_j(e)
//    [R_e V_e B_e^T (dE/dp_k) B_e (R_e^T x_e - X_e)]_e. After every step the centre values are
//    projected onto the feasible set (base_material.h); the Jacobian ignores the projection.
//    Repeating the passes makes the held state consistent with the fitted material and the centres
//    cover the strains that material produces.
// 4. The errors are reported from full simulations of the final material, per force level as in
//    Table 5.8.1 (average, standard deviation and largest node distance).
#pragma once

#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "fabrication/composite/base_material.h"
#include "fabrication/composite/composite.h"
#include "processing/material/samples.h"

namespace hc::composite {

enum class TangentialForces {
  kAuto,  // recover them for examples whose known forces are all parallel
  kOn,    // for every example (also when its forces already have tangential parts)
  kOff,
};

struct BaseFitOptions {
  BaseModel model = BaseModel::kIsotropic;
  int centres = 0;         // P; 0: default_centres(model)
  int passes = 3;          // strain-coverage passes after the homogeneous fit (>= 1)
  int max_iterations = 25;  // Levenberg-Marquardt iterations per pass
  double function_tolerance = 1e-7;  // stop when an accepted step lowers the cost by less (rel.)
  TangentialForces tangential = TangentialForces::kAuto;
  // Fraction of the largest strain features left out when placing centres (outliers: a few
  // elements right under a probe).
  double outlier_fraction = 0.01;
  // Feasibility: the modulus floor relative to the homogeneous fit's Young's modulus (isotropic)
  // or its smallest invariant stiffness (transverse); the Poisson's ratio range.
  double min_modulus_fraction = 1e-3;
  double min_poisson = -0.9;
  double max_poisson = 0.49;
  ForwardOptions forward;  // the full simulations
  ProgressReporter* progress = nullptr;

  Status validate() const;
};

// One row of Table 5.8.1: the examples at one force level (total force magnitudes within 5 % of
// each other) and the node distances over their visible, non-fixed nodes.
struct ForceLevelError {
  double force_n = 0;  // mean total force of the level's examples
  int examples = 0;
  Eigen::Index nodes = 0;
  double avg_m = 0;
  double std_m = 0;
  double max_m = 0;
};

struct BaseFitSummary {
  double rms_error_m = 0;  // over all measured nodes of all examples, full simulation
  double max_error_m = 0;
  std::vector<ForceLevelError> levels;
  int centres = 0;
  int passes = 0;
  int iterations = 0;                // LM iterations over all passes
  int tangential_examples = 0;       // examples whose tangential forces were recovered
  double homogeneous_rms_error_m = 0;  // the homogeneous linear material's (full simulation)
  std::vector<double> pass_rms_error_m;  // after each pass (full simulation)
  Eigen::VectorXd homogeneous;       // its parameter vector (Pa)
  double time_s = 0;
};

// Fits one base material to the examples of all `samples` (non-empty, each validated).
// invalid_argument for bad options or samples without usable examples (no fixed node, nothing
// measured, no force); failed_precondition when a simulation finds no equilibrium.
Result<BaseMaterial> fit_base_material(const std::vector<const material::Samples*>& samples,
                                       const BaseFitOptions& options,
                                       BaseFitSummary* summary = nullptr);

// The error table of a material on samples (e.g. a thicker or thinner block than it was fitted
// on): full simulations with `material` in every element.
struct BaseEvaluation {
  double rms_error_m = 0;
  double max_error_m = 0;
  double max_displacement_m = 0;
  std::vector<ForceLevelError> levels;
  std::vector<MatrixX3d> positions;
};
Result<BaseEvaluation> evaluate_base_material(const BaseMaterial& material,
                                              const material::Samples& samples,
                                              const ForwardOptions& options = {});

// Groups examples by total force and computes the Table 5.8.1 rows from simulated positions (one
// matrix per example of `samples`).
std::vector<ForceLevelError> force_level_errors(const material::Samples& samples,
                                                const std::vector<MatrixX3d>& positions);

}  // namespace hc::composite
