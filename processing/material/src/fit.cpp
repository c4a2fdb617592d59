// Levenberg–Marquardt for Eq. 4.10: the homogeneous and per-example fits (own LM, lm.h, dense or
// matrix-free) and a Ceres backend for comparison.
//
// Why an own LM next to Ceres: the data Jacobian is dense (every node moves with every element's
// stiffness) while the regulariser is sparse; Ceres treats the data block as one residual block
// over all 2T parameters, so its normal equations are a dense 2T×2T matrix factorised each
// iteration, whereas the own LM never forms the Jacobian on large meshes (J v and Jᵀ w by one FEM
// solve each). The unit tests and bench_material_fit time both on the same problem.
#include <ceres/ceres.h>
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>

#include "lm.h"
#include "processing/material/fit.h"

namespace hc::material {
namespace {

using detail::error_stats;
using detail::Reparam;
using detail::sigmoid;
using Clock = std::chrono::steady_clock;
// Per-element fits start with ν / ν_max inside [low, high] (see fit_example).
constexpr double kStartPoissonLow = 0.1;
constexpr double kStartPoissonHigh = 0.9;

std::vector<LambdaAlpha> params_of(const Reparam& rp, const Eigen::VectorXd& q) {
  std::vector<LambdaAlpha> p(static_cast<std::size_t>(q.size() / 2));
  for (std::size_t e = 0; e < p.size(); ++e)
    p[e] =
        rp.to_params(q(2 * static_cast<Eigen::Index>(e)), q(2 * static_cast<Eigen::Index>(e) + 1));
  return p;
}

// J_q = J_p ∂(λ, α)/∂q / s of one example, matrix-free (ExampleProblem's products).
class ExampleOperator final : public detail::JacobianOperator {
 public:
  ExampleOperator(const ExampleProblem* problem, const Reparam& rp, const Eigen::VectorXd& q,
                  double scale)
      : problem_(problem), chain_(q.size() / 2, 3), scale_(scale) {
    // Per element (λ, α, c): ∂λ/∂q0 = λ, ∂α/∂q0 = α, ∂α/∂q1 = c = λ ν_max σ(q1)(1 − σ(q1)).
    for (Eigen::Index e = 0; e < q.size() / 2; ++e) {
      const LambdaAlpha p = rp.to_params(q(2 * e), q(2 * e + 1));
      const double sg = sigmoid(q(2 * e + 1));
      chain_.row(e) << p.lambda, p.alpha, p.lambda * rp.max_poisson * sg * (1 - sg);
    }
  }
  Status apply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const override {
    Eigen::VectorXd vp(v.size());
    for (Eigen::Index e = 0; e < v.size() / 2; ++e) {
      vp(2 * e) = chain_(e, 0) * v(2 * e);
      vp(2 * e + 1) = chain_(e, 1) * v(2 * e) + chain_(e, 2) * v(2 * e + 1);
    }
    HC_RETURN_IF_ERROR(problem_->apply_jacobian(vp, out));
    *out /= scale_;
    return {};
  }
  Status apply_transpose(const Eigen::MatrixXd& w, Eigen::MatrixXd* out) const override {
    Eigen::MatrixXd jp;
    HC_RETURN_IF_ERROR(problem_->apply_jacobian_transpose(w, &jp));
    out->resize(jp.rows(), jp.cols());
    for (Eigen::Index e = 0; e < jp.rows() / 2; ++e) {
      out->row(2 * e) = (chain_(e, 0) * jp.row(2 * e) + chain_(e, 1) * jp.row(2 * e + 1)) / scale_;
      out->row(2 * e + 1) = chain_(e, 2) * jp.row(2 * e + 1) / scale_;
    }
    return {};
  }

