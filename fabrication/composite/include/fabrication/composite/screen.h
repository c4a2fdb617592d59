// The fast forward model of the design search ("screen"): per example, a linear model with each
// cell's material frozen at the secant stiffness it has in the uniform block of that material
// (the thesis's "extreme behaviours", Sec. 5.5.3) under the example's forces, reduced by Galerkin
// projection onto a small per-example basis (POD of linear solves of snapshot designs: the uniform
// blocks, every cell in turn with every material in a middle-stiffness block, and random designs).
//
// Per example i, cell c and material m the r x r matrix A_icm = V_i^T K_icm V_i is computed once;
// a design m then costs, per example, the sum of its cells' matrices, one r x r Cholesky
// factorisation and a few r x r products for the error against the target, instead of a sparse
// non-linear simulation. Designs that share their first cells (in search order) share the partial
// sums (screen_all, enumerate).
//
// The screen is an approximation of the full model (composite.h): it ignores how the strains, and
// with them the secant stiffness, of a cell change when its neighbours change, and the rotations.
// The design search re-simulates its candidates with the full model and measures the difference.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "fabrication/composite/base_material.h"
#include "fabrication/composite/composite.h"
#include "processing/material/samples.h"

namespace hc::composite {

struct ScreenOptions {
  // Modes kept: singular values of the snapshot matrix down to this fraction of the largest.
  // 1e-3 keeps ~20 modes on the thesis's block with a screen error of a few micrometres against
  // millimetre displacements (5 layers x 9 materials x 5 examples).
  double basis_tolerance = 1e-3;
  int max_basis = 40;           // per example
  int random_snapshots = 0;     // 0: max(10, cells)
  std::uint64_t seed = 1;       // random snapshot designs
  ForwardOptions forward;       // the uniform blocks' full simulations
  ProgressReporter* progress = nullptr;
  Status validate() const;
};

class Screen {
 public:
  // `samples` gives the mesh, the examples' forces and fixed nodes and the targets; the cells'
  // element sets come from `grid`. Runs M x examples full simulations (the uniform blocks) and the
  // snapshot solves.
  static Result<Screen> create(const material::Samples& samples, const CellGrid& grid,
                               const std::vector<BaseMaterial>& library,
                               const ScreenOptions& options = {});
  Screen(Screen&&) noexcept;
  Screen& operator=(Screen&&) noexcept;
  ~Screen();

  int num_cells() const;
  int num_materials() const;
  std::size_t num_examples() const;
  Eigen::Index basis_size(std::size_t example) const;
  Eigen::Index measured_coordinates() const;  // over all examples
  Eigen::Index measured_nodes() const;

  // Replaces the targets (positions and visibility) by those of `samples`, which must have the same
  // mesh, examples, forces and fixed nodes. invalid_argument otherwise.
  Status set_target(const material::Samples& samples);

  // RMS node distance (m) of a design's screened positions to the target (design: one material
  // index per cell, in cell order).
  double error(const std::vector<int>& design) const;
  // The screened displacements at the measured coordinates (all examples, stacked) and the target
  // displacements there.
  Eigen::VectorXd displacements(const std::vector<int>& design) const;
  const Eigen::VectorXd& target_displacements() const;
  // One evaluation giving the error (m, RMS), the displacements z at the measured coordinates and
  // short coordinates w with |w_a - w_b| = |z_a - z_b| for any two designs (w_i = L_i^T y_i with
  // P_i^T P_i = L_i L_i^T per example): Eq. 5.5's distances at a fraction of the length. Any
  // output may be null.
  void evaluate(const std::vector<int>& design, double* error, Eigen::VectorXd* z,
                Eigen::VectorXd* w) const;

  // Visits every design (M^N) by depth-first enumeration over `order` (a permutation of the cells;
  // the first ones vary slowest), sharing the partial sums; calls visit(design, error) for each.
  // Parallel over the first cell's materials (visit must be thread-safe).
  void enumerate(const std::vector<int>& order,
                 const std::function<void(const std::vector<int>&, double)>& visit) const;

  // Setup time (s): the uniform full simulations and the snapshot solves.
  double setup_time_s() const;

 private:
  struct Impl;
  explicit Screen(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::composite
