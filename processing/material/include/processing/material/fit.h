// Per-example material parameter estimation (thesis Sec. 4.3.1, Eq. 4.10, Appendix A):
//
//   p̂ = argmin_p  Σ_i ‖x_i(p, F̄) − x̄_i‖² / s²  +  γ ‖L q(p)‖²
//
// over one (λ_e, α_e) per tetrahedron, where x(p, F̄) are the node positions of the linear
// co-rotational model (processing/fem) under the example's measured nodal forces, with the element
// rotations R_e taken from the measured configuration (Appendix A differentiates with R_e fixed);
// the sum runs over visible, non-fixed nodes; s is the example's largest measured displacement (so
// γ is dimensionless and comparable between examples); L is the umbrella Laplacian over tets
// (w_ij = 1 iff tets i and j share a vertex, [Zhang 2004]).
//
// Physical validity (thesis Sec. 4.6) by reparameterisation rather than projection: the optimiser
// works on q_e = (ln λ_e, logit(ν_e / ν_max)), so λ_e > 0 and 0 < ν_e = α_e/λ_e < ν_max < 0.5 for
// every iterate; the regulariser acts on q (scale-free smoothness of log-stiffness).
//
// The Jacobian is analytic (Appendix A, Eq. A.2–A.3): with u_e = R_eᵀ x_e − X_e,
//   ∂x/∂λ_e = −K⁻¹ [R_e V_e B_eᵀ G B_e u_e]_e,   ∂x/∂α_e = −K⁻¹ [R_e V_e B_eᵀ H B_e u_e]_e,
// restricted to free dofs (fixed nodes' rows and columns drop out: their known positions are part
// of the right-hand side, the "slight modification" of Appendix A's last paragraph). One Cholesky
// factorisation of K serves all right-hand sides; whichever is smaller is solved for: the measured
// dofs (Z = K⁻¹ Sᵀ, then J = −Zᵀ G) or the parameter columns (K⁻¹ G, then rows S).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "common/tet_mesh.h"
#include "processing/fem/corotational.h"
#include "processing/material/material.h"
#include "processing/material/samples.h"

namespace hc::material {

// Which tets an umbrella Laplacian couples.
enum class TetAdjacency {
  kVertex,  // tets that share a vertex: the thesis's Eq. 4.10 ([Zhang 2004])
  kFace,    // tets that share a face: a narrower stencil (≤ 4 neighbours)
};

// Umbrella Laplacian over tets: L_ii = #neighbours, L_ij = −1 iff tets i ≠ j are neighbours.
Eigen::SparseMatrix<double> tet_umbrella_laplacian(const TetMesh& mesh,
                                                   TetAdjacency adjacency = TetAdjacency::kVertex);

// One example's fitting problem: the co-rotational model under the example's forces and fixed nodes
// with rotations frozen at the measured configuration, the measured dofs and their targets.
class ExampleProblem {
 public:
  // Estimates a uniform stiffness from one linear solve (see stiffness_guess()), simulates the
  // example once with it (co-rotational) to fill occluded nodes' positions of the reference
  // configuration, and takes the rotations R_e from that configuration (measured positions where
  // visible). Fails when the example has no fixed node, no measured free node, no measured
  // displacement, or displacements that do not follow the forces, or the FEM cannot be built.
  static Result<ExampleProblem> create(const TetMesh& mesh, const Example& example,
                                       double poisson_guess = 0.3);
  ExampleProblem(ExampleProblem&&) noexcept;
  ExampleProblem& operator=(ExampleProblem&&) noexcept;
  ~ExampleProblem();

  const TetMesh& mesh() const;
  Eigen::Index num_elements() const;
  Eigen::Index num_measurements() const;  // measured scalar coordinates (3 per measured node)
  double scale_m() const;                 // s: the example's largest measured displacement (m)