 private:
  const ExampleProblem* problem_;
  Eigen::Matrix<double, Eigen::Dynamic, 3> chain_;
  double scale_;
};

// ---- Ceres backend ----

class DataCost final : public ceres::CostFunction {
 public:
  DataCost(ExampleProblem* problem, const Reparam& rp) : problem_(problem), rp_(rp) {
    for (Eigen::Index e = 0; e < problem->num_elements(); ++e)
      mutable_parameter_block_sizes()->push_back(2);
    set_num_residuals(static_cast<int>(problem->num_measurements()));
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Index t = problem_->num_elements();
    std::vector<LambdaAlpha> p(static_cast<std::size_t>(t));
    for (Eigen::Index e = 0; e < t; ++e)
      p[static_cast<std::size_t>(e)] = rp_.to_params(parameters[e][0], parameters[e][1]);
    Eigen::VectorXd r;
    if (!problem_->simulate(p, &r).ok()) return false;
    const double s = problem_->scale_m();
    Eigen::Map<Eigen::VectorXd>(residuals, r.size()) = r / s;
    if (jacobians == nullptr) return true;
    Eigen::MatrixXd j;
    if (!problem_->jacobian(&j).ok()) return false;
    for (Eigen::Index e = 0; e < t; ++e) {
      if (jacobians[e] == nullptr) continue;
      Eigen::MatrixXd block = j.middleCols(2 * e, 2) / s;
      rp_.chain(parameters[e][0], parameters[e][1], block);
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>(jacobians[e], j.rows(),
                                                                            2) = block;
    }
    return true;
  }

 private:
  ExampleProblem* problem_;
  Reparam rp_;
};

// sqrt(γ) (deg_i q_i − Σ_j q_j), both channels; blocks: i then its neighbours.
class LaplacianCost final : public ceres::CostFunction {
 public:
  LaplacianCost(double degree, int neighbours, double sqrt_gamma)
      : degree_(degree), sqrt_gamma_(sqrt_gamma) {
    for (int k = 0; k <= neighbours; ++k) mutable_parameter_block_sizes()->push_back(2);
    set_num_residuals(2);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const std::size_t blocks = parameter_block_sizes().size();
    for (int c = 0; c < 2; ++c) {
      double v = degree_ * parameters[0][c];
      for (std::size_t k = 1; k < blocks; ++k) v -= parameters[k][c];
      residuals[c] = sqrt_gamma_ * v;
    }
    if (jacobians)
      for (std::size_t k = 0; k < blocks; ++k) {
        if (!jacobians[k]) continue;
        const double w = sqrt_gamma_ * (k == 0 ? degree_ : -1.0);
        jacobians[k][0] = w;
        jacobians[k][1] = 0;
        jacobians[k][2] = 0;
        jacobians[k][3] = w;
      }
    return true;
  }

 private:
  double degree_;
  double sqrt_gamma_;
};

// sqrt(w) (q1 − q1_prior) on one element's block (ParameterFitOptions::poisson_prior).
class PoissonPriorCost final : public ceres::SizedCostFunction<1, 2> {
 public:
  PoissonPriorCost(double sqrt_weight, double q1_prior) : w_(sqrt_weight), q1_(q1_prior) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    residuals[0] = w_ * (parameters[0][1] - q1_);
    if (jacobians && jacobians[0]) {
      jacobians[0][0] = 0;
      jacobians[0][1] = w_;
    }
    return true;
  }

 private:
  double w_;
  double q1_;
};

Status fit_example_ceres(ExampleProblem* problem, const Eigen::SparseMatrix<double>& laplacian,
                         const Reparam& rp, const ParameterFitOptions& options, Eigen::VectorXd* q,
                         ParameterFitSummary* summary) {
  const Eigen::Index t = problem->num_elements();
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem cp(po);
  std::vector<double*> blocks(static_cast<std::size_t>(t));
  for (Eigen::Index e = 0; e < t; ++e) blocks[static_cast<std::size_t>(e)] = q->data() + 2 * e;
  cp.AddResidualBlock(new DataCost(problem, rp), nullptr, blocks);
  const double sg = std::sqrt(options.regularization);
  Eigen::SparseMatrix<double, Eigen::RowMajor> lr = laplacian;
  for (Eigen::Index i = 0; i < t; ++i) {
    std::vector<double*> b = {blocks[static_cast<std::size_t>(i)]};
    double degree = 0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(lr, i); it; ++it) {
      if (it.col() == i) {
        degree = it.value();
      } else {
        b.push_back(blocks[static_cast<std::size_t>(it.col())]);
      }
    }
    if (b.size() > 1)
      cp.AddResidualBlock(new LaplacianCost(degree, static_cast<int>(b.size() - 1), sg), nullptr,
                          b);
    if (options.poisson_prior > 0)
      cp.AddResidualBlock(new PoissonPriorCost(std::sqrt(options.poisson_prior),
                                               rp.to_q({1.0, options.initial_poisson})(1)),
                          nullptr, blocks[static_cast<std::size_t>(i)]);
  }
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type =
      2 * t <= options.dense_parameter_limit ? ceres::DENSE_NORMAL_CHOLESKY : ceres::CGNR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary cs;
  ceres::Solve(so, &cp, &cs);
  summary->iterations = static_cast<int>(cs.iterations.size());
  summary->initial_cost = 2 * cs.initial_cost;  // Ceres reports ½‖r‖²
  summary->final_cost = 2 * cs.final_cost;
  summary->message = cs.message;
  summary->usable = cs.IsSolutionUsable();
  return {};
}

}  // namespace

