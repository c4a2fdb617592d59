// Structured (optionally graded) box meshes and the FEM verification table behind `hardcopy
// validate fem`: each case runs the FEM and compares with a closed-form answer from
// ../shared/data/fem/ANALYTIC_BENCHMARKS.md.
//
// The box mesher here is a small Kuhn (6 tets per cell) generator for verification grids; specimens
// for the product come from processing/meshing (TetGen).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "common/status.h"
#include "common/tet_mesh.h"

namespace hc::fem {

// Grid-line coordinates on [lo, hi]: spacing h_min at `focus` (inside [lo, hi]) growing
// geometrically by `growth` (>= 1) away from it, each side's cells stretched to end exactly at lo /
// hi.
std::vector<double> graded_coordinates(double lo, double hi, double focus, double h_min,
                                       double growth);
// Uniform coordinates: cells + 1 values.
std::vector<double> uniform_coordinates(double lo, double hi, int cells);

// Tensor-product grid with every hexahedral cell split into 6 positively oriented tets around its
// main diagonal (Kuhn/Freudenthal; conforming across cells). Node (i, j, k) has index i + nx (j +
// ny k), nx = xs.size() etc.
TetMesh structured_box_mesh(const std::vector<double>& xs, const std::vector<double>& ys,
                            const std::vector<double>& zs);

// Nodes with |coordinate(axis) - value| <= tolerance.
std::vector<int> nodes_on_plane(const TetMesh& mesh, int axis, double value, double tolerance);

struct VerificationCase {
  std::string name;      // "patch", "cantilever", "flat_punch", "sphere"
  std::string quantity;  // what is compared, with unit
  double computed = 0;
  double expected = 0;
  double error_rel =
      0;  // |computed - expected| / |expected| (patch: max position error / max displacement)
  double tolerance = 0;
  bool pass = false;
  std::string source;  // where the expected value comes from
  int level = 0;       // mesh refinement level
  long tets = 0;
  double time_s = 0;
};

// Constant-strain patch test: a box with perturbed interior nodes, all boundary nodes prescribed by
// a linear displacement field; interior nodes must follow it to round-off (linear and
// co-rotational).
Result<VerificationCase> verify_patch(bool corotational);
// Cantilever 100 x 20 x 10 mm, E = 1 MPa, nu = 0.3, tip load 1 mN (small deflection), clamped at x
// = 0; tip deflection vs Timoshenko (Euler-Bernoulli + shear). Level 1..4: (20, 4, 2) x level
// cells.
Result<VerificationCase> verify_cantilever(int level);
// Rigid flat punch, radius a = 2.5 mm, depth 0.01 a, on a 40a x 40a x 20a block (bottom fixed), E =
// 1 MPa, nu = 0.3: force vs Boussinesq F = 2 a E* d. Level 1..4: h_min = a / (2 level).
Result<VerificationCase> verify_flat_punch(int level);
// Rigid sphere R = 10 mm, depth 0.1 mm (a = sqrt(R d) = 1 mm), same block and material: force vs
// Sneddon's exact sphere solution (-> Hertz). Level 1..4: h_min = a / (2 level).
Result<VerificationCase> verify_sphere(int level);

// The table: patch (linear, co-rotational), cantilever, flat punch, sphere at `level`.
std::vector<VerificationCase> run_verification(int level, std::vector<Status>* errors = nullptr);

}  // namespace hc::fem
