// The joint material fit (fit.h, fit_joint_material): one material fitted to all examples at once,
// with the own LM (lm.h) dense on small problems and matrix-free on large ones.
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>

#include "lm.h"
#include "processing/fem/blas_threads.h"
#include "processing/material/fit.h"

namespace hc::material {
namespace {

using Clock = std::chrono::steady_clock;
using Strains = Eigen::Matrix<double, Eigen::Dynamic, 6>;
using detail::sigmoid;
// The strain-dependent factor is kept above this (λ > 0 for any k; fit.h).
constexpr double kMinFactor = 0.5;

// The material's parameters per element, v_e = (ln λ0, logit(ν/ν_max), k[, m]), and each example's
// strain features ‖ε‖/ε_ref and h(ε).
struct JointModel {
  Eigen::Index t = 0;
  Eigen::Index np = 4;
  double nu_max = 0;
  double eps_ref = 1;
  std::vector<Eigen::VectorXd> r_norm, h_quad;

  // h(ε) = (Σ_k ‖ε − c e_k‖ + ‖ε + c e_k‖ − 12 c) / (5 ε_ref), c = ε_ref, e_k the 6 unit strain
  // axes: ≈ ‖ε‖² / ε_ref² for ‖ε‖ ≪ c in every direction (the 12 terms' second-order parts sum to
  // 5 ‖ε‖² / c), ≈ 2.4 ‖ε‖ / ε_ref − 2.4 for ‖ε‖ ≫ c.
  double quad_feature(const Vector6d& eps) const {
    double g = 0;
    for (int k = 0; k < 6; ++k) {
      Vector6d d = eps;
      d(k) -= eps_ref;
      g += d.norm();
      d(k) += 2 * eps_ref;
      g += d.norm();
    }
    return (g - 12 * eps_ref) / (5 * eps_ref);
  }
  void update_features(std::size_t i, const Strains& strains) {
    r_norm[i].resize(t);
    h_quad[i].resize(t);
    for (Eigen::Index e = 0; e < t; ++e) {
      const Vector6d eps = strains.row(e).transpose();
      r_norm[i](e) = eps.norm() / eps_ref;
      h_quad[i](e) = quad_feature(eps);
    }
  }
  // The unfloored strain factor 1 + k ‖ε‖/ε_ref [+ m h(ε)].
  double raw_factor(const Eigen::VectorXd& v, std::size_t i, Eigen::Index e) const {
    double f = 1.0 + v(np * e + 2) * r_norm[i](e);
    if (np == 4) f += v(np * e + 3) * h_quad[i](e);
    return f;
  }
  void params_at(const Eigen::VectorXd& v, std::size_t i, std::vector<LambdaAlpha>* p) const {
    p->resize(static_cast<std::size_t>(t));
    for (Eigen::Index e = 0; e < t; ++e) {
      const double l = std::exp(v(np * e)) * std::max(raw_factor(v, i, e), kMinFactor);
      (*p)[static_cast<std::size_t>(e)] = {l, l * nu_max * sigmoid(v(np * e + 1))};
    }
  }
  // ∂(λ_e, α_e)/∂v_e for example i (2 × np; the stiffening columns vanish where the floor holds).
  Eigen::Matrix<double, 2, 4> chain(const Eigen::VectorXd& v, std::size_t i, Eigen::Index e) const {
    const double raw = raw_factor(v, i, e);
    const double l0 = std::exp(v(np * e));
    const double sg = sigmoid(v(np * e + 1));
    const double nu = nu_max * sg;
    const double l = l0 * std::max(raw, kMinFactor);
    Eigen::Matrix<double, 2, 4> c = Eigen::Matrix<double, 2, 4>::Zero();
    c.col(0) << l, nu * l;
    c(1, 1) = l * nu_max * sg * (1 - sg);
    if (raw > kMinFactor) {
      c.col(2) << l0 * r_norm[i](e), nu * l0 * r_norm[i](e);
      if (np == 4) c.col(3) << l0 * h_quad[i](e), nu * l0 * h_quad[i](e);
    }
    return c;
  }
  Material to_material(const Eigen::VectorXd& v) const;
};

Material JointModel::to_material(const Eigen::VectorXd& x) const {
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
      const double wq = l0 * x(np * e + 3) / (5 * eps_ref);
      for (int k = 0; k < 6; ++k)
        for (const double sign : {-1.0, 1.0}) {
          Vector6d centre = Vector6d::Zero();
          centre(k) = sign * eps_ref;
          rbf.centres.push_back(centre);
          rbf.weights.row(static_cast<Eigen::Index>(rbf.centres.size()) - 1) << wq, nu * wq;
        }
      constant -= 12 * eps_ref * wq;
    }
    rbf.constant = Eigen::Vector2d(constant, nu * constant);
    rbf.lambda_floor_pa = kMinFactor * l0;
    rbf.max_poisson = nu_max;
  }
  return material;
}

