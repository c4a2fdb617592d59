// Levenberg–Marquardt for Eq. 4.10 (own implementation and a Ceres backend for comparison).
//
// Why an own LM next to Ceres: the data Jacobian is dense (every node moves with every element's
// stiffness) while the regulariser is sparse; Ceres treats the data block as one residual block
// over all 2T parameters, so its normal equations are a dense 2T×2T matrix factorised each
// iteration, whereas the own LM can use a matrix-free CG on JᵀJ + γLᵀL for large meshes. The unit
// tests and bench_material_fit time both on the same problem.
#include <ceres/ceres.h>
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCore>
#include <chrono>
#include <cmath>
#include <optional>

#include "processing/fem/blas_threads.h"
#include "processing/material/fit.h"

namespace hc::material {
namespace {

using Clock = std::chrono::steady_clock;
// Per-element fits start with ν / ν_max inside [low, high] (see fit_example).
constexpr double kStartPoissonLow = 0.1;
constexpr double kStartPoissonHigh = 0.9;

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }
double logit(double y) { return std::log(y / (1.0 - y)); }

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

std::vector<LambdaAlpha> params_of(const Reparam& rp, const Eigen::VectorXd& q) {
  std::vector<LambdaAlpha> p(static_cast<std::size_t>(q.size() / 2));
  for (std::size_t e = 0; e < p.size(); ++e)
    p[e] =
        rp.to_params(q(2 * static_cast<Eigen::Index>(e)), q(2 * static_cast<Eigen::Index>(e) + 1));
  return p;
}

// Generic LM over q with data residuals r(q) (scaled) and a sparse quadratic regulariser
// γ‖R q‖² (R may be empty).
struct LmProblem {
  std::function<Status(const Eigen::VectorXd& q, Eigen::VectorXd* r)> residual;
  // Jacobian of the last residual() call's point (the LM re-evaluates when needed).
  std::function<Status(const Eigen::VectorXd& q, Eigen::MatrixXd* j)> jacobian;
  Eigen::SparseMatrix<double> reg;  // R (rows × n) already multiplied by sqrt(γ); may be 0×0
  Eigen::VectorXd reg_target;       // b: the regulariser is ‖R q − b‖² (empty: b = 0)
};

Status run_lm(const LmProblem& problem, const ParameterFitOptions& options, Eigen::VectorXd* q,
              ParameterFitSummary* summary) {
  const Eigen::Index n = q->size();
  const bool has_reg = problem.reg.rows() > 0;
  const Eigen::SparseMatrix<double>& reg = problem.reg;
  Eigen::SparseMatrix<double> rtr;
  if (has_reg) rtr = reg.transpose() * reg;
  const bool has_target = has_reg && problem.reg_target.size() == problem.reg.rows();
  const Eigen::VectorXd& reg_target = problem.reg_target;
  const auto reg_residual = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
    Eigen::VectorXd out = reg * v;
    if (has_target) out -= reg_target;
    return out;
  };

