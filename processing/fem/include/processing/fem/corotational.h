// Linear co-rotational FEM on linear tetrahedra with the (lambda, alpha) parameterisation of thesis
// Sec. 4.2.2 (Eqs. 4.1-4.8) and the warped stiffness of Mueller & Gross 2004.
//
// Conventions (used by every other processing library):
// * Strain and stress are 6-vectors in the order of Eq. 4.1: (xx, yy, zz, xy, xz, yz). The shear
// entries
//   of the STRAIN are engineering shears (gamma_xy = 2 eps_xy = du_x/dy + du_y/dx): that is the
//   convention under which sigma = E eps with E = lambda G + alpha H (Eqs. 4.3-4.6) reproduces
//   isotropic Hooke's law (the shear entry 0.5 lambda - alpha equals the shear modulus mu).
// * Per element e: E_e = lambda_e G + alpha_e H, K_e = lambda_e V_e B_e^T G B_e + alpha_e V_e B_e^T
// H B_e
//   (Eq. 4.8), where B_e (6 x 12) maps the element's 12 nodal displacements (node-major: x0 y0 z0
//   x1 ...) to the strain 6-vector and V_e is the rest volume. lambda = E / ((1+nu)(1-2nu)), alpha
//   = lambda nu (Eq. 4.7); see material_model.h for conversions.
// * The global stiffness is K = sum_e [R_e K_e R_e^T]_e, and the rest-shape term
//   K' x0 = sum_e [R_e K_e X_e]_e (Appendix A, Eq. A.1), so equilibrium under external nodal forces
//   F is K x = F + K' x0 with x the deformed positions. The elastic force on the nodes of e is f_e
//   = -R_e K_e (R_e^T x_e - X_e).
// * Fixed nodes are eliminated: unknowns are the free nodes' coordinates, numbered node-major
//   (dof(node, axis)); a fixed node keeps its prescribed position (its rest position unless
//   set_positions() moved it), and its coupling moves to the right-hand side.
// * R_e is the rotation of the polar decomposition F_e = R_e S_e of the deformation gradient
//   F_e = D_s D_m^{-1}; the rotated-frame strain is eps_e = B_e (R_e^T x_e - X_e) (zero for any
//   rigid motion of the rest shape).
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/fem/sparse_cholesky.h"

namespace hc::fem {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;
using Matrix6x12d = Eigen::Matrix<double, 6, 12>;
using Vector12d = Eigen::Matrix<double, 12, 1>;
// The four shape-function gradients of a linear tet (row a = grad N_a, 1/m); they sum to zero.
using Matrix43d = Eigen::Matrix<double, 4, 3>;

// The per-element material parameters of Eq. 4.6, both in Pa.
struct LambdaAlpha {
  double lambda = 0;
  double alpha = 0;
};

// G = diag(1,1,1,0.5,0.5,0.5) (Eq. 4.4) and H (Eq. 4.5).
const Matrix6d& g_matrix();
const Matrix6d& h_matrix();
// E = lambda G + alpha H (Eq. 4.6).
Matrix6d elasticity_matrix(const LambdaAlpha& p);

// Rotation of the polar decomposition F = R S (R proper orthogonal, det R = +1). Uses the iterative
// method of Mueller et al. 2016 ("A robust method to extract the rotational part of deformations"),
// warm-started from `*q` (updated in place), which is robust for degenerate and inverted F.
Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& f, Eigen::Quaterniond* q,
                               int max_iterations = 30);
// Same, starting from the identity.
Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d& f);

struct CorotationalOptions {
  // false: plain linear FEM (R_e = I always), e.g. for small-strain verification.
  bool corotational = true;
  // Elements whose rest volume is below this fraction of the mean |volume| are "degenerate"
  // (error).
  double min_relative_volume = 1e-10;
  int polar_max_iterations = 30;

  Status validate() const;
};

