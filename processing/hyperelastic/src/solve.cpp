// Static equilibrium by Newton's method with a backtracking line search, and probe indentation.
#include <fmt/format.h>

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "common/clock.h"
#include "processing/hyperelastic/neo_hookean.h"

namespace hc::hyperelastic {
namespace {

constexpr double kNoEnergy = std::numeric_limits<double>::infinity();

using Clock = std::chrono::steady_clock;
// Total potential Π = elastic − fᵀx + Σ contact, its gradient and (optionally) the Hessian.
struct Potential {
  const NeoHookeanModel& model;
  const Boundary& boundary;

  double value(const Eigen::VectorXd& x, Eigen::VectorXd* g, Eigen::SparseMatrix<double>* H,
               bool project, double* elastic_scale) const {
    double e = model.energy_gradient_hessian(x, g, H, project);
    if (!std::isfinite(e)) return kNoEnergy;
    if (elastic_scale != nullptr) *elastic_scale = g->cwiseAbs().maxCoeff();
    if (boundary.external_forces_n.size() > 0) {
      e -= boundary.external_forces_n.dot(x);
      if (g != nullptr) *g -= boundary.external_forces_n;
    }
    if (!boundary.contacts.empty()) {
      std::vector<Eigen::Triplet<double>> trip;
      for (const ContactPotential* c : boundary.contacts)
        e += c->energy(x, g, H != nullptr ? &trip : nullptr, project);
      if (H != nullptr && !trip.empty()) {
        Eigen::SparseMatrix<double> C(H->rows(), H->cols());
        C.setFromTriplets(trip.begin(), trip.end());
        *H += C;
      }
    }
    return e;
  }
};

// Picks the free rows/columns of a full 3N×3N matrix (lower triangle only, which CHOLMOD reads).
Eigen::SparseMatrix<double> reduce_lower(const Eigen::SparseMatrix<double>& H,
                                         const std::vector<int>& free_index, Eigen::Index nfree) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(H.nonZeros() / 2 + H.rows()));
  for (int k = 0; k < H.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(H, k); it; ++it) {
      const int r = free_index[static_cast<std::size_t>(it.row())];
      const int c = free_index[static_cast<std::size_t>(it.col())];
      if (r >= 0 && c >= 0 && r >= c) t.emplace_back(r, c, it.value());
    }
  Eigen::SparseMatrix<double> R(nfree, nfree);
  R.setFromTriplets(t.begin(), t.end());
  return R;
}

// Per DOF, whether it is held: nodes in no tet, fixed nodes and fixed DOFs. invalid_argument for a
// node or DOF out of range.
Result<std::vector<bool>> fixed_dofs(const NeoHookeanModel& model, const Boundary& boundary) {
  const Eigen::Index ndof = model.num_dofs();
  std::vector<bool> fixed(static_cast<std::size_t>(ndof), true);
  const TetMesh& mesh = model.mesh();
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)  // nodes in no tet stay fixed
    for (int k = 0; k < 4; ++k)
      for (int a = 0; a < 3; ++a) fixed[static_cast<std::size_t>(3 * mesh.tets(t, k) + a)] = false;
  for (int i : boundary.fixed_nodes) {
    if (i < 0 || i >= mesh.num_nodes())
      return invalid_argument(fmt::format("fixed node {} out of range", i));
    for (int a = 0; a < 3; ++a) fixed[static_cast<std::size_t>(3 * i + a)] = true;
  }
  for (int d : boundary.fixed_dofs) {
    if (d < 0 || d >= ndof) return invalid_argument(fmt::format("fixed DOF {} out of range", d));
    fixed[static_cast<std::size_t>(d)] = true;
  }
  return fixed;
}

}  // namespace

std::string_view to_string(StopReason reason) {
  switch (reason) {
    case StopReason::kConverged:
      return "converged";
    case StopReason::kMaxIterations:
      return "max_iterations";
    case StopReason::kLineSearchFailed:
      return "line_search_failed";
    case StopReason::kFactorizationFailed:
      return "factorization_failed";
  }
  return "unknown";
}

