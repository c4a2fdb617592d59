// Incremental loading with strain-dependent parameters (thesis Sec. 4.2.3-4.2.4): the load (probe
// depth, probe force or nodal forces) is applied in `steps` equal increments; before each increment
// every element's (lambda, alpha) is updated from its current rotated-frame strain through a
// MaterialModel, then the co-rotational contact problem is re-solved.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "processing/fem/contact.h"
#include "processing/fem/corotational.h"
#include "processing/fem/material_model.h"
#include "processing/fem/probe.h"

namespace hc::fem {

struct IncrementalOptions {
  int steps = 10;
  ContactOptions contact;
  // Also update parameters inside each step's equilibrium iterations (self-consistent p(eps) at the
  // end of every step) rather than only at its start (the thesis's explicit incremental scheme).
  bool update_within_step = false;
  // Reports the load steps of probe loading (optional).
  ProgressReporter* progress = nullptr;

  Status validate() const;
};

struct LoadStep {
  double depth_m = 0;  // probe travel beyond first contact (0 for nodal-force loading)
  double force_n = 0;  // total contact force along the probe direction, or |sum of nodal forces|
  int iterations = 0;
};

struct IncrementalSummary {
  std::vector<LoadStep> steps;
  double max_displacement_m = 0;
  int total_iterations = 0;
  double time_s = 0;
  // false when a load step ended at contact.max_iterations without reaching the tolerance (nodal-
  // force loading only; probe loading fails instead).
  bool converged = false;
};

// Sets every element's parameters from its current strain (fem.strains() after update_rotations()),
// and for an anisotropic() model its elasticity matrix (CorotationalFem::set_elasticity).
void update_params_from_strain(CorotationalFem* fem, const MaterialModel& material);

// One incremental step exactly as benchmarked: update rotations, update parameters from the current
// strains, assemble, numeric factorisation, solve under nodal forces (#N by 3).
Status incremental_step(CorotationalFem* fem, const MaterialModel& material,
                        const MatrixX3d& forces);

// Probe loading in options.steps increments of `load`. fem's positions are reset to the rest shape
// first. On success fem holds the final deformed positions and parameters.
Status run_incremental(CorotationalFem* fem, const MaterialModel& material, const Probe& probe,
                       const Load& load, const IncrementalOptions& options,
                       IncrementalSummary* summary);

// Nodal-force loading: step k applies (k / steps) * forces and iterates rotations (and, with
// update_within_step, parameters; under-relaxed when the iteration oscillates) to equilibrium.
Status run_incremental_forces(CorotationalFem* fem, const MaterialModel& material,
                              const MatrixX3d& forces, const IncrementalOptions& options,
                              IncrementalSummary* summary);

}  // namespace hc::fem