class CorotationalFem {
 public:
  // Checks the mesh (finite coordinates, node indices in range, every element positively oriented
  // and not degenerate: an inverted or flat element is an invalid_argument naming the element), the
  // fixed nodes (in range; at least one fixed node is NOT required here, but factorize() then fails
  // for a free body), precomputes B_e, V_e, the sparsity pattern of K over the free dofs and the
  // scatter map from element blocks into its CSC values, and analyses the pattern symbolically
  // (once). Parameters start at zero: call set_params() before assemble().
  static Result<CorotationalFem> create(const TetMesh& mesh, const std::vector<int>& fixed_nodes,
                                        const CorotationalOptions& options = {});

  CorotationalFem(CorotationalFem&&) noexcept;
  CorotationalFem& operator=(CorotationalFem&&) noexcept;
  ~CorotationalFem();

  // ---- Mesh, dofs -------------------------------------------------------------------------------
  const TetMesh& mesh() const;
  Eigen::Index num_nodes() const;
  Eigen::Index num_elements() const;
  Eigen::Index num_free_dofs() const;
  bool is_fixed(Eigen::Index node) const;
  const std::vector<int>& fixed_nodes() const;  // sorted, unique
  // Index of (node, axis) among the unknowns, or -1 when the node is fixed.
  int dof(Eigen::Index node, int axis) const;
  // The 12 dof indices of element e (node-major, -1 for fixed nodes).
  std::array<int, 12> element_dofs(Eigen::Index e) const;

  // ---- Per-element rest quantities
  // ---------------------------------------------------------------
  double volume(Eigen::Index e) const;  // V_e in m^3
  const Matrix43d& shape_gradients(Eigen::Index e) const;
  Matrix6x12d b_matrix(Eigen::Index e) const;         // B_e (engineering shear rows)
  Matrix12d stiffness_g(Eigen::Index e) const;        // V_e B_e^T G B_e  (= dK_e / dlambda_e)
  Matrix12d stiffness_h(Eigen::Index e) const;        // V_e B_e^T H B_e  (= dK_e / dalpha_e)
  Matrix12d element_stiffness(Eigen::Index e) const;  // K_e at the current parameters (Eq. 4.8)
  Vector12d rest_positions(Eigen::Index e) const;     // X_e (node-major)
  Vector12d current_positions(Eigen::Index e) const;  // x_e (node-major)

  // ---- State: parameters, positions, rotations
  // ----------------------------------------------------- One (lambda, alpha) per element (size
  // num_elements()); invalid_argument on a size mismatch or a non-finite value. The parameters need
  // not be physically valid here (the fitter explores), but factorize() fails when K is then not
  // positive definite.
  Status set_params(const std::vector<LambdaAlpha>& params);
  void set_uniform_params(const LambdaAlpha& p);
  const std::vector<LambdaAlpha>& params() const;

  // Anisotropic elements (the transversely isotropic base materials of thesis Eq. 5.6): one
  // symmetric 6x6 elasticity matrix E_e per element (Eq. 4.1 order, engineering shears) that
  // replaces (lambda, alpha) in assembly, elastic forces and element_stiffness(): K_e = V_e B_e^T
  // E_e B_e. Size num_elements(); invalid_argument on a size mismatch or a non-finite or
  // non-symmetric matrix (naming the element). clear_elasticity() goes back to (lambda, alpha).
  Status set_elasticity(std::vector<Matrix6d> elasticity);
  void clear_elasticity();
  bool has_elasticity() const;
  // E_e in use: the per-element matrix when set, else elasticity_matrix(params()[e]).
  Matrix6d element_elasticity(Eigen::Index e) const;

  // Current positions (#N by 3, metres). Fixed nodes' rows are their prescribed positions (e.g. a
  // linear displacement boundary condition); free rows are the initial guess / last solution.
  Status set_positions(const MatrixX3d& x);
  const MatrixX3d& positions() const;
  MatrixX3d displacements() const;  // positions() - rest positions

  // R_e from the current positions (polar decomposition, warm-started); identity for all elements
  // when options.corotational is false.
  void update_rotations();
  const Eigen::Matrix3d& rotation(Eigen::Index e) const;
  void set_rotations_identity();