Status validate(const SolveOptions& o) {
  if (o.max_newton_iterations < 1) return invalid_argument("max_newton_iterations must be >= 1");
  if (!(o.gradient_tolerance_n >= 0) || !(o.relative_gradient_tolerance >= 0) ||
      !(o.gradient_tolerance_n + o.relative_gradient_tolerance > 0))
    return invalid_argument("gradient tolerances must be >= 0 and not both 0");
  if (o.max_line_search_steps < 1) return invalid_argument("max_line_search_steps must be >= 1");
  if (!(o.armijo_c > 0 && o.armijo_c < 0.5))
    return invalid_argument("armijo_c must be in (0, 0.5)");
  return {};
}

Status solve_equilibrium(const NeoHookeanModel& model, const Boundary& boundary,
                         const SolveOptions& options, Eigen::VectorXd* x, SolveSummary* summary) {
  HC_RETURN_IF_ERROR(validate(options));
  const auto start = Clock::now();
  const Eigen::Index ndof = model.num_dofs();
  if (x == nullptr || x->size() != ndof)
    return invalid_argument(fmt::format("x must have {} entries (3 per node)", ndof));
  if (!x->allFinite()) return invalid_argument("start positions are not finite");
  if (boundary.external_forces_n.size() != 0 && boundary.external_forces_n.size() != ndof)
    return invalid_argument(fmt::format("external forces must have {} entries (3 per node), got {}",
                                        ndof, boundary.external_forces_n.size()));
  if (!boundary.external_forces_n.allFinite())
    return invalid_argument("an external force is not finite");
  HC_ASSIGN_OR_RETURN(const std::vector<bool> fixed, fixed_dofs(model, boundary));
  std::vector<int> free_index(static_cast<std::size_t>(ndof), -1);
  std::vector<int> free_dofs;
  for (Eigen::Index d = 0; d < ndof; ++d)
    if (!fixed[static_cast<std::size_t>(d)]) {
      free_index[static_cast<std::size_t>(d)] = static_cast<int>(free_dofs.size());
      free_dofs.push_back(static_cast<int>(d));
    }
  const auto nfree = static_cast<Eigen::Index>(free_dofs.size());

  SolveSummary sum;
  const Potential pot{model, boundary};
  Eigen::VectorXd g, gf(nfree), d(nfree), step(ndof), x_try;
  Eigen::SparseMatrix<double> H;
  double scale = 0;
  double e = pot.value(*x, &g, nullptr, false, &scale);
  if (!std::isfinite(e)) return invalid_argument("an element is inverted at the start positions");
  // CHOLMOD through Eigen; the symbolic analysis is done once, every iteration refactorizes.
  Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> chol;
  bool analysed = false;
  chol.cholmod().print = 0;  // "not positive definite" is expected and handled below
  const double f_scale =
      boundary.external_forces_n.size() > 0 ? boundary.external_forces_n.cwiseAbs().maxCoeff() : 0;
  sum.reason = StopReason::kMaxIterations;
  for (int it = 0; it < options.max_newton_iterations; ++it) {
    e = pot.value(*x, &g, &H, false, &scale);
    for (Eigen::Index i = 0; i < nfree; ++i) gf[i] = g[free_dofs[static_cast<std::size_t>(i)]];
    const double gnorm = nfree > 0 ? gf.cwiseAbs().maxCoeff() : 0.0;
    const double tol = options.gradient_tolerance_n +
                       options.relative_gradient_tolerance * std::max(scale, f_scale);
    NewtonIteration rec;
    rec.energy_j = e;
    rec.gradient_norm_n = gnorm;
    sum.final_energy_j = e;
    sum.final_gradient_norm_n = gnorm;
    if (gnorm <= tol) {
      sum.reason = StopReason::kConverged;
      break;
    }
    Eigen::SparseMatrix<double> R = reduce_lower(H, free_index, nfree);
    if (!analysed) {
      chol.analyzePattern(R);
      analysed = true;
    }
    chol.factorize(R);
    if (chol.info() != Eigen::Success) {
      // Not positive definite: the Hessian with every element block projected onto the PSD cone
      // (the pattern is the same, so the analysis is reused); then a growing diagonal shift.
      rec.projected = true;
      pot.value(*x, nullptr, &H, true, nullptr);
      R = reduce_lower(H, free_index, nfree);
      chol.factorize(R);
      double shift = 1e-8 * std::max(1.0, R.diagonal().cwiseAbs().maxCoeff());
      while (chol.info() != Eigen::Success && shift < 1e30) {
        Eigen::SparseMatrix<double> S = R;
        for (Eigen::Index i = 0; i < nfree; ++i) S.coeffRef(i, i) += shift;
        chol.factorize(S);
        shift *= 10;
      }
      if (chol.info() != Eigen::Success) {
        sum.reason = StopReason::kFactorizationFailed;
        sum.history.push_back(rec);
        break;
      }
    }
    d = chol.solve(-gf);
    double slope = gf.dot(d);
    if (!d.allFinite() || !(slope < 0)) {
      d = -gf;
      slope = -gf.squaredNorm();
    }
    step.setZero();
    for (Eigen::Index i = 0; i < nfree; ++i) step[free_dofs[static_cast<std::size_t>(i)]] = d[i];
    double alpha = 1.0;
    bool accepted = false;
    for (int ls = 0; ls < options.max_line_search_steps; ++ls, alpha *= 0.5) {
      x_try = *x + alpha * step;
      // The full step first with the contacts' second-order correction (ContactPotential::
      // correct_step): with a stiff penalty on a curved probe it is what lets Newton take full
      // steps (the simulated specimen's default location: 113 -> 39 Newton iterations, 17.3 ->
      // 4.4 s).
      if (ls == 0 && !boundary.contacts.empty()) {
        for (const ContactPotential* c : boundary.contacts) c->correct_step(*x, &x_try);
        for (Eigen::Index i = 0; i < ndof; ++i)
          if (fixed[static_cast<std::size_t>(i)]) x_try[i] = (*x)[i];
      }
      const double e_try = pot.value(x_try, nullptr, nullptr, false, nullptr);
      // Armijo, with slack for round-off once the decrease is at the level of the energy's
      // floating-point resolution (near convergence).
      const double slack = 1e-14 * (std::abs(e) + 1e-300);
      if (std::isfinite(e_try) && e_try <= e + options.armijo_c * alpha * slope + slack) {
        accepted = true;
        break;
      }
      // Near the solution the energy decrease of a Newton step (‖g‖²/k) falls below the
      // energy's round-off while the gradient can still be reduced: accept a full step that
      // halves the free gradient and does not raise the energy beyond round-off.
      if (alpha == 1.0 && std::isfinite(e_try) && e_try <= e + 1e-10 * std::abs(e)) {
        Eigen::VectorXd g_try;
        pot.value(x_try, &g_try, nullptr, false, nullptr);
        double gn = 0;
        for (int dof : free_dofs) gn = std::max(gn, std::abs(g_try[dof]));
        if (gn < 0.5 * gnorm) {
          accepted = true;
          break;
        }
      }
    }
    if (!accepted) {
      sum.reason = StopReason::kLineSearchFailed;
      sum.history.push_back(rec);
      break;
    }
    rec.step_length = alpha;
    sum.history.push_back(rec);
    *x = x_try;
    ++sum.iterations;
    if (options.progress != nullptr) options.progress->update(static_cast<std::uint64_t>(it + 1));
  }
  if (sum.reason == StopReason::kLineSearchFailed || sum.reason == StopReason::kMaxIterations) {
    // Round-off floor: accept when the gradient is within a few hundred times the tolerance.
    pot.value(*x, &g, nullptr, false, &scale);
    double gnorm = 0;
    for (int dof : free_dofs) gnorm = std::max(gnorm, std::abs(g[dof]));
    const double tol = options.gradient_tolerance_n +
                       options.relative_gradient_tolerance * std::max(scale, f_scale);
    sum.final_gradient_norm_n = gnorm;
    if (gnorm <= 100 * tol) sum.reason = StopReason::kConverged;
  }
  sum.time_s = seconds_since(start);
  if (summary != nullptr) *summary = std::move(sum);
  return {};
}

