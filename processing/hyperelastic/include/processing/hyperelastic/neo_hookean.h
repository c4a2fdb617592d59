// The hyperelastic reference model ("ground-truth physics" for synthetic data and the rig's
// simulated specimen): compressible neo-Hookean tetrahedra (linear shape functions, one material
// per tet), optionally strain-stiffening, solved for static equilibrium by Newton's method with a
// backtracking line search on the total energy.
//
// Energy density per unit rest volume (FEBio's compressible neo-Hookean, see
// ../shared/data/fem/ANALYTIC_BENCHMARKS.md §6), with F the deformation gradient, J = det F and
// I1 = tr(FᵀF):
//   ψ(F) = μ/2 (I1 − 3) − μ ln J + λ/2 (ln J)²  +  β μ/4 (I1 − 3 − 2 ln J)²
// μ = E / (2(1+ν)), λ = E ν / ((1+ν)(1−2ν)). The last term (β ≥ 0, dimensionless, default 0) is a
// strain-stiffening addition: its argument I1 − 3 − 2 ln J is ≥ 0 and quadratic in the strain, so
// the term is quartic and the small-strain limit is linear elasticity with (E, ν) for every β.
//
// Optional transverse isotropy (the tube-structured printed materials of thesis Sec. 5.7.2): a
// fibre term along the unit axis a (default z, the printer's build direction),
//   ψ_f = E_f/8 (I4 − 1)²,   I4 = |F a|²   (the standard reinforcing model, e.g. Bonet & Burton 1998)
// adds E_f to the small-strain axial stiffness C33 and nothing else, stiffens in axial tension and
// softens in axial compression (like tubes that bow); E_f = 0 (default) is the isotropic model.
//
// Units: SI (m, N, Pa, J). Positions are #N by 3 (hc::MatrixX3d) or a stacked 3N vector
// [x0 y0 z0 x1 ...].
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "common/tet_mesh.h"

namespace hc::hyperelastic {

// One isotropic material: Young's modulus E (Pa), Poisson's ratio ν in (−1, 0.5), and the
// stiffening coefficient β ≥ 0 (0: plain neo-Hookean).
struct NeoHookeanMaterial {
  double youngs_pa = 1e6;
  double poisson = 0.3;
  double stiffening = 0.0;
  double fibre_pa = 0.0;  // E_f ≥ 0: axial stiffening along fibre_axis (0: isotropic)
  Eigen::Vector3d fibre_axis = Eigen::Vector3d::UnitZ();  // unit vector (material frame = world)