// The stacked Jacobian of all examples' scaled residuals with respect to the material parameters,
// matrix-free: example i's block is J_i C_i / s_i with J_i its Appendix A Jacobian (products by
// one solve each, ExampleProblem) and C_i the chain from v to its (λ, α).
class JointOperator final : public detail::JacobianOperator {
 public:
  JointOperator(const std::vector<ExampleProblem*>& problems,
                const std::vector<Eigen::Index>& offset, const JointModel& model,
                const Eigen::VectorXd& v)
      : problems_(problems), offset_(offset), model_(model) {
    const std::size_t n = problems.size();
    chain_.resize(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      chain_[i].resize(static_cast<std::size_t>(model.t));
      for (Eigen::Index e = 0; e < model.t; ++e)
        chain_[i][static_cast<std::size_t>(e)] = model.chain(v, i, e);
    });
  }
  Status apply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const override {
    const std::size_t n = problems_.size();
    out->resize(offset_.back());
    std::vector<Status> st(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      Eigen::VectorXd vp(2 * model_.t), ji;
      for (Eigen::Index e = 0; e < model_.t; ++e)
        vp.segment<2>(2 * e) = chain_[i][static_cast<std::size_t>(e)].leftCols(model_.np) *
                               v.segment(model_.np * e, model_.np);
      st[i] = problems_[i]->apply_jacobian(vp, &ji);
      if (st[i].ok())
        out->segment(offset_[i], ji.size()) = ji / problems_[i]->scale_m();
    });
    for (const Status& s : st) HC_RETURN_IF_ERROR(s);
    return {};
  }
  Status apply_transpose(const Eigen::MatrixXd& w, Eigen::MatrixXd* out) const override {
    const std::size_t n = problems_.size();
    std::vector<Eigen::MatrixXd> parts(n);
    std::vector<Status> st(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      const Eigen::Index m = problems_[i]->num_measurements();
      Eigen::MatrixXd jp;
      st[i] = problems_[i]->apply_jacobian_transpose(w.middleRows(offset_[i], m), &jp);
      if (!st[i].ok()) return;
      parts[i].resize(model_.np * model_.t, w.cols());
      for (Eigen::Index e = 0; e < model_.t; ++e)
        parts[i].middleRows(model_.np * e, model_.np) =
            chain_[i][static_cast<std::size_t>(e)].leftCols(model_.np).transpose() *
            jp.middleRows(2 * e, 2) / problems_[i]->scale_m();
    });
    for (const Status& s : st) HC_RETURN_IF_ERROR(s);
    *out = Eigen::MatrixXd::Zero(model_.np * model_.t, w.cols());
    for (const Eigen::MatrixXd& p : parts) *out += p;
    return {};
  }

 private:
  const std::vector<ExampleProblem*>& problems_;
  const std::vector<Eigen::Index>& offset_;  // n + 1 row offsets
  const JointModel& model_;
  std::vector<std::vector<Eigen::Matrix<double, 2, 4>>> chain_;
};