Status validate(const IndentOptions& o) {
  if (o.steps < 1) return invalid_argument(fmt::format("steps {} must be >= 1", o.steps));
  if (o.force_control) {
    if (!(std::isfinite(o.force_n) && o.force_n > 0))
      return invalid_argument(fmt::format("force {} N must be positive and finite", o.force_n));
  } else if (!(std::isfinite(o.depth_m) && o.depth_m >= 0)) {
    return invalid_argument(fmt::format("depth {} m must be >= 0 and finite", o.depth_m));
  }
  if (!(o.force_relative_tolerance > 0)) return invalid_argument("force tolerance must be > 0");
  if (o.max_force_iterations < 1) return invalid_argument("max_force_iterations must be >= 1");
  return validate(o.solve);
}

namespace {

// Equilibrium with the probe at `depth`; returns the probe force along its direction.
Result<double> force_at_depth(const NeoHookeanModel& model, const Boundary& boundary,
                              RigidProbe& probe, const SolveOptions& options, double depth,
                              Eigen::VectorXd* x, int* iterations) {
  probe.set_depth(depth);
  SolveSummary s;
  HC_RETURN_IF_ERROR(solve_equilibrium(model, boundary, options, x, &s));
  *iterations += s.iterations;
  if (!s.usable())
    return failed_precondition(
        fmt::format("no equilibrium at probe depth {} m: Newton stopped ({}) with gradient {} N",
                    depth, to_string(s.reason), s.final_gradient_norm_n));
  return contact_force(probe, *x).dot(probe.direction());
}

}  // namespace

