// Composites of base materials (thesis Sec. 5.3.2, 5.5.1, 5.9.2): the specimen's bounding box cut
// into regular cells, layers along z (any thicknesses) or NX x NY x NZ voxels, each cell filled with
// one base material, and the quasi-static FEM of Sec. 5.3.2 on such an assignment: every element
// takes the base material of the cell its centroid lies in, and at each load increment its
// parameters follow its own strain (processing/fem incremental loading).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "common/status.h"
#include "common/tet_mesh.h"
#include "fabrication/composite/base_material.h"
#include "processing/fem/corotational.h"
#include "processing/fem/material_model.h"
#include "processing/material/samples.h"

namespace hc::composite {

// A regular partition of a box. Cells are numbered x fastest, then y, then z, so layers are
// numbered bottom first.
class CellGrid {
 public:
  // `thickness_m` (bottom first, each > 0) must add up to the box's height within 1e-6 of it.
  static Result<CellGrid> layers(const Eigen::AlignedBox3d& box,
                                 const std::vector<double>& thickness_m);
  static Result<CellGrid> equal_layers(const Eigen::AlignedBox3d& box, int count);
  static Result<CellGrid> voxels(const Eigen::AlignedBox3d& box, const Eigen::Vector3i& counts);
  // From boundary coordinates per axis (each strictly increasing, >= 2 values).
  static Result<CellGrid> from_boundaries(std::vector<double> x_m, std::vector<double> y_m,
                                          std::vector<double> z_m);

  int num_cells() const;
  Eigen::Vector3i counts() const;
  bool is_layers() const { return x_m_.size() == 2 && y_m_.size() == 2; }
  const std::vector<double>& x_m() const { return x_m_; }
  const std::vector<double>& y_m() const { return y_m_; }
  const std::vector<double>& z_m() const { return z_m_; }
  Eigen::AlignedBox3d box() const;
  Eigen::AlignedBox3d cell_box(int cell) const;
  // The cell holding point p (points on or outside the boundary go to the nearest cell).
  int cell_of(const Eigen::Vector3d& p) const;

 private:
  std::vector<double> x_m_, y_m_, z_m_;
};

// The cell of each tet (by centroid).
std::vector<int> element_cells(const TetMesh& mesh, const CellGrid& grid);

// The axis-aligned box of a mesh's nodes.
Eigen::AlignedBox3d mesh_box(const TetMesh& mesh);

// Per element one base material (pointers into a library that must outlive the model). Anisotropic
// when any of them is transversely isotropic.
class CompositeMaterial final : public fem::MaterialModel {
 public:
  CompositeMaterial(std::vector<const BaseMaterial*> per_element);
  fem::LambdaAlpha params(Eigen::Index element, const Vector6d& strain) const override;
  Matrix6d elasticity(Eigen::Index element, const Vector6d& strain) const override;
  bool anisotropic() const override { return anisotropic_; }
  Eigen::Index num_elements() const override {
    return static_cast<Eigen::Index>(per_element_.size());
  }

 private:
  std::vector<const BaseMaterial*> per_element_;
  bool anisotropic_ = false;
};

// The composite of `design` (one index into `library` per cell of `cells`, whose size is the cell
// count) on a mesh whose elements lie in `element_cell` (element_cells()).
// invalid_argument on a size mismatch or an index out of range.
Result<CompositeMaterial> make_composite(const std::vector<BaseMaterial>& library,
                                         const std::vector<int>& element_cell,
                                         const std::vector<int>& design, int num_cells);
// The composite points into `library`: a temporary library would leave it dangling.
Result<CompositeMaterial> make_composite(std::vector<BaseMaterial>&& library,
                                         const std::vector<int>& element_cell,
                                         const std::vector<int>& design, int num_cells) = delete;

// Options of the quasi-static simulation of Sec. 5.3.2 under an example's nodal forces.
struct ForwardOptions {
  int steps = 4;  // load increments; parameters follow the strain within each (self-consistent)
  // processing/fem's position tolerance relative to the specimen's size (1e-5 of a 5 cm block is
  // 0.5 nm; 1e-6 took ~2x the iterations for no visible change in errors of micrometres).
  double tolerance_rel = 1e-5;
  int max_iterations = 100;     // equilibrium iterations per increment
  Status validate() const;
};

// The full model for one example: `fem` (built with the example's fixed nodes) loaded by the
// nodal forces (#N by 3) in options.steps increments, parameters self-consistent with the strain in
// each (processing/fem's run_incremental_forces); fem holds the deformed positions afterwards.
Status simulate_forces(fem::CorotationalFem* fem, const fem::MaterialModel& material,
                       const MatrixX3d& forces, const ForwardOptions& options);
// An example's applied forces as #N by 3.
MatrixX3d example_forces(const material::Example& example, Eigen::Index num_nodes);

// The error of simulated positions against an example's measurements: over its visible nodes that
// are not fixed, the sum of squared node distances (m^2), the count and the largest distance.
struct ExampleError {
  double sum_sq_m2 = 0;
  Eigen::Index nodes = 0;
  double max_m = 0;
};
ExampleError example_error(const material::Example& example, const MatrixX3d& positions);

// Simulates every example of `samples` with `material` (its forces, its fixed nodes). One FEM per
// example is built once and reused across calls (the symbolic factorisation is the costly part),
// so a simulator is for one thread at a time.
class ExampleSimulator {
 public:
  static Result<ExampleSimulator> create(const material::Samples& samples,
                                         const ForwardOptions& options);
  ExampleSimulator(ExampleSimulator&&) noexcept;
  ExampleSimulator& operator=(ExampleSimulator&&) noexcept;
  ~ExampleSimulator();

  std::size_t num_examples() const;
  // Deformed positions of example i (#N by 3). failed_precondition when no equilibrium is found.
  Result<MatrixX3d> simulate(std::size_t i, const fem::MaterialModel& material);
  // All examples; their RMS node distance to the measurements (m) in *rms_m when not null.
  Result<std::vector<MatrixX3d>> simulate_all(const fem::MaterialModel& material,
                                              double* rms_m = nullptr);

 private:
  struct Impl;
  explicit ExampleSimulator(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::composite
