// Levenberg–Marquardt on a scaled least-squares problem  ‖r(q)‖² + ‖R q − b‖²  (R sparse), with
// the Jacobian of r either dense or as an operator (matrix-free: J v and Jᵀ w by one FEM solve
// each). Internal to processing/material: fit.cpp (per-example and homogeneous fits) and
// joint_fit.cpp (the joint material fit) use it.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/status.h"
#include "processing/fem/sparse_cholesky.h"
#include "processing/material/fit.h"

namespace hc::material::detail {

// The fits' parameterisation of physical validity (fit.h): q = (ln λ, logit(ν/ν_max)).
inline double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }
inline double logit(double y) { return std::log(y / (1.0 - y)); }

// q = (ln λ, logit(ν/ν_max)) per element ↔ (λ, α).
struct Reparam {
  double max_poisson;
  LambdaAlpha to_params(double q0, double q1) const {
    const double lambda = std::exp(q0);
    return {lambda, lambda * max_poisson * sigmoid(q1)};
  }
  Eigen::Vector2d to_q(const LambdaAlpha& p) const {
    const double lambda = std::max(p.lambda, 1e-300);
    double nu = p.alpha / lambda;
    nu = std::clamp(nu / max_poisson, 1e-6, 1 - 1e-6);
    return {std::log(lambda), logit(nu)};
  }
  // ∂(λ, α)/∂(q0, q1) applied to the (λ, α) columns of `j` in place (columns 2e, 2e+1 per block e).
  void chain(double q0, double q1, Eigen::Ref<Eigen::MatrixXd> j2) const {
    const double lambda = std::exp(q0);
    const double s = sigmoid(q1);
    const double alpha = lambda * max_poisson * s;
    const Eigen::VectorXd dl = j2.col(0);
    const Eigen::VectorXd da = j2.col(1);
    j2.col(0) = lambda * dl + alpha * da;
    j2.col(1) = lambda * max_poisson * s * (1 - s) * da;
  }
};

// J at the LM's current point (valid until the next residual evaluation).
class JacobianOperator {
 public:
  virtual ~JacobianOperator() = default;
  // out = J v (rows), v has cols entries.
  virtual Status apply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const = 0;
  // out = Jᵀ W for the columns of W (rows × k) → cols × k.
  virtual Status apply_transpose(const Eigen::MatrixXd& w, Eigen::MatrixXd* out) const = 0;
};

// The coarse space of the matrix-free preconditioner: P = C ⊗ I_block for a coarse basis C
// (elements × coarse functions, e.g. smoothed_aggregation_basis), and the coarse matrices
// Pᵀ (X + RᵀR) P for block-diagonal X. Their entry (j b + a, k b + c) is Σ_e C(e, j) C(e, k)
// X_e(a, c) plus Pᵀ RᵀR P's, so the pattern and a scatter of the terms C(e, j) C(e, k) are made
// here once and each LM trial only adds numbers (Eigen's sparse triple product per trial took 14 %
// of the per-example fits at 10,000 tets, 23 ms a trial). It depends on C and R alone: fits that
// share them (the examples of one mesh) share one.
class CoarseSpace {
 public:
  CoarseSpace(const Eigen::SparseMatrix<double>& basis, const Eigen::SparseMatrix<double>& reg,
              int block);
  const Eigen::SparseMatrix<double>& p() const { return p_; }
  // *upper = the upper triangle of Pᵀ (X + RᵀR) P for X's diagonal blocks stacked in x
  // (elements · block × block); *upper keeps the pattern between calls.
  void assemble(const Eigen::MatrixXd& x, fem::SparseMatrix* upper) const;

 private:
  struct Term {
    int element, k;  // C(element, j) C(element, k), j <= k
    int offset;      // of row j b in column k b (and in each k b + c)
    bool diagonal;   // j == k
    double weight;
  };
  int b_;
  Eigen::SparseMatrix<double> p_;
  fem::SparseMatrix upper_;     // the pattern, with Pᵀ RᵀR P's values
  Eigen::VectorXd reg_values_;  // those values
  std::vector<Term> terms_;
};