  // Solves the linear co-rotational system at per-element parameters `p` (size num_elements()),
  // and writes the measured coordinates minus their targets (m, unscaled) to *residual.
  // failed_precondition when K is not positive definite.
  Status simulate(const std::vector<LambdaAlpha>& p, Eigen::VectorXd* residual);
  // ∂(measured coordinates)/∂(λ_0, α_0, λ_1, α_1, ...) at the last simulate(), num_measurements()
  // by 2·num_elements() (m/Pa). `groups` (optional, size num_elements(), values 0..k−1) ties
  // elements together: column pairs are then summed per group (k groups → 2k columns).
  Status jacobian(Eigen::MatrixXd* j, const std::vector<int>* groups = nullptr,
                  int num_groups = 0) const;
  // Matrix-free products with the same Jacobian (thesis Appendix A), reusing the factorisation of
  // the last simulate(): J v by one solve (v: 2·num_elements(), (λ, α) per element; result
  // num_measurements()), Jᵀ w by one adjoint solve (K is symmetric), and Jᵀ W for the columns of W
  // by one multi-right-hand-side solve. No dense Jacobian is formed.
  Status apply_jacobian(const Eigen::VectorXd& v, Eigen::VectorXd* jv) const;
  Status apply_jacobian_transpose(const Eigen::VectorXd& w, Eigen::VectorXd* jtw) const;
  Status apply_jacobian_transpose(const Eigen::MatrixXd& w, Eigen::MatrixXd* jtw) const;
  // Free dofs of the model and entries of its Cholesky factor (for choosing dense vs matrix-free).
  Eigen::Index num_free_dofs() const;
  double factor_entries() const;
  // The FEM's numeric factorisations so far (one per simulate()) and their wall time.
  int factorizations() const;
  double factorize_time_s() const;
  // Re-freezes the rotations R_e at the last simulate()'s positions (the model's own
  // configuration instead of the measured one).
  void update_rotations();
  // Positions (#N by 3) and rotated-frame strains (#T by 6) of the last simulate().
  const MatrixX3d& positions() const;
  Eigen::Matrix<double, Eigen::Dynamic, 6> strains() const;
  // The uniform (λ, α) whose linear (R = I) displacements best match the measured ones in the
  // least-squares sense, at ν = poisson_guess (displacements scale with 1/λ at fixed ν).
  const LambdaAlpha& stiffness_guess() const;