  // Rotated-frame strain of element e at the current positions and rotation: B_e (R_e^T x_e - X_e).
  Vector6d strain(Eigen::Index e) const;
  // All of them, #T by 6.
  Eigen::Matrix<double, Eigen::Dynamic, 6> strains() const;

  // ---- Assembly and solve
  // ------------------------------------------------------------------------ Assembles K (upper
  // triangle, free dofs) from the current rotations and parameters by the precomputed scatter map,
  // and the right-hand side K' x0 - K_free,fixed x_fixed.
  void assemble();
  // The assembled K: upper triangle, CSC, fixed pattern (the pattern never changes).
  const SparseMatrix& stiffness() const;
  // Adds a 3x3 block to the diagonal block of a FREE node in the assembled K (contact penalties);
  // the block must be symmetric. No-op for fixed nodes. Valid until the next assemble().
  void add_to_node_block(Eigen::Index node, const Eigen::Matrix3d& block);
  // Adds `block` to K's block (node a, node b) of element e's local nodes a, b (0..3) and its
  // transpose to (b, a), i.e. the symmetric coupling of two nodes of one element (contact points
  // on a boundary triangle). a == b adds to the node's own block (which must then be symmetric).
  // No-op when either node is fixed. Valid until the next assemble().
  void add_to_element_block(Eigen::Index e, int a, int b, const Eigen::Matrix3d& block);
  // Right-hand side without external forces (length num_free_dofs()).
  const Eigen::VectorXd& rest_rhs() const;

  // Numeric Cholesky factorisation of the assembled K (symbolic analysis was done by create()).
  // failed_precondition when K is not positive definite (e.g. no fixed nodes, or invalid
  // parameters).
  Status factorize();
  const SparseCholesky& cholesky() const;

  // Solves K x = F + rhs with the current factorisation; F is #N by 3 external nodal forces in N
  // (rows of fixed nodes ignored). Writes the free nodes' positions into positions() (fixed rows
  // unchanged).
  Status solve(const MatrixX3d& external_forces);
  // Same with an extra right-hand side on the free dofs (length num_free_dofs(); e.g. contact
  // targets).
  Status solve(const MatrixX3d& external_forces, const Eigen::VectorXd& extra_rhs);

  // Conjugate gradients for the system of solve(zero forces, extra_rhs) with the assembled K's
  // current values, preconditioned by the last factorisation (of an earlier K of this model:
  // between equilibrium iterations the rotations and contact terms change K little, and a few
  // iterations, each a product with K and one solve with the factor, cost less than a numeric
  // factorisation), starting from the current positions.
  struct PcgOptions {
    int max_iterations = 20;
    // Converged when the preconditioned residual norm is below this times its value at the start.
    double relative_tolerance = 1e-6;
    // z = M⁻¹ r for an M close to K on the free dofs; empty = the solve with the factorisation
    // (contact adds its penalties to the factor by a low-rank update).
    std::function<Status(const Eigen::VectorXd& r, Eigen::VectorXd* z)> precondition;
  };
  struct PcgSummary {
    bool converged = false;
    int iterations = 0;
  };
  // When not converged within max_iterations, or there is no factorisation, the positions are
  // unchanged.
  Status solve_preconditioned(const Eigen::VectorXd& extra_rhs, const PcgOptions& options,
                              PcgSummary* summary);

  // One co-rotational static step: update_rotations(), assemble(), factorize(), solve(F).
  Status step(const MatrixX3d& external_forces);
  // Iterates step() until the largest position change is below tolerance_m (or max_iterations).
  // Returns the number of iterations through *iterations when not null.
  Status solve_static(const MatrixX3d& external_forces, int max_iterations, double tolerance_m,
                      int* iterations = nullptr);

  // Elastic nodal forces at the current positions and rotations, #N by 3:
  // f = -sum_e [R_e K_e (R_e^T x_e - X_e)]_e. At equilibrium f + F = 0 at free nodes; rows of fixed
  // nodes are minus the support reactions.
  MatrixX3d elastic_forces() const;

  const CorotationalOptions& options() const;

 private:
  struct Impl;
  explicit CorotationalFem(std::unique_ptr<Impl> impl);
  void assemble_anisotropic();
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::fem