struct LmProblem {
  std::function<Status(const Eigen::VectorXd& q, Eigen::VectorXd* r)> residual;
  // Dense Jacobian at the last residual() point.
  std::function<Status(const Eigen::VectorXd& q, Eigen::MatrixXd* j)> jacobian;
  // Matrix-free Jacobian at the last residual() point (used when matrix_free is set).
  std::function<Result<std::unique_ptr<JacobianOperator>>(const Eigen::VectorXd& q)> jacobian_operator;
  bool matrix_free = false;
  Eigen::Index rows = 0;  // residual length (needed by the matrix-free path's sketch)
  // Parameters per element: the matrix-free preconditioner holds these diagonal blocks of JᵀJ.
  int block = 1;
  // Flops of one product J v (or Jᵀ w) of the matrix-free path: whether its preconditioner also
  // factorises RᵀR (see lm.cpp) is chosen from it.
  double product_flops = 0;
  Eigen::SparseMatrix<double> reg;  // R (rows × n) already multiplied by sqrt(γ); may be 0×0
  Eigen::VectorXd reg_target;       // b: the regulariser is ‖R q − b‖² (empty: b = 0)
  // Optional: *out = RᵀR v by a cheaper route than R's entries (the matrix-free path's CG applies
  // it once per iteration). Must equal reg.transpose() * (reg * v).
  std::function<void(const Eigen::VectorXd& v, Eigen::VectorXd* out)> reg_normal_product;
  // Optional, for the matrix-free path's preconditioner: a coarse space (CoarseSpace, for this
  // problem's R and block), whose span holds the regulariser's smooth modes. The preconditioner
  // is then block-Jacobi plus the coarse correction P (Pᵀ M P)⁻¹ Pᵀ in place of trying RᵀR whole
  // (lm.cpp).
  std::shared_ptr<const CoarseSpace> coarse;
  ProgressReporter* progress = nullptr;  // one unit per LM iteration
  std::string progress_task = "LM iterations";
};

// RᵀR v for fit_example's regulariser R = [√γ (L ⊗ I₂); √prior P] (P picks each element's second
// parameter) from the Laplacian's neighbour lists, for LmProblem::reg_normal_product; empty when
// L is not an umbrella Laplacian (tet_umbrella_laplacian: L_ii its degree, L_ij = −1).
std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)> umbrella_normal_product(
    const Eigen::SparseMatrix<double>& laplacian, double gamma, double prior);

// The pattern of (I + |A|)^rings (values 1): the elements within `rings` steps of each other on
// the graph of A's off-diagonal entries.
Eigen::SparseMatrix<double> neighbourhood(const Eigen::SparseMatrix<double>& a, int rings);

// Smoothed aggregation's coarse basis (Vaněk, Mandel and Brezina 1996) for a CoarseSpace:
// aggregates over `graph` (an element whose neighbours are all free, with them; the rest join a
// neighbouring aggregate), their indicator functions smoothed by one Jacobi step of the umbrella
// Laplacian L, (I − D⁻¹ L) with D its diagonal: each element's value becomes its L-neighbours'
// mean. Columns: the aggregates. Written here: an algebraic multigrid package (AMGCL, hypre)
// would build its hierarchy from the assembled M, whose RᵀR couples two vertex rings, at every LM
// trial; this basis is built once per mesh (ExampleFitSetup) from the mesh's graph alone.
Eigen::SparseMatrix<double> smoothed_aggregation_basis(
    const Eigen::SparseMatrix<double>& graph, const Eigen::SparseMatrix<double>& laplacian);

struct LmSettings {
  int max_iterations = 40;
  double function_tolerance = 1e-7;
  double parameter_tolerance = 1e-8;
  int cg_max_iterations = 400;
  double cg_relative_tolerance = 1e-8;
  int sketch_size = 16;
  std::uint64_t seed = 1;
};
LmSettings lm_settings(const ParameterFitOptions& options);

// Runs LM from *q; summary gets iterations, costs, message, usable (and cg_iterations).
Status run_lm(const LmProblem& problem, const LmSettings& settings, Eigen::VectorXd* q,
              ParameterFitSummary* summary);

// Flops of one solve with a Cholesky factor of `factor_entries` entries (forward and back
// substitution: ~4 per entry); the cost model of prefer_dense and LmProblem::product_flops.
inline double solve_flops(double factor_entries) { return 4 * factor_entries; }

// Whether the dense path is expected to be faster (and fits in memory) for a problem with m
// residuals, n parameters and Cholesky factors of `factor_entries` entries over `examples` FEM
// models (see fit.h, FitSolver::kAuto).
bool prefer_dense(double m, double n, double factor_entries, double examples,
                  const ParameterFitOptions& options);

// RMS and largest node distance of residuals in metres (3 per node).
void error_stats(const Eigen::VectorXd& r_m, double* rms, double* max);

}  // namespace hc::material::detail