  const auto reg_cost = [&](const Eigen::VectorXd& v) {
    return has_reg ? reg_residual(v).squaredNorm() : 0.0;
  };

  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(problem.residual(*q, &r));
  double cost = r.squaredNorm() + reg_cost(*q);
  summary->initial_cost = cost;
  double mu = 1e-3, nu = 2;
  bool at_current = true;
  Eigen::MatrixXd j;
  summary->message = "max iterations";
  int it = 0;
  bool done = false;
  for (; it < options.max_iterations && !done; ++it) {
    if (!at_current) HC_RETURN_IF_ERROR(problem.residual(*q, &r));
    at_current = true;
    HC_RETURN_IF_ERROR(problem.jacobian(*q, &j));
    Eigen::VectorXd g = j.transpose() * r;
    if (has_reg) g += reg.transpose() * reg_residual(*q);
    Eigen::VectorXd diag = j.colwise().squaredNorm().transpose();
    if (has_reg) diag += rtr.diagonal();
    const double diag_floor = 1e-12 * std::max(diag.maxCoeff(), 1e-300);
    for (Eigen::Index i = 0; i < n; ++i) diag(i) = std::max(diag(i), diag_floor);

    const bool dense = n <= options.dense_parameter_limit;
    Eigen::MatrixXd a;
    if (dense) {
      a = Eigen::MatrixXd::Zero(n, n);
      a.selfadjointView<Eigen::Lower>().rankUpdate(j.transpose());
      a.triangularView<Eigen::Upper>() = a.transpose();
      if (has_reg) a += Eigen::MatrixXd(rtr);
    }
    bool accepted = false;
    for (int attempt = 0; attempt < 30 && !accepted; ++attempt) {
      Eigen::VectorXd delta;
      if (dense) {
        Eigen::MatrixXd am = a;
        am.diagonal() += mu * diag;
        Eigen::LLT<Eigen::MatrixXd> llt(am);
        if (llt.info() != Eigen::Success) {
          mu *= nu;
          nu *= 2;
          continue;
        }
        delta = llt.solve(-g);
      } else {
        // Matrix-free Jacobi-preconditioned CG on (JᵀJ + RᵀR + μD) δ = −g.
        const Eigen::VectorXd precond =
            (j.colwise().squaredNorm().transpose() +
             (has_reg ? Eigen::VectorXd(rtr.diagonal()) : Eigen::VectorXd::Zero(n)) + mu * diag)
                .cwiseMax(1e-300)
                .cwiseInverse();
        const auto apply = [&](const Eigen::VectorXd& v) {
          Eigen::VectorXd out = j.transpose() * (j * v);
          if (has_reg) out += rtr * v;
          out += mu * diag.cwiseProduct(v);
          return out;
        };
        delta = Eigen::VectorXd::Zero(n);
        Eigen::VectorXd res = -g;
        Eigen::VectorXd z = precond.cwiseProduct(res);
        Eigen::VectorXd pdir = z;
        double rz = res.dot(z);
        const double stop =
            options.cg_relative_tolerance * options.cg_relative_tolerance * g.squaredNorm();
        for (int k = 0; k < options.cg_max_iterations && res.squaredNorm() > stop; ++k) {
          const Eigen::VectorXd ap = apply(pdir);
          const double step = rz / pdir.dot(ap);
          delta += step * pdir;
          res -= step * ap;
          z = precond.cwiseProduct(res);
          const double rz_new = res.dot(z);
          pdir = z + (rz_new / rz) * pdir;
          rz = rz_new;
        }
      }
      const double predicted = -delta.dot(g) + mu * delta.dot(diag.cwiseProduct(delta));
      const Eigen::VectorXd trial = *q + delta;
      Eigen::VectorXd r_trial;
      Status st = problem.residual(trial, &r_trial);
      at_current = false;
      const double cost_trial = st.ok() ? r_trial.squaredNorm() + reg_cost(trial) : INFINITY;
      const double rho = (cost - cost_trial) / std::max(predicted, 1e-300);
      if (st.ok() && cost_trial < cost) {
        const double decrease = (cost - cost_trial) / std::max(cost, 1e-300);
        const bool small_step =
            delta.norm() <= options.parameter_tolerance * (q->norm() + options.parameter_tolerance);
        *q = trial;
        r = r_trial;
        cost = cost_trial;
        at_current = true;
        accepted = true;
        mu *= std::max(1.0 / 3.0, 1.0 - std::pow(2 * rho - 1, 3));
        nu = 2;
        if (decrease < options.function_tolerance) {
          summary->message = "function tolerance";
          done = true;
        } else if (small_step) {
          summary->message = "parameter tolerance";
          done = true;
        }
      } else {
        mu *= nu;
        nu *= 2;
      }
    }
    if (!accepted) {
      summary->message = "no decrease found (converged to machine precision)";
      break;
    }
  }
  summary->iterations = it;
  if (!at_current) HC_RETURN_IF_ERROR(problem.residual(*q, &r));
  summary->final_cost = cost;
  summary->usable = std::isfinite(cost);
  return {};
}