Status indent(const NeoHookeanModel& model, const Boundary& boundary, RigidProbe& probe,
              const IndentOptions& options, Eigen::VectorXd* x, IndentSummary* summary) {
  HC_RETURN_IF_ERROR(validate(options));
  if (x == nullptr || x->size() != model.num_dofs())
    return invalid_argument("x must have 3 entries per node");
  const auto start = Clock::now();
  Boundary b = boundary;
  b.contacts.push_back(&probe);
  IndentSummary sum;
  const Eigen::VectorXd rest = *x;
  const double size =
      (model.mesh().nodes.colwise().maxCoeff() - model.mesh().nodes.colwise().minCoeff()).norm();
  double depth = probe.depth();
  double force = 0;
  double stiffness = 0;  // dF/dd estimate from the last step (N/m)
  auto fail = [&](const Status& s) {
    sum.usable = false;
    sum.message = s.message();
    sum.time_s = seconds_since(start);
    if (summary != nullptr) *summary = sum;
    return Status{};
  };
  for (int i = 1; i <= options.steps; ++i) {
    IndentStep st;
    if (!options.force_control) {
      const double target = options.depth_m * i / options.steps;
      Result<double> f =
          force_at_depth(model, b, probe, options.solve, target, x, &st.newton_iterations);
      if (!f.ok()) return fail(f.status());
      depth = target;
      force = *f;
    } else {
      // Root of F(d) − target, bracketed: `lo` is the deepest depth known to give less than the
      // target (its equilibrium warm-starts every trial), `hi` the shallowest known to give more
      // or where Newton failed (an overshoot that inverts elements). Steps are secant / regula
      // falsi (Illinois) inside the bracket, bisection when that leaves it, and geometric growth
      // while there is no contact yet.
      const double target = options.force_n * i / options.steps;
      double lo_d = depth, lo_f = force;
      double hi_d = kNoEnergy, hi_f = kNoEnergy;
      double prev_d = depth, prev_f = force;  // the evaluation before the last, for the secant
      Eigen::VectorXd x_lo = *x;
      double trial = stiffness > 0 ? (target - force) / stiffness : 1e-3 * size;
      double d1 = depth + std::max(trial, 1e-9 * size);
      int same_side = 0;
      bool done = false;
      for (int k = 0; k < options.max_force_iterations && !done; ++k) {
        Eigen::VectorXd xk = x_lo;
        Result<double> f1 =
            force_at_depth(model, b, probe, options.solve, d1, &xk, &st.newton_iterations);
        if (!f1.ok() && f1.status().code() == StatusCode::kInvalidArgument)
          return fail(f1.status());
        if (!f1.ok()) {  // no equilibrium this deep: an upper bound of unknown force
          hi_d = d1;
          hi_f = kNoEnergy;
          d1 = 0.5 * (lo_d + hi_d);
          continue;
        }
        if (std::abs(*f1 - target) <= options.force_relative_tolerance * target) {
          depth = d1;
          force = *f1;
          *x = xk;
          done = true;
          break;
        }
        double d2;
        if (*f1 < target) {
          prev_d = lo_d;
          prev_f = lo_f;
          lo_d = d1;
          lo_f = *f1;
          x_lo = xk;
          same_side = same_side > 0 ? same_side + 1 : 1;
          if (!std::isfinite(hi_d)) {
            // Extrapolate (secant, at most 4× the last step) or, without contact, double.
            const double last = lo_d - prev_d;
            d2 = (lo_f > prev_f)
                     ? lo_d + std::min((target - lo_f) * last / (lo_f - prev_f), 4 * last)
                     : lo_d + 2 * last;
            if (lo_d - depth > size)
              return fail(failed_precondition(
                  "force control diverged: the probe does not reach the specimen (unreachable "
                  "probe)"));
            d1 = d2;
            continue;
          }
          if (same_side >= 2 && std::isfinite(hi_f)) hi_f = target + 0.5 * (hi_f - target);
        } else {
          hi_d = d1;
          hi_f = *f1;
          same_side = same_side < 0 ? same_side - 1 : -1;
          if (same_side <= -2) lo_f = target - 0.5 * (target - lo_f);
        }
        d2 = std::isfinite(hi_f) ? lo_d + (target - lo_f) * (hi_d - lo_d) / (hi_f - lo_f)
                                 : 0.5 * (lo_d + hi_d);
        if (!(d2 > lo_d && d2 < hi_d)) d2 = 0.5 * (lo_d + hi_d);
        d1 = d2;
      }
      if (!done)
        return fail(failed_precondition(
            fmt::format("force control: {} N not reached within {} depth iterations", target,
                        options.max_force_iterations)));
    }
    {
      const double prev_d = sum.steps.empty() ? 0.0 : sum.steps.back().depth_m;
      const double prev_f = sum.steps.empty() ? 0.0 : sum.steps.back().force_n;
      if (depth != prev_d) stiffness = (force - prev_f) / (depth - prev_d);
    }
    st.depth_m = depth;
    st.force_n = force;
    sum.steps.push_back(st);
    if (options.record_positions) sum.positions.push_back(*x);
    if (options.solve.progress != nullptr)
      options.solve.progress->update(static_cast<std::uint64_t>(i));
  }
  sum.usable = true;
  sum.depth_m = depth;
  sum.force_n = force;
  double maxd = 0;
  for (Eigen::Index i = 0; i < x->size() / 3; ++i)
    maxd = std::max(maxd, (x->segment<3>(3 * i) - rest.segment<3>(3 * i)).norm());
  sum.max_displacement_m = maxd;
  sum.time_s = seconds_since(start);
  if (summary != nullptr) *summary = sum;
  return {};
}

}  // namespace hc::hyperelastic
