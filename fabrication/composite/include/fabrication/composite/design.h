// Goal-driven composite design (thesis Sec. 5.5): the assignment of base materials to cells whose
// simulated displacements under the target's forces are closest (RMS node distance) to the
// target's measured ones.
//
// Two searches over the screen (screen.h), both finished by full simulations (composite.h):
// * kBranchAndBound, the thesis's (Sec. 5.5.2-5.5.4): a breadth-first decision tree over the cells
//   (top cell first: nearest the probe, largest effect), every node bounded by the axis-aligned box
//   of its M uniform completions' displacements (culled when the target is farther from that box
//   than the best error so far), every level clustered by K-means on Eq. 5.5's distance before it
//   is split (the representative: the member nearest its cluster's centroid). The best screened
//   designs are then simulated in full. The thesis's bounds are not conservative and the
//   clustering can drop the optimum, so this search promises nothing.
// * kExact: every design is screened (M^N of them, refused above max_designs), and designs are
//   then simulated in full in order of their screened error until no design that is left can beat
//   the best simulated one: with delta the largest |screened - simulated| error seen so far (at
//   least min_simulated designs), a design with screened error s has simulated error >= s - kappa
//   delta. The answer is certified either because its simulated error is zero to the solver's
//   tolerance (no design can do better, e.g. a target simulated from the base models), or by that
//   screen bound (kappa = margin). It is a bound measured on the simulated designs, not proven for
//   every design; the report says which certificate holds and the remaining gap when the budget
//   of full simulations ends first.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "fabrication/composite/composite.h"
#include "fabrication/composite/screen.h"
#include "processing/material/samples.h"

namespace hc::composite {

enum class SearchMode { kBranchAndBound, kExact };

struct SearchOptions {
  SearchMode mode = SearchMode::kBranchAndBound;
  int clusters = 20;           // K of the thesis's K-means per level (Sec. 5.5.4)
  int simulate_best = 3;       // B&B: the best screened designs simulated in full
  double margin = 2.0;         // exact: kappa
  int min_simulated = 8;       // exact: full simulations before the screen bound is trusted
  int max_simulated = 400;     // exact: budget of full simulations
  double max_designs = 2e6;    // exact: largest M^N enumerated
  // Exact: a simulated error at or below this (m) certifies by itself; 0: 1e-9 x the target's
  // largest displacement (the forward solver's tolerance is 1e-6 of the specimen's size).
  double zero_error_m = 0;
  ProgressReporter* progress = nullptr;
  Status validate() const;
};

struct DesignResult {
  std::vector<int> design;           // material index per cell (cell order: bottom first)
  double rms_error_m = 0;            // full simulation
  double screen_error_m = 0;
  long long designs_screened = 0;    // screen evaluations
  int designs_simulated = 0;         // full simulations
  bool certified = false;
  std::string certificate = "none";  // "zero_error", "screen_bound", "exhaustive" or "none"
  double gap_m = 0;                  // best - (lowest lower bound of the designs not simulated)
  double screen_bound_m = 0;         // kappa delta
  double max_screen_discrepancy_m = 0;  // delta
  double search_time_s = 0;
  double simulate_time_s = 0;        // spent in full simulations
  double time_s = 0;
};

class CompositeDesigner {
 public:
  // `target`: the specimen (its mesh), the examples' forces and fixed nodes and the measured
  // positions; `grid`: the cells (over the specimen's box); `library`: the base materials.
  static Result<CompositeDesigner> create(const material::Samples& target, const CellGrid& grid,
                                          std::vector<BaseMaterial> library,
                                          const ScreenOptions& screen = {});
  CompositeDesigner(CompositeDesigner&&) noexcept;
  CompositeDesigner& operator=(CompositeDesigner&&) noexcept;
  ~CompositeDesigner();

  // Replaces the measured positions (same specimen, forces, fixed and visible nodes).
  Status set_target(const material::Samples& target);
  Result<DesignResult> search(const SearchOptions& options);
  // Thickness as a design variable (the thesis varied layer thicknesses): the designer's cells must
  // be a stack of S sublayers; searches `layers` layers, each one material over a whole number of
  // sublayers (at least one), the same searches over (material, thickness) decisions, top layer
  // first. The result's design is per sublayer (runs of one material form a layer).
  // Exact mode enumerates C(S - 1, layers - 1) M^layers designs (screened one by one).
  Result<DesignResult> search_layers(int layers, const SearchOptions& options);

  const Screen& screen() const;
  const CellGrid& grid() const;
  // Full simulation of a design: positions per example, and the RMS error against the target.
  Result<std::vector<MatrixX3d>> simulate(const std::vector<int>& design, double* rms_m = nullptr);
  double setup_time_s() const;

 private:
  struct Impl;
  explicit CompositeDesigner(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The cells in the order the searches decide them: top layer first (then y, then x descending).
std::vector<int> search_order(const CellGrid& grid);

}  // namespace hc::composite