void error_stats(const Eigen::VectorXd& r_m, double* rms, double* max) {
  const Eigen::Index nodes = r_m.size() / 3;
  double sum = 0, mx = 0;
  for (Eigen::Index i = 0; i < nodes; ++i) {
    const double d = r_m.segment<3>(3 * i).norm();
    sum += d * d;
    mx = std::max(mx, d);
  }
  *rms = nodes ? std::sqrt(sum / static_cast<double>(nodes)) : 0.0;
  *max = mx;
}

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

  LmProblem lm;
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
  HC_RETURN_IF_ERROR(run_lm(lm, options, &q, s));
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

Status fit_example(ExampleProblem* problem, const std::vector<LambdaAlpha>& initial,
                   const ParameterFitOptions& options, std::vector<LambdaAlpha>* params,
                   ParameterFitSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  const auto t0 = Clock::now();
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
  const Eigen::SparseMatrix<double> laplacian = tet_umbrella_laplacian(problem->mesh());
  ParameterFitSummary local;
  ParameterFitSummary* s = summary ? summary : &local;
  *s = ParameterFitSummary{};
  if (options.backend == FitBackend::kCeres) {
    HC_RETURN_IF_ERROR(fit_example_ceres(problem, laplacian, rp, options, &q, s));
  } else {
    LmProblem lm;
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
      lm.reg_target = Eigen::VectorXd::Zero(rows + t);
      const double q1 = rp.to_q({1.0, options.initial_poisson})(1);
      for (Eigen::Index e = 0; e < t; ++e) {
        trip.emplace_back(static_cast<int>(rows + e), static_cast<int>(2 * e + 1), w);
        lm.reg_target(rows + e) = w * q1;
      }
      rows += t;
    }
    lm.reg.resize(rows, 2 * t);
    lm.reg.setFromTriplets(trip.begin(), trip.end());
    HC_RETURN_IF_ERROR(run_lm(lm, options, &q, s));
  }
  *params = params_of(rp, q);
  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(problem->simulate(*params, &r));
  error_stats(r, &s->rms_error_m, &s->max_error_m);
  s->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return {};
}

Status JointRefinementOptions::validate() const {
  if (!(regularization_scale >= 0) || !std::isfinite(regularization_scale))
    return invalid_argument("joint.regularization_scale: must be >= 0");
  if (max_iterations < 1) return invalid_argument("joint.max_iterations: must be >= 1");
  if (!(stiffening_regularization_scale >= 0) || !std::isfinite(stiffening_regularization_scale))
    return invalid_argument("joint.stiffening_regularization_scale: must be >= 0");
  if (passes < 1) return invalid_argument("joint.passes: must be >= 1");
  if (!(function_tolerance >= 0)) return invalid_argument("joint.function_tolerance: must be >= 0");
  if (!(max_jacobian_bytes > 0)) return invalid_argument("joint.max_jacobian_bytes: must be > 0");
  return {};
}

