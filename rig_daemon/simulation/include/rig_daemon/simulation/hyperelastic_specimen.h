// A FEM-backed virtual specimen: a block of compressible, strain-stiffening neo-Hookean material
// (processing/hyperelastic, the reference model, which differs from the fitter's co-rotational
// data-driven model), fixed at its bottom and indented from above by the rigid spherical probe.
//
// Each probe location is solved once, lazily, by hyperelastic::reference_indentation (the one
// "indent the reference block" that `hardcopy simulate`, `synth` and the tests use, with the
// co-rotational FEM's contact rule) in depth steps up to max_depth_m; force and marker positions
// are interpolated linearly in depth between the steps. Locations snap to a grid of
// `location_grid_m` (the probe centre is within half a grid cell of where it is); the first query
// at a new location blocks while it is solved (about a second on a coarse mesh), so plans should
// revisit a few locations. Markers are the top-surface nodes of a structured mesh whose top grid
// spacing is the marker spacing (3 mm, thesis 5.6).
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "common/config.h"
#include "common/status.h"
#include "rig_daemon/simulation/specimen.h"

namespace hc::devices::sim {

// One layer of a layered specimen (thesis Ch. 5's stacked composites; a "hidden" layered material
// the whole-loop demo captures and designs for), bottom first.
struct MaterialLayer {
  double thickness_m = 0.01;
  double youngs_modulus_pa = 1.0e6;
  double poisson_ratio = 0.45;
  double stiffening = 1.0;
  Status read(ConfigNode node);
};

struct HyperelasticSpecimenOptions {
  double youngs_modulus_pa = 1.0e6;
  double poisson_ratio = 0.45;
  double stiffening = 1.0;  // neo-Hookean β (hidden non-linearity)
  double top_z_m = 0.05;
  Eigen::Vector2d center_m{0.0, 0.0};
  Eigen::Vector2d size_m{0.06, 0.06};
  double height_m = 0.03;
  double marker_spacing_m = 0.003;  // = top mesh spacing
  int layers = 6;                   // cells through the height
  double marker_radius_m = 0.0006;
  double probe_radius_m = 0.005;
  double max_depth_m = 0.006;
  int depth_steps = 12;
  double location_grid_m = 0.003;
  // Bottom first; their thicknesses add up to height_m and each is a whole number of the mesh's
  // cells through the height (height_m / layers). Empty: one material (the three keys above).
  std::vector<MaterialLayer> material_layers;
  Status validate() const;
};

class HyperelasticSpecimen final : public Specimen {
 public:
  // Builds the mesh and model (no solve yet). Fails on invalid options or a failed mesh build.
  static Result<std::shared_ptr<HyperelasticSpecimen>> create(
      const HyperelasticSpecimenOptions& options);
  ~HyperelasticSpecimen() override;

  std::string name() const override { return "hyperelastic"; }
  double top_z_m() const override { return options_.top_z_m; }
  Eigen::AlignedBox2d footprint() const override;
  double force_n(const Indentation& indentation) const override;
  Eigen::Vector3d displacement(const Eigen::Vector3d& rest_point,
                               const Indentation& indentation) const override;
  const std::vector<Eigen::Vector3d>& rest_markers() const override { return markers_; }
  double marker_radius_m() const override { return options_.marker_radius_m; }
  // Locations solved so far, and whether the last solve converged at every step.
  std::size_t solved_locations() const;
  bool all_converged() const;

 private:
  struct Curve;  // one location: depths, forces, marker positions per step
  class Impl;
  HyperelasticSpecimen() = default;
  // The curve at a grid location (solved on first use, under the lock).
  const Curve* curve_at(double x_m, double y_m) const;
  // Indents the block at (x_m, y_m) (world) with hyperelastic::reference_indentation into *curve;
  // the error when a step found no equilibrium (curve->converged false, the finished steps kept).
  Status solve_curve(double x_m, double y_m, Curve* curve) const;

  HyperelasticSpecimenOptions options_;
  std::vector<Eigen::Vector3d> markers_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::devices::sim