// n γ_J ‖L_F c‖² per channel c (κ on the stiffening channels) and the Poisson prior, as rows of R
// (already scaled) and the target b of ‖R v − b‖².
void joint_regularizer(const TetMesh& mesh, std::size_t n, const ParameterFitOptions& parameters,
                       const JointRefinementOptions& options, Eigen::Index np,
                       Eigen::SparseMatrix<double>* reg, Eigen::VectorXd* target) {
  const Eigen::Index t = mesh.num_tets();
  const Eigen::SparseMatrix<double> laplacian = tet_umbrella_laplacian(mesh, options.adjacency);
  const double gamma = options.regularization_scale * parameters.regularization;
  const double sg = std::sqrt(gamma * static_cast<double>(n));
  const double k_weight = std::sqrt(options.stiffening_regularization_scale);
  std::vector<Eigen::Triplet<double>> trip;
  std::vector<double> b;
  Eigen::Index rows = 0;
  if (gamma > 0) {
    for (Eigen::Index k = 0; k < laplacian.outerSize(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, k); it; ++it)
        for (Eigen::Index c = 0; c < np; ++c)
          trip.emplace_back(static_cast<int>(np * it.row() + c), static_cast<int>(np * it.col() + c),
                            sg * it.value() * (c >= 2 ? k_weight : 1.0));
    rows = np * t;
    b.assign(static_cast<std::size_t>(rows), 0.0);
  }
  if (parameters.poisson_prior > 0) {
    const double w = std::sqrt(parameters.poisson_prior * static_cast<double>(n));
    const double q1 =
        detail::Reparam{parameters.max_poisson}.to_q({1.0, parameters.initial_poisson})(1);
    for (Eigen::Index e = 0; e < t; ++e) {
      trip.emplace_back(static_cast<int>(rows + e), static_cast<int>(np * e + 1), w);
      b.push_back(w * q1);
    }
    rows += t;
  }
  reg->resize(rows, np * t);
  reg->setFromTriplets(trip.begin(), trip.end());
  *target = Eigen::Map<const Eigen::VectorXd>(b.data(), static_cast<Eigen::Index>(b.size()));
}