Status ParameterFitOptions::validate() const {
  if (!(regularization >= 0) || !std::isfinite(regularization))
    return invalid_argument("regularization: must be >= 0");
  if (max_iterations < 1) return invalid_argument("max_iterations: must be >= 1");
  if (!(max_poisson > 0 && max_poisson < 0.5))
    return invalid_argument("max_poisson: must be in (0, 0.5)");
  if (!(initial_poisson > 0 && initial_poisson < max_poisson))
    return invalid_argument("initial_poisson: must be in (0, max_poisson)");
  if (!(poisson_prior >= 0) || !std::isfinite(poisson_prior))
    return invalid_argument("poisson_prior: must be >= 0");
  if (!(function_tolerance >= 0) || !(parameter_tolerance >= 0))
    return invalid_argument("tolerances must be >= 0");
  if (cg_max_iterations < 1 || sketch_size < 1)
    return invalid_argument("cg_max_iterations and sketch_size: must be >= 1");
  if (!(cg_relative_tolerance > 0 && cg_relative_tolerance < 1))
    return invalid_argument("cg_relative_tolerance: must be in (0, 1)");
  if (!(max_dense_bytes > 0)) return invalid_argument("max_dense_bytes: must be > 0");
  return {};
}

Result<LambdaAlpha> fit_homogeneous(std::vector<ExampleProblem*> problems,
                                    const ParameterFitOptions& options,
                                    ParameterFitSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  if (problems.empty()) return invalid_argument("fit_homogeneous: no examples");
  const auto t0 = Clock::now();
  const Reparam rp{options.max_poisson};
  const Eigen::Index t = problems[0]->num_elements();
  for (ExampleProblem* p : problems)
    if (p->num_elements() != t) return invalid_argument("fit_homogeneous: examples differ in mesh");
  LambdaAlpha guess = problems[0]->stiffness_guess();
  guess.alpha = guess.lambda * options.initial_poisson;
  Eigen::VectorXd q = rp.to_q(guess);
  const std::vector<int> groups(static_cast<std::size_t>(t), 0);
  Eigen::Index rows = 0;
  for (ExampleProblem* p : problems) rows += p->num_measurements();

  detail::LmProblem lm;
  lm.residual = [&](const Eigen::VectorXd& qq, Eigen::VectorXd* r) -> Status {
    const std::vector<LambdaAlpha> p(static_cast<std::size_t>(t), rp.to_params(qq(0), qq(1)));
    r->resize(rows);
    Eigen::Index at = 0;
    for (ExampleProblem* ex : problems) {
      Eigen::VectorXd ri;
      HC_RETURN_IF_ERROR(ex->simulate(p, &ri));
      r->segment(at, ri.size()) = ri / ex->scale_m();
      at += ri.size();
    }
    return {};
  };
  lm.jacobian = [&](const Eigen::VectorXd& qq, Eigen::MatrixXd* j) -> Status {
    j->resize(rows, 2);
    Eigen::Index at = 0;
    for (ExampleProblem* ex : problems) {
      Eigen::MatrixXd ji;
      HC_RETURN_IF_ERROR(ex->jacobian(&ji, &groups, 1));
      j->middleRows(at, ji.rows()) = ji / ex->scale_m();
      at += ji.rows();
    }
    rp.chain(qq(0), qq(1), *j);
    return {};
  };
  if (options.poisson_prior > 0) {
    // The per-element prior summed over the T elements sharing the one ν.
    const double w = std::sqrt(options.poisson_prior * static_cast<double>(t));
    lm.reg.resize(1, 2);
    lm.reg.insert(0, 1) = w;
    lm.reg_target = Eigen::VectorXd::Constant(1, w * rp.to_q({1.0, options.initial_poisson})(1));
  }
  ParameterFitSummary local;
  ParameterFitSummary* s = summary ? summary : &local;
  *s = ParameterFitSummary{};
  HC_RETURN_IF_ERROR(detail::run_lm(lm, detail::lm_settings(options), &q, s));
  const LambdaAlpha result = rp.to_params(q(0), q(1));
  // Error statistics in metres over all examples at the result.
  double sum = 0, mx = 0;
  Eigen::Index nodes = 0;
  for (ExampleProblem* ex : problems) {
    Eigen::VectorXd ri;
    HC_RETURN_IF_ERROR(
        ex->simulate(std::vector<LambdaAlpha>(static_cast<std::size_t>(t), result), &ri));
    double rms = 0, emax = 0;
    error_stats(ri, &rms, &emax);
    sum += rms * rms * static_cast<double>(ri.size() / 3);
    nodes += ri.size() / 3;
    mx = std::max(mx, emax);
  }
  s->rms_error_m = std::sqrt(sum / static_cast<double>(std::max<Eigen::Index>(nodes, 1)));
  s->max_error_m = mx;
  s->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return result;
}