  double mu_pa() const;      // shear modulus μ = E / (2(1+ν))
  double lambda_pa() const;  // first Lamé parameter λ = Eν / ((1+ν)(1−2ν))
  // Fails with kInvalidArgument naming the bad value (E ≤ 0 or not finite, ν ∉ (−1, 0.5), β < 0,
  // E_f < 0, a fibre axis that is not a finite unit vector).
  Status validate() const;
};

// A layer of a layered specimen: tets whose centroid z lies in [z_min_m, z_max_m) get `material`.
struct MaterialLayer {
  double z_min_m = 0;
  double z_max_m = 0;
  NeoHookeanMaterial material;
};

// Per-tet materials from z-layers (tet centroid decides; the topmost layer also takes centroids
// exactly on its z_max). Fails when a tet's centroid lies in no layer or a material is invalid.
Result<std::vector<NeoHookeanMaterial>> layered_materials(const TetMesh& mesh,
                                                          std::span<const MaterialLayer> layers);

// Energy density ψ(F) (J/m³), first Piola–Kirchhoff stress P = ∂ψ/∂F (Pa) and the 9×9 tangent
// ∂P/∂F (column-major vec(F) ordering: index = 3·col + row). `dP_dF` may be null. Returns +inf
// (and leaves P, dP_dF untouched) when det F ≤ 0.
double neo_hookean_density(const NeoHookeanMaterial& m, const Eigen::Matrix3d& F,
                           Eigen::Matrix3d* P, Eigen::Matrix<double, 9, 9>* dP_dF);

// A rigid obstacle acting on nodes through a penalty potential (contact without friction).
// processing/fem's probes can be adapted to this interface; hyperelastic ships sphere and flat
// cylinder probes (make_sphere_probe, make_flat_probe).
class ContactPotential {
 public:
  virtual ~ContactPotential() = default;
  // Penalty energy (J) of one node at `p` (m); adds its gradient (N) to *grad and its 3×3 Hessian
  // (N/m) to *hess when they are non-null. Zero when the node is outside the obstacle. The default
  // is no contact (for potentials that override energy() instead).
  virtual double node_energy(const Eigen::Vector3d& p, Eigen::Vector3d* grad,
                             Eigen::Matrix3d* hess) const;
  // Penalty energy (J) of the configuration x (3N): adds its gradient (N) to *grad (3N) and the
  // entries of its Hessian (N/m, row/column = DOF) to *hessian when non-null; with `project` the
  // Hessian is made positive semi-definite. The default sums node_energy over the nodes (each
  // node's 3×3 block projected on its own); potentials whose contact points couple several nodes
  // (points on boundary triangles, fem_probe.h) override it.
  virtual double energy(const Eigen::VectorXd& x, Eigen::VectorXd* grad,
                        std::vector<Eigen::Triplet<double>>* hessian, bool project) const;
  // The second-order correction of a Newton step from x to the trial positions *x_try: moves each
  // contact point that is inside the obstacle at x, and that the step's linear model keeps inside,
  // to the penetration that model predicts (s(x) + ∇s(x)·Δ), along the obstacle's normal at
  // x_try. On a curved obstacle a step along the tangent plane lifts a point off by about
  // Δ²/(2ρ), far more than the penetration F/k of a stiff penalty: the next step sees the point
  // free and pulls it deep inside again, and the line search cuts that step to nearly nothing (the
  // Maratos effect). The default does nothing.
  virtual void correct_step(const Eigen::VectorXd& x, Eigen::VectorXd* x_try) const;
};

// A rigid probe moving along a unit `direction` (its axis) from a start pose; `depth_m` is how far
// it has moved. Penetration s (m) of a node gives the penalty energy k/2 s² (so the force is k s
// along the surface normal), k = `stiffness_n_per_m`.
class RigidProbe : public ContactPotential {
 public:
  virtual void set_depth(double depth_m) = 0;
  virtual double depth() const = 0;
  virtual Eigen::Vector3d direction() const = 0;
};

struct ProbeOptions {
  Eigen::Vector3d start_position_m =
      Eigen::Vector3d::Zero();                            // sphere centre / disk centre at depth 0
  Eigen::Vector3d direction = Eigen::Vector3d(0, 0, -1);  // travel direction (normalised)
  double radius_m = 5e-3;
  double stiffness_n_per_m = 1e4;  // penalty stiffness per node
};
// Sphere of radius r centred at start + depth·direction.
std::unique_ptr<RigidProbe> make_sphere_probe(const ProbeOptions& options);
// Flat-ended cylinder (punch) of radius r whose flat face is centred at start + depth·direction,
// face normal = −direction; the cylinder extends backwards (opposite to `direction`) indefinitely.
std::unique_ptr<RigidProbe> make_flat_probe(const ProbeOptions& options);

// The discrete model: rest shape, per-tet materials and precomputed Dm⁻¹ and rest volumes.
class NeoHookeanModel {
 public:
  // Fails when a tet is degenerate or inverted (rest volume ≤ 1e-12 of the bounding-box volume or
  // negative), an index is out of range, the material count is not #T (or 1: used for all), or a
  // material is invalid.
  static Result<NeoHookeanModel> create(const TetMesh& mesh,
                                        std::vector<NeoHookeanMaterial> materials);

  const TetMesh& mesh() const { return mesh_; }
  const std::vector<NeoHookeanMaterial>& materials() const { return materials_; }
  const std::vector<double>& rest_volumes() const { return rest_volumes_; }
  Eigen::Index num_dofs() const { return 3 * mesh_.num_nodes(); }

  // Elastic energy (J) at deformed positions x (3N vector). +inf when any tet is inverted.
  double energy(const Eigen::VectorXd& x) const;
  // Energy, gradient (3N, N) and optionally the sparse Hessian (3N×3N, N/m; exact, may be
  // indefinite when `project_psd` is false; with it every element's 12×12 block is projected onto
  // the positive semi-definite cone). Returns +inf and leaves the outputs undefined when any tet is
  // inverted.
  double energy_gradient_hessian(const Eigen::VectorXd& x, Eigen::VectorXd* gradient,
                                 Eigen::SparseMatrix<double>* hessian,
                                 bool project_psd = false) const;
  // Per-tet deformation gradient F at x.
  Eigen::Matrix3d deformation_gradient(const Eigen::VectorXd& x, Eigen::Index tet) const;

  // Internal (elastic) nodal forces ∂E/∂x (3N, N): at equilibrium, minus the applied loads; at
  // fixed DOFs, minus the support reactions. +inf entries when a tet is inverted.
  Eigen::VectorXd internal_forces(const Eigen::VectorXd& x) const;

  // Rest positions as a 3N vector.
  Eigen::VectorXd rest_positions() const;