Result<Material> fit_joint_material(const std::vector<ExampleProblem*>& problems,
                                    std::vector<Eigen::Matrix<double, Eigen::Dynamic, 6>>* strains,
                                    const std::vector<std::vector<LambdaAlpha>>& start,
                                    const ParameterFitOptions& parameters,
                                    const JointRefinementOptions& options,
                                    ParameterFitSummary* summary) {
  HC_RETURN_IF_ERROR(parameters.validate());
  HC_RETURN_IF_ERROR(options.validate());
  if (problems.empty()) return invalid_argument("fit_joint_material: no examples");
  const std::size_t n = problems.size();
  if (strains->size() != n || start.size() != n)
    return invalid_argument("fit_joint_material: one strain matrix and start per example expected");
  const auto t0 = Clock::now();
  std::optional<fem::SingleThreadedBlasScope> blas;  // as in fit_heterogeneous (pipeline.cpp)
  if (n > 1) blas.emplace();
  const Eigen::Index t = problems[0]->num_elements();
  for (std::size_t i = 0; i < n; ++i)
    if (problems[i]->num_elements() != t || (*strains)[i].rows() != t ||
        static_cast<Eigen::Index>(start[i].size()) != t)
      return invalid_argument(fmt::format("fit_joint_material: example {} differs in mesh", i));
  const Reparam rp{parameters.max_poisson};
  const double nu_max = parameters.max_poisson;
  // The strain-dependent factor is kept above this (λ > 0 for any k).
  constexpr double kMinFactor = 0.5;  // see fit.h

  const Eigen::Index np = options.parameters_per_tet();
  // Start: per element the geometric mean λ and the mean logit ν of the per-example estimates.
  Eigen::VectorXd x = Eigen::VectorXd::Zero(np * t);
  for (Eigen::Index e = 0; e < t; ++e) {
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d q = rp.to_q(start[i][static_cast<std::size_t>(e)]);
      x(np * e) += q(0) / static_cast<double>(n);
      x(np * e + 1) += q(1) / static_cast<double>(n);
    }
  }
  double eps_ref = 0;
  for (std::size_t i = 0; i < n; ++i)
    if ((*strains)[i].rows() > 0)
      eps_ref = std::max(eps_ref, (*strains)[i].rowwise().norm().maxCoeff());
  if (!(eps_ref > 0)) eps_ref = 1;
  // The quadratic feature h(ε) = (Σ_k ‖ε − c e_k‖ + ‖ε + c e_k‖ − 12 c) / (5 ε_ref), c = ε_ref,
  // e_k the 6 unit strain axes: ≈ ‖ε‖² / ε_ref² for ‖ε‖ ≪ c in every direction (the 12 terms'
  // second-order parts sum to 5 ‖ε‖² / c), ≈ 2.4 ‖ε‖ / ε_ref − 2.4 for ‖ε‖ ≫ c.
  const double c_quad = eps_ref;
  const auto quad_feature = [&](const Vector6d& eps) {
    double g = 0;
    for (int k = 0; k < 6; ++k) {
      Vector6d d = eps;
      d(k) -= c_quad;
      g += d.norm();
      d(k) += 2 * c_quad;
      g += d.norm();
    }
    return (g - 12 * c_quad) / (5 * eps_ref);
  };
  std::vector<Eigen::VectorXd> r_norm(n, Eigen::VectorXd(t)), h_quad(n, Eigen::VectorXd(t));
  const auto update_features = [&](std::size_t i) {
    for (Eigen::Index e = 0; e < t; ++e) {
      const Vector6d eps = (*strains)[i].row(e).transpose();
      r_norm[i](e) = eps.norm() / eps_ref;
      h_quad[i](e) = quad_feature(eps);
    }
  };
  for (std::size_t i = 0; i < n; ++i) update_features(i);
  // The unfloored strain factor 1 + k ‖ε‖/ε_ref [+ m h(ε)].
  const auto raw_factor = [&](const Eigen::VectorXd& v, std::size_t i, Eigen::Index e) {
    double f = 1.0 + v(np * e + 2) * r_norm[i](e);
    if (np == 4) f += v(np * e + 3) * h_quad[i](e);
    return f;
  };

  const auto params_at = [&](const Eigen::VectorXd& v, std::size_t i, std::vector<LambdaAlpha>* p) {
    p->resize(static_cast<std::size_t>(t));
    for (Eigen::Index e = 0; e < t; ++e) {
      const double factor = std::max(raw_factor(v, i, e), kMinFactor);
      const double l = std::exp(v(np * e)) * factor;
      (*p)[static_cast<std::size_t>(e)] = {l, l * nu_max * sigmoid(v(np * e + 1))};
    }
  };
  Eigen::Index rows = 0;
  std::vector<Eigen::Index> offset(n);
  for (std::size_t i = 0; i < n; ++i) {
    offset[i] = rows;
    rows += problems[i]->num_measurements();
  }
  // The stacked Jacobian is dense (rows × np T); refuse what would not fit in memory rather than
  // fail in the allocator (the thesis-scale foam, 48 examples on 1,805 tets, would need ~8 GB).
  const double jacobian_bytes = 8.0 * static_cast<double>(rows) * static_cast<double>(np * t);
  if (jacobian_bytes > options.max_jacobian_bytes)
    return failed_precondition(fmt::format(
        "fit_joint_material: the joint Jacobian would take {:.1f} GB (limit {:.1f} GB); use "
        "fewer examples or the per-example pipeline",
        jacobian_bytes / 1e9, options.max_jacobian_bytes / 1e9));
  LmProblem lm;
  lm.residual = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r) -> Status {
    r->resize(rows);
    std::vector<Status> st(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      std::vector<LambdaAlpha> p;
      params_at(v, i, &p);
      Eigen::VectorXd ri;
      st[i] = problems[i]->simulate(p, &ri);
      if (st[i].ok()) r->segment(offset[i], ri.size()) = ri / problems[i]->scale_m();
    });
    for (const Status& s : st) HC_RETURN_IF_ERROR(s);
    return {};
  };
  lm.jacobian = [&](const Eigen::VectorXd& v, Eigen::MatrixXd* j) -> Status {
    j->resize(rows, np * t);
    std::vector<Status> st(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      Eigen::MatrixXd ji;
      st[i] = problems[i]->jacobian(&ji);
      if (!st[i].ok()) return;
      ji /= problems[i]->scale_m();
      auto out = j->middleRows(offset[i], ji.rows());
      for (Eigen::Index e = 0; e < t; ++e) {
        const double raw = raw_factor(v, i, e);
        const double factor = std::max(raw, kMinFactor);
        const double l0 = std::exp(v(np * e));
        const double sg = sigmoid(v(np * e + 1));
        const double nu = nu_max * sg;
        const double l = l0 * factor;
        const auto dl = ji.col(2 * e), da = ji.col(2 * e + 1);
        out.col(np * e) = l * (dl + nu * da);
        out.col(np * e + 1) = l * nu_max * sg * (1 - sg) * da;
        if (raw > kMinFactor) {
          out.col(np * e + 2) = l0 * r_norm[i](e) * (dl + nu * da);
          if (np == 4) out.col(np * e + 3) = l0 * h_quad[i](e) * (dl + nu * da);
        } else {
          out.middleCols(np * e + 2, np - 2).setZero();
        }
      }
    });
    for (const Status& s : st) HC_RETURN_IF_ERROR(s);
    return {};
  };
  // n γ ‖L c‖² per channel c (each example's Eq. 4.10 regulariser, summed), the Poisson prior.
  const Eigen::SparseMatrix<double> laplacian =
      tet_umbrella_laplacian(problems[0]->mesh(), options.adjacency);
  const double gamma = options.regularization_scale * parameters.regularization;
  const double sg = std::sqrt(gamma * static_cast<double>(n));
  const double k_weight = std::sqrt(options.stiffening_regularization_scale);
  std::vector<Eigen::Triplet<double>> trip;
  std::vector<double> target;
  Eigen::Index reg_rows = 0;
  if (gamma > 0) {
    for (Eigen::Index k = 0; k < laplacian.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, k); it; ++it)
        for (Eigen::Index c = 0; c < np; ++c)
          trip.emplace_back(static_cast<int>(np * it.row() + c),
                            static_cast<int>(np * it.col() + c),
                            sg * it.value() * (c >= 2 ? k_weight : 1.0));
    reg_rows = np * t;
    target.assign(static_cast<std::size_t>(reg_rows), 0.0);
  }
  if (parameters.poisson_prior > 0) {
    const double w = std::sqrt(parameters.poisson_prior * static_cast<double>(n));
    const double q1 = rp.to_q({1.0, parameters.initial_poisson})(1);
    for (Eigen::Index e = 0; e < t; ++e) {
      trip.emplace_back(static_cast<int>(reg_rows + e), static_cast<int>(np * e + 1), w);
      target.push_back(w * q1);
    }
    reg_rows += t;
  }
  lm.reg.resize(reg_rows, np * t);
  lm.reg.setFromTriplets(trip.begin(), trip.end());
  lm.reg_target =
      Eigen::Map<const Eigen::VectorXd>(target.data(), static_cast<Eigen::Index>(target.size()));
  ParameterFitOptions lm_options = parameters;
  lm_options.max_iterations = options.max_iterations;
  lm_options.function_tolerance = options.function_tolerance;
  ParameterFitSummary local;
  ParameterFitSummary* s = summary ? summary : &local;
  int iterations = 0;
  for (int pass = 0; pass < options.passes; ++pass) {
    if (pass > 0) {
      // Strains under the current material (fixed-point sweeps as in evaluation).
      std::vector<Status> st(n);
      tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        std::vector<LambdaAlpha> p;
        for (int sweep = 0; sweep < 3 && st[i].ok(); ++sweep) {
          params_at(x, i, &p);
          Eigen::VectorXd r;
          st[i] = problems[i]->simulate(p, &r);
          if (!st[i].ok()) break;
          (*strains)[i] = problems[i]->strains();
          update_features(i);
          // The next LM pass linearises at the model's own configuration, not the noisy
          // measured one (noise study with the vertex stencil, mean of 5 noise seeds: 10 % 2.31
          // -> 2.21 %, 20 % 3.73 -> 3.35 %, 30 % 4.58 -> 4.04 %).
          problems[i]->update_rotations();
        }
      });
      for (const Status& e : st) HC_RETURN_IF_ERROR(e);
    }
    *s = ParameterFitSummary{};
    HC_RETURN_IF_ERROR(run_lm(lm, lm_options, &x, s));
    iterations += s->iterations;
  }
  s->iterations = iterations;

  Material material;
  material.kind = MaterialKind::kHeterogeneous;
  material.rbfs.resize(static_cast<std::size_t>(t));
  for (Eigen::Index e = 0; e < t; ++e) {
    StrainRbf& rbf = material.rbfs[static_cast<std::size_t>(e)];
    const double l0 = std::exp(x(np * e));
    const double nu = nu_max * sigmoid(x(np * e + 1));
    const double w = l0 * x(np * e + 2) / eps_ref;
    rbf.centres = {Vector6d::Zero()};
    rbf.weights.resize(np == 4 ? 13 : 1, 2);
    rbf.weights.row(0) << w, nu * w;
    double constant = l0;
    if (np == 4) {
      // m h(ε) as 12 more centres ±c e_k with equal weights m l0 / (5 ε_ref).
      const double m = x(np * e + 3);
      const double wq = l0 * m / (5 * eps_ref);
      for (int k = 0; k < 6; ++k)
        for (const double sign : {-1.0, 1.0}) {
          Vector6d centre = Vector6d::Zero();
          centre(k) = sign * c_quad;
          rbf.centres.push_back(centre);
          rbf.weights.row(static_cast<Eigen::Index>(rbf.centres.size()) - 1) << wq, nu * wq;
        }
      constant -= 12 * c_quad * wq;
    }
    rbf.constant = Eigen::Vector2d(constant, nu * constant);
    rbf.lambda_floor_pa = kMinFactor * l0;
    rbf.max_poisson = nu_max;
  }
  double sum = 0, mx = 0;
  Eigen::Index nodes = 0;
  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(lm.residual(x, &r));
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Index m = problems[i]->num_measurements();
    double rms = 0, emax = 0;
    error_stats(r.segment(offset[i], m) * problems[i]->scale_m(), &rms, &emax);
    sum += rms * rms * static_cast<double>(m / 3);
    nodes += m / 3;
    mx = std::max(mx, emax);
  }
  s->rms_error_m = std::sqrt(sum / static_cast<double>(std::max<Eigen::Index>(nodes, 1)));
  s->max_error_m = mx;
  s->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return material;
}

}  // namespace hc::material