Result<std::shared_ptr<const ExampleFitSetup>> make_example_fit_setup(
    const TetMesh& mesh, const ParameterFitOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  auto setup = std::make_shared<ExampleFitSetup>();
  const Eigen::Index t = mesh.num_tets();
  setup->tets = t;
  setup->regularization = options.regularization;
  setup->poisson_prior = options.poisson_prior;
  setup->initial_poisson = options.initial_poisson;
  setup->max_poisson = options.max_poisson;
  setup->laplacian = tet_umbrella_laplacian(mesh);
  setup->face_laplacian = tet_umbrella_laplacian(mesh, TetAdjacency::kFace);
  const Eigen::SparseMatrix<double>& laplacian = setup->laplacian;
  // sqrt(γ) (L ⊗ I₂): the Laplacian acts on each channel of q separately.
  std::vector<Eigen::Triplet<double>> trip;
  const double sg = std::sqrt(options.regularization);
  for (Eigen::Index k = 0; k < laplacian.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, k); it; ++it)
      for (int c = 0; c < 2; ++c)
        trip.emplace_back(static_cast<int>(2 * it.row() + c), static_cast<int>(2 * it.col() + c),
                          sg * it.value());
  Eigen::Index rows = options.regularization > 0 ? 2 * t : 0;
  if (rows == 0) trip.clear();
  if (options.poisson_prior > 0) {
    const double w = std::sqrt(options.poisson_prior);
    setup->reg_target = Eigen::VectorXd::Zero(rows + t);
    const double q1 = Reparam{options.max_poisson}.to_q({1.0, options.initial_poisson})(1);
    for (Eigen::Index e = 0; e < t; ++e) {
      trip.emplace_back(static_cast<int>(rows + e), static_cast<int>(2 * e + 1), w);
      setup->reg_target(rows + e) = w * q1;
    }
    rows += t;
  }
  setup->reg.resize(rows, 2 * t);
  setup->reg.setFromTriplets(trip.begin(), trip.end());
  setup->reg_normal_product = detail::umbrella_normal_product(laplacian, options.regularization,
                                                              std::max(options.poisson_prior, 0.0));
  return std::shared_ptr<const ExampleFitSetup>(std::move(setup));
}

bool ExampleFitSetup::made_for(const ParameterFitOptions& options) const {
  return options.regularization == regularization && options.poisson_prior == poisson_prior &&
         options.initial_poisson == initial_poisson && options.max_poisson == max_poisson;
}

std::shared_ptr<const detail::CoarseSpace> ExampleFitSetup::coarse_space() const {
  // The preconditioner's coarse space: aggregates of about 17 tets (a tet and its face
  // neighbours up to two faces away), smoothed by the regulariser's own Laplacian. Per example
  // in bench_material_fit BM_FitScaling/<tets>/0, block-Jacobi alone took 435 / 852 CG
  // iterations at 3,000 / 9,996 tets; with aggregates over three face rings (40 tets) 112 /
  // 179, over two (17) 101 / 147; over L's vertex stencil (75 tets) 144 at 3,000. Made at the
  // first matrix-free fit that asks (so never for dense ones), once for all that share this.
  std::call_once(coarse_once_, [&] {
    coarse_ = std::make_shared<const detail::CoarseSpace>(
        detail::smoothed_aggregation_basis(detail::neighbourhood(face_laplacian, 2), laplacian),
        reg, 2);
  });
  return coarse_;
}