// Each example simulated with the current material in co-rotational sweeps (as in evaluation);
// its strains and features follow, and its rotations are re-frozen at the model's own
// configuration for the next LM pass instead of the noisy measured one (noise study with the
// vertex stencil, mean of 5 noise seeds: 10 % 2.31 -> 2.21 %, 20 % 3.73 -> 3.35 %, 30 % 4.58 ->
// 4.04 %).
Status update_strains(const std::vector<ExampleProblem*>& problems, const Eigen::VectorXd& x,
                      JointModel* model, std::vector<Strains>* strains) {
  const std::size_t n = problems.size();
  std::vector<Status> st(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    std::vector<LambdaAlpha> p;
    for (int sweep = 0; sweep < 3 && st[i].ok(); ++sweep) {
      model->params_at(x, i, &p);
      Eigen::VectorXd r;
      st[i] = problems[i]->simulate(p, &r);
      if (!st[i].ok()) break;
      (*strains)[i] = problems[i]->strains();
      model->update_features(i, (*strains)[i]);
      problems[i]->update_rotations();
    }
  });
  for (const Status& e : st) HC_RETURN_IF_ERROR(e);
  return {};
}

}  // namespace

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
  JointModel model;
  model.t = problems[0]->num_elements();
  model.np = options.parameters_per_tet();
  model.nu_max = parameters.max_poisson;
  const Eigen::Index t = model.t, np = model.np;
  for (std::size_t i = 0; i < n; ++i)
    if (problems[i]->num_elements() != t || (*strains)[i].rows() != t ||
        static_cast<Eigen::Index>(start[i].size()) != t)
      return invalid_argument(fmt::format("fit_joint_material: example {} differs in mesh", i));
  // Start: per element the geometric mean λ and the mean logit ν of the per-example estimates.
  const detail::Reparam rp{parameters.max_poisson};
  Eigen::VectorXd x = Eigen::VectorXd::Zero(np * t);
  for (Eigen::Index e = 0; e < t; ++e)
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d q = rp.to_q(start[i][static_cast<std::size_t>(e)]);
      x(np * e) += q(0) / static_cast<double>(n);
      x(np * e + 1) += q(1) / static_cast<double>(n);
    }
  model.eps_ref = 0;
  for (std::size_t i = 0; i < n; ++i)
    if ((*strains)[i].rows() > 0)
      model.eps_ref = std::max(model.eps_ref, (*strains)[i].rowwise().norm().maxCoeff());
  if (!(model.eps_ref > 0)) model.eps_ref = 1;
  model.r_norm.resize(n);
  model.h_quad.resize(n);
  for (std::size_t i = 0; i < n; ++i) model.update_features(i, (*strains)[i]);
  std::vector<Eigen::Index> offset(n + 1, 0);
  double factor_entries = 0;
  for (std::size_t i = 0; i < n; ++i) {
    offset[i + 1] = offset[i] + problems[i]->num_measurements();
    factor_entries = std::max(factor_entries, problems[i]->factor_entries());
  }
  const Eigen::Index rows = offset[n];

  detail::LmProblem lm;
  lm.rows = rows;
  lm.block = static_cast<int>(np);
  lm.product_flops = detail::solve_flops(factor_entries) * static_cast<double>(n);  // per example
  lm.progress = options.progress;
  lm.matrix_free = !detail::prefer_dense(static_cast<double>(rows), static_cast<double>(np * t),
                                         factor_entries, static_cast<double>(n), parameters);
  // The dense path stores the stacked Jacobian (rows × np T): refuse what would not fit rather
  // than fail in the allocator.
  const double jacobian_bytes = 8.0 * static_cast<double>(rows) * static_cast<double>(np * t);
  if (!lm.matrix_free && jacobian_bytes > options.max_jacobian_bytes)
    return failed_precondition(fmt::format(
        "fit_joint_material: the dense joint Jacobian would take {:.1f} GB (limit {:.1f} GB); "
        "use the matrix-free solver (FitSolver::kMatrixFree, fit --solver matrix-free)",
        jacobian_bytes / 1e9, options.max_jacobian_bytes / 1e9));
  lm.residual = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r) -> Status {
    r->resize(rows);
    std::vector<Status> st(n);
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      std::vector<LambdaAlpha> p;
      model.params_at(v, i, &p);
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
      for (Eigen::Index e = 0; e < t; ++e)
        out.middleCols(np * e, np) =
            ji.middleCols(2 * e, 2) * model.chain(v, i, e).leftCols(np);
    });
    for (const Status& s : st) HC_RETURN_IF_ERROR(s);
    return {};
  };
  lm.jacobian_operator = [&](const Eigen::VectorXd& v)
      -> Result<std::unique_ptr<detail::JacobianOperator>> {
    return std::unique_ptr<detail::JacobianOperator>(
        std::make_unique<JointOperator>(problems, offset, model, v));
  };
  joint_regularizer(problems[0]->mesh(), n, parameters, options, np, &lm.reg, &lm.reg_target);
  ParameterFitOptions lm_options = parameters;
  lm_options.max_iterations = options.max_iterations;
  lm_options.function_tolerance = options.function_tolerance;
  ParameterFitSummary local;
  ParameterFitSummary* s = summary ? summary : &local;
  int iterations = 0;
  long cg_iterations = 0;
  for (int pass = 0; pass < options.passes; ++pass) {
    if (pass > 0) HC_RETURN_IF_ERROR(update_strains(problems, x, &model, strains));
    *s = ParameterFitSummary{};
    lm.progress_task = fmt::format("joint fit pass {}/{}", pass + 1, options.passes);
    HC_RETURN_IF_ERROR(detail::run_lm(lm, detail::lm_settings(lm_options), &x, s));
    iterations += s->iterations;
    cg_iterations += s->cg_iterations;
  }
  s->iterations = iterations;
  s->cg_iterations = cg_iterations;
  Material material = model.to_material(x);
  double sum = 0, mx = 0;
  Eigen::Index nodes = 0;
  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(lm.residual(x, &r));
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Index m = problems[i]->num_measurements();
    double rms = 0, emax = 0;
    detail::error_stats(r.segment(offset[i], m) * problems[i]->scale_m(), &rms, &emax);
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