 private:
  TetMesh mesh_;
  std::vector<NeoHookeanMaterial> materials_;
  std::vector<double> rest_volumes_;
  std::vector<Eigen::Matrix3d> dm_inv_;
  // The Hessian's sparsity (every element's full 12x12 block), built once, and per tet where each
  // of its 144 entries (a, b, i, j order: row 3a+i, column 3b+j) lands in the value array.
  Eigen::SparseMatrix<double> hessian_pattern_;
  std::vector<int> hessian_slot_;
};

// ---- Static equilibrium ----

struct SolveOptions {
  int max_newton_iterations = 100;
  // Converged when ‖free gradient‖∞ ≤ gradient_tolerance_n + relative_gradient_tolerance · s,
  // with s the load scale: the largest nodal internal force, reaction or applied force (N).
  double gradient_tolerance_n = 1e-9;
  double relative_gradient_tolerance = 1e-8;
  int max_line_search_steps = 40;  // halvings
  double armijo_c = 1e-4;
  ProgressReporter* progress = nullptr;
};
Status validate(const SolveOptions& options);

enum class StopReason { kConverged, kMaxIterations, kLineSearchFailed, kFactorizationFailed };
std::string_view to_string(StopReason reason);

struct NewtonIteration {
  double energy_j = 0;
  double gradient_norm_n = 0;  // ‖free gradient‖∞ at the start of the iteration
  double step_length = 0;      // accepted line-search α
  bool projected = false;      // the exact Hessian was not positive definite: PSD-projected used
};

struct SolveSummary {
  StopReason reason = StopReason::kMaxIterations;
  bool usable() const { return reason == StopReason::kConverged; }
  int iterations = 0;
  double final_energy_j = 0;
  double final_gradient_norm_n = 0;
  std::vector<NewtonIteration> history;
  double time_s = 0;
};

// What is held: nodes fixed at given positions, single fixed DOFs (rollers), nodal external forces
// and rigid obstacles. Nodes that belong to no tet are held fixed too.
struct Boundary {
  std::vector<int> fixed_nodes;       // all three DOFs held at their position in the initial x
  std::vector<int> fixed_dofs;        // DOF 3·node + axis held at its initial value (e.g. rollers)
  Eigen::VectorXd external_forces_n;  // 3N or empty (none); dead loads
  std::vector<const ContactPotential*> contacts;  // not owned; may be empty
};

// Total potential Π(x) = elastic(x) − fᵀx + Σ contact(x); minimises it over the free DOFs by Newton
// with a backtracking (Armijo) line search, rejecting steps that invert an element. `x` holds the
// start (and the fixed nodes' positions) on entry, the equilibrium on exit (the last accepted
// iterate when not converged). Fails (Status) only on bad arguments; non-convergence is in the
// summary.
Status solve_equilibrium(const NeoHookeanModel& model, const Boundary& boundary,
                         const SolveOptions& options, Eigen::VectorXd* x, SolveSummary* summary);

// ---- Probe indentation, by depth or by force, in steps ----

struct IndentOptions {
  int steps = 10;                          // load increments (≥ 1)
  bool force_control = false;              // false: target is depth_m; true: target is force_n
  double depth_m = 1e-3;                   // final probe depth (depth control)
  double force_n = 1.0;                    // final probe force (force control), > 0
  double force_relative_tolerance = 1e-4;  // force control: |F − target| ≤ tol·target
  int max_force_iterations = 30;           // force control: secant steps per load step
  bool record_positions = false;           // keep x after every step (IndentSummary::positions)
  SolveOptions solve;
};
Status validate(const IndentOptions& options);

struct IndentStep {
  double depth_m = 0;
  double force_n = 0;  // probe reaction along its direction (N), ≥ 0 when pushing
  int newton_iterations = 0;
};

struct IndentSummary {
  bool usable = false;
  std::string message;  // why not usable
  std::vector<IndentStep> steps;
  double depth_m = 0;
  double force_n = 0;
  double max_displacement_m = 0;
  double time_s = 0;
  std::vector<Eigen::VectorXd> positions;  // with record_positions: x after each finished step
};

// Pushes `probe` into the model in `steps` increments (each warm-started from the previous
// equilibrium). Force is Σ over nodes of the contact force, projected on the probe direction.
// `x` holds rest/start positions on entry and the final equilibrium on exit.
Status indent(const NeoHookeanModel& model, const Boundary& boundary, RigidProbe& probe,
              const IndentOptions& options, Eigen::VectorXd* x, IndentSummary* summary);

// Total contact force (N) that obstacle `c` exerts on the nodes at x (3-vector, sum over nodes).
Eigen::Vector3d contact_force(const ContactPotential& c, const Eigen::VectorXd& x);
// The force on each node, #N by 3 (N): −∂(contact energy)/∂x.
MatrixX3d contact_forces(const ContactPotential& c, const Eigen::VectorXd& x);

}  // namespace hc::hyperelastic