Status fit_example(ExampleProblem* problem, const std::vector<LambdaAlpha>& initial,
                   const ParameterFitOptions& options, std::vector<LambdaAlpha>* params,
                   ParameterFitSummary* summary, const ExampleFitSetup* setup) {
  HC_RETURN_IF_ERROR(options.validate());
  const auto t0 = Clock::now();
  const int factorizations0 = problem->factorizations();
  const double factorize_s0 = problem->factorize_time_s();
  const Eigen::Index t = problem->num_elements();
  if (initial.size() != 1 && static_cast<Eigen::Index>(initial.size()) != t)
    return invalid_argument(
        fmt::format("fit_example: {} initial parameters for {} elements", initial.size(), t));
  const Reparam rp{options.max_poisson};
  Eigen::VectorXd q(2 * t);
  for (Eigen::Index e = 0; e < t; ++e) {
    const LambdaAlpha& p0 = initial.size() == 1 ? initial[0] : initial[static_cast<std::size_t>(e)];
    if (!(p0.lambda > 0) || !std::isfinite(p0.lambda) || !std::isfinite(p0.alpha))
      return invalid_argument(
          fmt::format("fit_example: initial parameters of element {} invalid", e));
    // Start strictly inside the valid range: at ν → 0 or ν → ν_max the logit saturates, its
    // derivative vanishes and LM cannot move ν back (a uniform start fitted to ν ≈ 0 left every
    // element of an example stuck there, 2 % fit error instead of 0.1 %; see noise_study_test).
    LambdaAlpha start = p0;
    start.alpha = p0.lambda * std::clamp(p0.alpha / p0.lambda, kStartPoissonLow * rp.max_poisson,
                                         kStartPoissonHigh * rp.max_poisson);
    q.segment<2>(2 * e) = rp.to_q(start);
  }
  std::shared_ptr<const ExampleFitSetup> own;
  if (setup == nullptr) {
    HC_ASSIGN_OR_RETURN(own, make_example_fit_setup(problem->mesh(), options));
    setup = own.get();
  } else if (setup->tets != t || !setup->made_for(options)) {
    return invalid_argument("fit_example: the shared setup was made for another mesh or options");
  }
  const Eigen::SparseMatrix<double>& laplacian = setup->laplacian;
  ParameterFitSummary local;
  ParameterFitSummary* s = summary ? summary : &local;
  *s = ParameterFitSummary{};
  if (options.backend == FitBackend::kCeres) {
    HC_RETURN_IF_ERROR(fit_example_ceres(problem, laplacian, rp, options, &q, s));
  } else {
    detail::LmProblem lm;
    const double scale = problem->scale_m();
    lm.residual = [&](const Eigen::VectorXd& qq, Eigen::VectorXd* r) -> Status {
      HC_RETURN_IF_ERROR(problem->simulate(params_of(rp, qq), r));
      *r /= scale;
      return {};
    };
    lm.jacobian = [&](const Eigen::VectorXd& qq, Eigen::MatrixXd* j) -> Status {
      HC_RETURN_IF_ERROR(problem->jacobian(j));
      *j /= scale;
      for (Eigen::Index e = 0; e < t; ++e)
        rp.chain(qq(2 * e), qq(2 * e + 1), j->middleCols(2 * e, 2));
      return {};
    };
    lm.rows = problem->num_measurements();
    lm.block = 2;
    lm.product_flops = detail::solve_flops(problem->factor_entries());
    lm.matrix_free = !detail::prefer_dense(static_cast<double>(lm.rows), 2.0 * static_cast<double>(t),
                                           problem->factor_entries(), 1, options);
    lm.jacobian_operator = [&](const Eigen::VectorXd& qq)
        -> Result<std::unique_ptr<detail::JacobianOperator>> {
      return std::unique_ptr<detail::JacobianOperator>(
          std::make_unique<ExampleOperator>(problem, rp, qq, scale));
    };
    lm.reg = setup->reg;
    lm.reg_target = setup->reg_target;
    if (setup->reg_normal_product)  // by reference: its neighbour lists are the mesh's size
      lm.reg_normal_product = [f = &setup->reg_normal_product](
                                  const Eigen::VectorXd& v, Eigen::VectorXd* out) { (*f)(v, out); };
    if (lm.matrix_free && options.regularization > 0) lm.coarse = setup->coarse_space();
    HC_RETURN_IF_ERROR(detail::run_lm(lm, detail::lm_settings(options), &q, s));
  }
  *params = params_of(rp, q);
  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(problem->simulate(*params, &r));
  error_stats(r, &s->rms_error_m, &s->max_error_m);
  s->fem_factorizations = problem->factorizations() - factorizations0;
  s->fem_factorize_s = problem->factorize_time_s() - factorize_s0;
  s->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return {};
}

}  // namespace hc::material
