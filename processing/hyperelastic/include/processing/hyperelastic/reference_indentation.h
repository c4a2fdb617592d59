// The reference indentation: the neo-Hookean reference model (neo_hookean.h) of a specimen, fixed
// at some nodes, indented by one of processing/fem's rigid probes by depth or by force. The one
// "indent the reference block with a probe" that `hardcopy simulate` (neo-Hookean materials),
// `hardcopy synth`, the material tests and the rig's simulated specimen share, with the contact
// rule of the co-rotational FEM (fem/contact.h): the probe starts at its first contact with the
// specimen's boundary (fem/contact_surface.h: nodes and, on faces coarser than the probe, points on
// the faces, so a probe smaller than the elements cannot pass between nodes), and the penalty
// stiffness of each contact point is penalty_scale times the small-strain stiffness at its nodes,
// per unit of boundary area, as in processing/fem.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "common/status.h"
#include "processing/fem/contact.h"
#include "processing/fem/probe.h"
#include "processing/hyperelastic/neo_hookean.h"

namespace hc::hyperelastic {

struct ReferenceIndentationOptions {
  int steps = 10;  // load increments
  double penalty_scale = fem::ContactOptions{}.penalty_scale;
  fem::ContactSamplingOptions sampling;
  // Keep the positions at the end of every load step (IndentationResult::step_positions_m).
  bool record_steps = false;
  SolveOptions solve;  // Newton per equilibrium (its progress reports Newton iterations)

  Status validate() const;
};

struct IndentationResult {
  MatrixX3d positions_m;          // #N by 3, the final equilibrium
  MatrixX3d contact_forces_n;     // #N by 3, the probe's force on each node there
  double contact_travel_m = 0;    // probe travel from its given pose to first contact
  IndentSummary summary;          // per step depth and force; usable / message
  std::vector<MatrixX3d> step_positions_m;  // with record_steps: one per finished load step
};

// Indents `model` (fixed at `fixed_nodes`) with `probe` (its pose is the start; depth is measured
// from first contact) to `load` in options.steps increments. invalid_argument for bad options, a
// fixed node out of range or a probe whose path misses the specimen (the message says where the
// probe is and where the specimen is). When an increment finds no equilibrium the result is still
// returned, with summary.usable false, the reason in summary.message and the steps that finished.
Result<IndentationResult> reference_indentation(const NeoHookeanModel& model,
                                                const std::vector<int>& fixed_nodes,
                                                const fem::Probe& probe, const fem::Load& load,
                                                const ReferenceIndentationOptions& options = {});

}  // namespace hc::hyperelastic