 private:
  struct Impl;
  explicit ExampleProblem(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

enum class FitBackend { kOwnLm, kCeres };

// How the own LM solves its linear systems. kDense forms the Jacobian (one solve per measurement
// or per parameter, whichever is fewer) and factorises JᵀJ + γLᵀL; kMatrixFree never forms it:
// preconditioned CG on the normal equations, each CG iteration one solve for J v and one adjoint
// solve for Jᵀ w with the model's factorisation (memory O(parameters + measurements), time per
// iteration O(factor size)); kAuto picks the one whose estimated cost is lower (dense for small
// problems) within max_dense_bytes.
enum class FitSolver { kAuto, kDense, kMatrixFree };

struct ParameterFitOptions {
  double regularization = 1e-3;  // γ (dimensionless, see above)
  int max_iterations = 40;
  double function_tolerance = 1e-7;   // stop when an accepted step lowers the cost by less (rel.)
  double parameter_tolerance = 1e-8;  // stop when ‖Δq‖ ≤ tol (‖q‖ + tol)
  double max_poisson = kDefaultMaxPoisson;
  double initial_poisson = 0.3;
  // Weak prior pulling each element's logit(ν/ν_max) towards that of initial_poisson: adds
  // poisson_prior · Σ_e (q1_e − q1_prior)² to the cost (dimensionless like γ). Poisson's ratio is
  // poorly identified by displacement data (E, not ν, sets the indentation depth), and with noisy
  // displacements the unregularised ν runs to the ends of its range, where λ = E/((1+ν)(1−2ν))
  // varies by 20× for the same E and the strain-space RBF of (λ, α) then mixes incompatible
  // samples. 0 turns it off.
  double poisson_prior = 0;
  // Own LM: dense normal equations up to this many parameters, matrix-free preconditioned CG above
  // (the Ceres backend's choice between DENSE_NORMAL_CHOLESKY and CGNR).
  int dense_parameter_limit = 2500;
  FitSolver solver = FitSolver::kAuto;
  // Dense path: largest memory for J, JᵀJ and its factor (bytes, per example fitted at once).
  double max_dense_bytes = 1e9;
  // Matrix-free path: CG iterations per LM step; the tightest relative CG tolerance (steps are
  // solved loosely far from the minimum, down to this near it); columns of the Gaussian sketch
  // that estimates JᵀJ's diagonal blocks for the preconditioner.
  int cg_max_iterations = 400;
  double cg_relative_tolerance = 1e-8;
  int sketch_size = 16;
  FitBackend backend = FitBackend::kOwnLm;

  Status validate() const;
};

struct ParameterFitSummary {
  bool usable = false;
  std::string message;  // why it stopped
  int iterations = 0;
  double initial_cost = 0;
  double final_cost = 0;
  double rms_error_m = 0;  // over measured coordinates (per node: ‖x − x̄‖ RMS)
  double max_error_m = 0;  // largest node distance
  double time_s = 0;
  bool matrix_free = false;  // which path the own LM took (FitSolver)
  long cg_iterations = 0;    // matrix-free: CG iterations over all LM steps
  // The FEM's sparse Cholesky factorisations (one per residual) and their wall time (in time_s).
  int fem_factorizations = 0;
  double fem_factorize_s = 0;
};

// Fits one (λ, α) shared by all elements (the "average-fit linear co-rotational model") to the
// given examples jointly (Levenberg–Marquardt on 2 parameters; problems must describe the same
// mesh). Starts from the linear-solve stiffness guess of the first problem.
Result<LambdaAlpha> fit_homogeneous(std::vector<ExampleProblem*> problems,
                                    const ParameterFitOptions& options,
                                    ParameterFitSummary* summary = nullptr);

namespace detail {
class CoarseSpace;
}

// What fit_example derives from the mesh and the options alone: the regulariser R (the umbrella
// Laplacian's, and the Poisson prior) and the matrix-free preconditioner's coarse space (made at
// its first use). The examples of one mesh share one: fit_heterogeneous makes it once (made per
// example it took ~10 % of the per-example fits at 3,000-10,000 tets). Thread-safe.
struct ExampleFitSetup {
  Eigen::Index tets = 0;
  double regularization = 0, poisson_prior = 0, initial_poisson = 0, max_poisson = 0;
  Eigen::SparseMatrix<double> laplacian;       // tet_umbrella_laplacian (vertex)
  Eigen::SparseMatrix<double> face_laplacian;  // over face neighbours (the coarse space's graph)
  Eigen::SparseMatrix<double> reg;             // R (rows × 2 #T)
  Eigen::VectorXd reg_target;  // the regulariser is ‖R q − b‖² (empty: b = 0)
  std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)> reg_normal_product;  // RᵀR v

  bool made_for(const ParameterFitOptions& options) const;
  std::shared_ptr<const detail::CoarseSpace> coarse_space() const;

 private:
  mutable std::once_flag coarse_once_;
  mutable std::shared_ptr<const detail::CoarseSpace> coarse_;
};
Result<std::shared_ptr<const ExampleFitSetup>> make_example_fit_setup(
    const TetMesh& mesh, const ParameterFitOptions& options);

// Fits per-element parameters to one example (Eq. 4.10), starting from `initial` (size #T, or 1
// for uniform; a start with ν outside [0.1, 0.9]·max_poisson is moved to that range's end). On
// return `*params` holds the estimate (physically valid). `setup` (optional) is the mesh's
// make_example_fit_setup for these options, shared with other examples.
Status fit_example(ExampleProblem* problem, const std::vector<LambdaAlpha>& initial,
                   const ParameterFitOptions& options, std::vector<LambdaAlpha>* params,
                   ParameterFitSummary* summary = nullptr, const ExampleFitSetup* setup = nullptr);

// ---- Joint material fit over all examples (an extension of the thesis's method) ----
//
// The thesis estimates (λ, α) from ONE example at a time (Eq. 4.10) and only then combines the
// examples in each element's strain-space RBF. With noisy data that fails twice: each per-example
// estimate carries its example's noise in full (an element far from the probe is set by the
// regulariser, yet enters the RBF like the others), and the Laplacian weight the noise needs also
// flattens each example's effective λ field where the material stiffens under the probe (a bump
// that is real): at noise-level γ the per-example fits were ~3 % off even on CLEAN data.
// fit_joint_material regularises the MATERIAL instead and fits it to ALL examples at once: per
// element a base stiffness λ0_e, Poisson's ratio ν_e, a linear stiffening k_e and a quadratic-like
// stiffening m_e, written as an ordinary RBF (Eq. 4.9; a centre at zero strain plus 12 at ±c e_k):
//
//   f_e(ε) = 1 + k_e ‖ε‖ / ε_ref + m_e h(ε),   λ_e(ε) = λ0_e · max(f_e(ε), ½),   α_e = ν_e λ0_e f_e
//   h(ε) = (Σ_{k=1..6} ‖ε − c e_k‖ + ‖ε + c e_k‖ − 12 c) / (5 ε_ref),   c = ε_ref
//
// (e_k the strain axes; h ≈ ‖ε‖²/ε_ref² for ‖ε‖ ≪ c in every direction, as the 12 terms' second
// order parts sum to 5 ‖ε‖²/c; the reference materials stiffen faster than linearly in ‖ε‖, and the
// linear k alone cost ~0.25 % more error on clean data), and
//
//   min  Σ_i ‖x_i(p_i) − x̄_i‖² / s_i²  +  n γ_J (‖L_F ln λ0‖² + ‖L_F logit(ν/ν_max)‖²
//                                                   + κ ‖L_F k‖² + κ ‖L_F m‖²)
//        + n w_ν ‖logit(ν/ν_max) − logit(ν_prior/ν_max)‖²
//
// i.e. the sum of the n examples' Eq. 4.10 objectives with one shared material (p_i: its (λ, α) at
// example i's element strains ε_i, ε_ref the largest strain norm, γ_J = regularization_scale ·
// ParameterFitOptions::regularization, κ = stiffening_regularization_scale, w_ν the Poisson
// prior, L_F the umbrella Laplacian over FACE neighbours, see JointRefinementOptions::adjacency).
// λ0, k and m are smooth across the stiffened region under a probe, so the smoothing no
// longer fights it, and every element's parameters are estimated from all examples that strain it
// (the Gauss–Newton weighting). The factor's floor ½ keeps a softening element from collapsing. The
// strains are held during an LM run (Appendix A's Jacobian with the chain rule through λ0, ν, k, m)
// and updated between passes: each example is simulated with the current material in co-rotational
// sweeps whose rotations are then kept for the next pass (the first pass starts from the measured
// configuration's rotations, as the per-example fits do; with noisy data the model's own
// configuration is the better linearisation point).
struct JointRefinementOptions {
  bool enabled = false;
  // The material's Laplacian couples face neighbours, not the thesis's vertex neighbours (the
  // per-example fits keep those). The vertex stencil (~20-40 tets) reaches across a whole layer of
  // a layered object from every tet, so the weight the noise needs blurs every jump between
  // layers; the face stencil (≤ 4) lets a much heavier weight smooth within a layer while it
  // penalises a jump only across the faces on it. Noise study (thesis Sec. 4.5, mean over noise
  // seeds 2026, 7, 99, 1, 2; noise_study_test.cpp): 10 / 20 / 30 % noise 2.21 / 3.35 / 4.04 % with
  // the vertex stencil at its best weights (0.03, κ 1), 1.92 / 2.89 / 3.73 % with this one.
  TetAdjacency adjacency = TetAdjacency::kFace;
  // γ_J relative to ParameterFitOptions::regularization (tuned with the face stencil: 20 / 30 /
  // 50 / 100 x gave 10 % means 2.06 / 1.98 / 1.98 / 1.98 %, 30 % means 3.90 / 3.70 / 3.99 /
  // 3.98 % at κ = 1).
  double regularization_scale = 30;
  // κ: the Laplacian weight on k (and m) relative to that on ln λ0 (1 / 3 / 10 / 30 / 100 at γ_J
  // 30: 20 % means 3.02 / 2.98 / 2.96 / 2.89 / 2.89 %, 30 % 3.70 / 3.73 / 3.76 / 3.73 / 3.83 %).
  double stiffening_regularization_scale = 30;
  // Adds a quadratic-like stiffening m_e h(ε) to the factor (4 parameters per tet): h(ε) =
  // (Σ_k ‖ε − c e_k‖ + ‖ε + c e_k‖ − 12 c) / (5 ε_ref) over the 6 strain axes e_k, c = ε_ref,
  // i.e. ≈ ‖ε‖²/ε_ref² for small strains in any direction; 12 more RBF centres per element.
  // false: the linear k only (3 parameters, one centre per tet).
  bool quadratic_stiffening = true;
  int max_iterations = 30;  // LM iterations per pass
  // The joint LM's relative cost-decrease stop (ParameterFitOptions::function_tolerance's role).
  // 1e-5 halves the noise study's iterations (46 -> 18 at 10 %) for < 0.02 % change in its error.
  double function_tolerance = 1e-5;
  int passes = 2;  // (strains under the current material, LM) rounds
  // The dense path (ParameterFitOptions::solver) stores the stacked Jacobian (all measurements ×
  // parameters_per_tet() T, 8 bytes each): fine for the noise study's size (2,700 × 864), not for
  // the thesis-scale foam (48 × ~4,000 × 5,400: 8 GB). A dense fit larger than this fails with
  // kFailedPrecondition; kAuto takes the matrix-free path (which keeps only every example's FEM
  // factorisation) well before.
  double max_jacobian_bytes = 2e9;
  // Reports each pass's LM iterations (optional).
  ProgressReporter* progress = nullptr;
  // (ln λ0, logit ν, k[, m]): 4 with the quadratic-like stiffening, else 3.
  int parameters_per_tet() const { return quadratic_stiffening ? 4 : 3; }
  Status validate() const;
};

// `start[i]` are example i's per-element parameters (the per-example fits), whose per-element
// means give the starting λ0 and ν (k starts at 0); `strains[i]` (#T by 6) their strains, updated
// in place. Fails on mismatched sizes or when a simulation fails.
Result<Material> fit_joint_material(const std::vector<ExampleProblem*>& problems,
                                    std::vector<Eigen::Matrix<double, Eigen::Dynamic, 6>>* strains,
                                    const std::vector<std::vector<LambdaAlpha>>& start,
                                    const ParameterFitOptions& parameters,
                                    const JointRefinementOptions& options,
                                    ParameterFitSummary* summary = nullptr);

// ---- The heterogeneous pipeline (Sec. 4.3): per example fit, then per element RBF ----

struct HeterogeneousFitOptions {
  ParameterFitOptions parameters;
  struct RbfOptions {
    double tolerance = 0.05;
    int max_basis = 12;
    // λ floor of each element's RBF = this × the smallest λ its examples gave (guards against
    // interpolants that dive towards zero stiffness between noisy samples).
    double lambda_floor_fraction = 0.5;
  } rbf;
  JointRefinementOptions joint;
  int threads = 0;  // examples fitted in parallel (0: TBB's default)
  ProgressReporter* progress = nullptr;
  Status validate() const;
};

struct HeterogeneousFitSummary {
  double rms_error_m = 0;  // per-example fits: RMS node position error over all measurements
  double max_error_m = 0;
  double mean_basis_size = 0;
  double time_s = 0;
  double parameter_time_s = 0;
  double rbf_time_s = 0;
  double joint_time_s = 0;
  ParameterFitSummary joint;  // the joint refinement (when enabled)
  std::vector<ParameterFitSummary> examples;
};

// Fits a heterogeneous material (one StrainRbf per tet) to all examples.
Result<Material> fit_heterogeneous(const Samples& samples, const HeterogeneousFitOptions& options,
                                   HeterogeneousFitSummary* summary = nullptr);

// ---- Evaluation: simulate each example's forces with a material and compare ----

struct EvaluateOptions {
  int steps = 8;  // load increments (processing/fem incremental loading, nodal forces)
  int threads = 0;  // examples simulated in parallel (0: TBB's default)
  ProgressReporter* progress = nullptr;
};

struct EvaluateSummary {
  double rms_error_m = 0;  // RMS node distance over the visible, non-fixed nodes of all examples
  double max_error_m = 0;
  double max_displacement_m = 0;  // largest measured displacement over all examples
  double error_rel_max_disp = 0;  // rms_error_m / max_displacement_m (thesis Sec. 4.5)
  std::vector<double> example_rms_error_m;
  std::vector<MatrixX3d> positions;  // simulated positions per example
  double time_s = 0;
};

// Fails when the material does not match the mesh (element count) or a simulation fails.
Result<EvaluateSummary> evaluate_material(const fem::MaterialModel& material,
                                          const Samples& samples, const EvaluateOptions& options);

}  // namespace hc::material
