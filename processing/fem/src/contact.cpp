#include "processing/fem/contact.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "processing/fem/incremental.h"

namespace hc::fem {

Status ContactOptions::validate() const {
  if (!std::isfinite(penalty_scale) || !(penalty_scale > 0)) {
    return invalid_argument("contact: penalty_scale must be > 0");
  }
  if (!std::isfinite(penalty_n_per_m) || penalty_n_per_m < 0) {
    return invalid_argument("contact: penalty_n_per_m must be >= 0");
  }
  if (max_iterations < 1 || max_force_iterations < 1) {
    return invalid_argument("contact: iteration limits must be >= 1");
  }
  if (!(tolerance_rel > 0) || !(force_tolerance_rel > 0)) {
    return invalid_argument("contact: tolerances must be > 0");
  }
  if (!std::isfinite(max_depth_step_m) || max_depth_step_m < 0) {
    return invalid_argument("contact: max_depth_step_m must be >= 0");
  }
  if (!std::isfinite(max_travel_m) || max_travel_m < 0) {
    return invalid_argument("contact: max_travel_m must be >= 0");
  }
  return {};
}

struct ContactSolver::Impl {
  CorotationalFem* fem = nullptr;
  std::unique_ptr<Probe> probe;
  Eigen::Isometry3d start_pose;
  ContactOptions options;
  double travel = 0;
  double size = 0;  // specimen bounding-box diagonal
  double penalty = 0;
  double max_step = 0;      // largest probe advance per sub-step
  double solved_depth = 0;  // depth of the state fem currently holds
  const MaterialModel* material = nullptr;
  MatrixX3d contact_forces;
  // Last converged (depth, force) pairs for force-control initial guesses.
  double last_depth = 0;
  double last_force = 0;

  double mean_diagonal() const {
    const SparseMatrix& k = fem->stiffness();
    double sum = 0;
    for (Eigen::Index c = 0; c < k.cols(); ++c) sum += k.valuePtr()[k.outerIndexPtr()[c + 1] - 1];
    return sum / static_cast<double>(k.cols());
  }

  Status solve_depth(double depth, ContactSummary* s);
  Status solve_depth_once(double depth, ContactSummary* s);
};

ContactSolver::ContactSolver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ContactSolver::ContactSolver(ContactSolver&&) noexcept = default;
ContactSolver& ContactSolver::operator=(ContactSolver&&) noexcept = default;
ContactSolver::~ContactSolver() = default;

Result<ContactSolver> ContactSolver::create(CorotationalFem* fem, const Probe& probe,
                                            const ContactOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  if (fem == nullptr) return invalid_argument("contact: no FEM model");
  auto impl = std::make_unique<Impl>();
  impl->fem = fem;
  impl->probe = probe.clone();
  impl->start_pose = probe.pose();
  impl->options = options;
  const MatrixX3d& rest = fem->mesh().nodes;
  impl->size = (rest.colwise().maxCoeff() - rest.colwise().minCoeff()).norm();
  const double max_travel = options.max_travel_m > 0 ? options.max_travel_m : 10 * impl->size;
  if (!probe.pose().matrix().allFinite()) return invalid_argument("contact: non-finite probe pose");
  // Only free nodes can be pushed; a probe that only touches fixed nodes cannot load the specimen.
  std::vector<Eigen::Index> free_nodes;
  for (Eigen::Index i = 0; i < rest.rows(); ++i) {
    if (!fem->is_fixed(i)) free_nodes.push_back(i);
  }
  MatrixX3d pts(static_cast<Eigen::Index>(free_nodes.size()), 3);
  for (size_t k = 0; k < free_nodes.size(); ++k) {
    pts.row(static_cast<Eigen::Index>(k)) = rest.row(free_nodes[k]);
  }
  const std::optional<double> t = probe.travel_to_contact(pts, max_travel);
  if (!t) {
    return invalid_argument("contact: the probe does not reach the specimen (no free node within " +
                            std::to_string(max_travel) + " m along the probe direction)");
  }
  impl->travel = *t;
  if (options.max_depth_step_m > 0) {
    impl->max_step = options.max_depth_step_m;
  } else {
    double shortest = std::numeric_limits<double>::infinity();
    const MatrixX4i& tets = fem->mesh().tets;
    for (Eigen::Index e = 0; e < tets.rows(); ++e) {
      for (int a = 0; a < 4; ++a) {
        for (int b = a + 1; b < 4; ++b) {
          shortest = std::min(shortest, (rest.row(tets(e, a)) - rest.row(tets(e, b))).norm());
        }
      }
    }
    impl->max_step = 0.5 * shortest;
  }
  impl->contact_forces = MatrixX3d::Zero(rest.rows(), 3);
  return ContactSolver(std::move(impl));
}

double ContactSolver::contact_travel() const { return impl_->travel; }
void ContactSolver::set_material(const MaterialModel* material) { impl_->material = material; }
const Probe& ContactSolver::probe() const { return *impl_->probe; }
MatrixX3d ContactSolver::contact_forces() const { return impl_->contact_forces; }
double ContactSolver::penalty_n_per_m() const { return impl_->penalty; }

Status ContactSolver::Impl::solve_depth(double depth, ContactSummary* s) {
  if (!std::isfinite(depth) || depth < 0) {
    return invalid_argument("contact: depth must be a finite number >= 0 m, got " +
                            std::to_string(depth));
  }
  const double from = solved_depth;
  const int substeps = std::max(1, static_cast<int>(std::ceil(std::abs(depth - from) / max_step)));
  if (substeps > 100000) return invalid_argument("contact: depth too large for this mesh");
  int iterations = 0;
  for (int k = 1; k <= substeps; ++k) {
    const double dk = (k == substeps) ? depth : from + (depth - from) * k / substeps;
    const Status st = solve_depth_once(dk, s);
    iterations += s->iterations;
    if (!st.ok()) return st;
  }
  s->iterations = iterations;
  return {};
}

Status ContactSolver::Impl::solve_depth_once(double depth, ContactSummary* s) {
  probe->set_pose(start_pose);
  probe->advance(travel + depth);
  const Eigen::Index n = fem->num_nodes();
  const double tolerance = options.tolerance_rel * (depth + 1e-3 * size);
  std::vector<char> active(static_cast<size_t>(n), 0), prev_active;
  // Nodes kept in the active set although slightly outside: sliding along the linearised (tangent
  // plane) constraint of a curved probe leaves a node just outside the surface by a second-order
  // amount larger than its penalty penetration; dropping it would make the active set chatter. A
  // node stays active while its linearised contact force is compressive; at a fixed point this is
  // equivalent to sd < 0, so only true contact states are accepted.
  std::vector<char> keep(static_cast<size_t>(n), 0);
  std::vector<Eigen::Vector3d> normals(static_cast<size_t>(n));
  std::vector<Eigen::Vector3d> targets(static_cast<size_t>(n));
  Eigen::VectorXd extra(fem->num_free_dofs());
  const MatrixX3d zero = MatrixX3d::Zero(n, 3);
  *s = ContactSummary{};
  s->depth_m = depth;
  bool converged = false;
  int it = 0;
  for (; it < options.max_iterations; ++it) {
    fem->update_rotations();
    if (material != nullptr) update_params_from_strain(fem, *material);
    fem->assemble();
    if (penalty == 0) {
      penalty = options.penalty_n_per_m > 0 ? options.penalty_n_per_m
                                            : options.penalty_scale * mean_diagonal();
      if (!(penalty > 0) || !std::isfinite(penalty)) {
        return failed_precondition(
            "contact: stiffness matrix has no positive diagonal (parameters "
            "not set?)");
      }
    }
    // Linearised penalty field: nodes inside the probe get k n n^T (target - x), target = the
    // closest surface point; frictionless, so only the normal part acts.
    extra.setZero();
    prev_active = active;
    const MatrixX3d& x = fem->positions();
    for (Eigen::Index i = 0; i < n; ++i) {
      active[static_cast<size_t>(i)] = 0;
      if (fem->is_fixed(i)) continue;
      Eigen::Vector3d nrm;
      const Eigen::Vector3d xi = x.row(i).transpose();
      const double sd = probe->signed_distance(xi, &nrm);
      if (!(sd < 0) && !keep[static_cast<size_t>(i)]) continue;
      active[static_cast<size_t>(i)] = 1;
      const Eigen::Vector3d target = xi - sd * nrm;
      normals[static_cast<size_t>(i)] = nrm;
      targets[static_cast<size_t>(i)] = target;
      fem->add_to_node_block(i, penalty * nrm * nrm.transpose());
      const int d0 = fem->dof(i, 0);
      extra.segment<3>(d0) += penalty * nrm * nrm.dot(target);
    }
    HC_RETURN_IF_ERROR(fem->factorize());
    const MatrixX3d before = x;
    HC_RETURN_IF_ERROR(fem->solve(zero, extra));
    const double change = (fem->positions() - before).cwiseAbs().maxCoeff();
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto ui = static_cast<size_t>(i);
      keep[ui] =
          active[ui] && normals[ui].dot(targets[ui] - fem->positions().row(i).transpose()) > 0;
    }
    const bool same_set = active == prev_active;
    if (change <= tolerance && (same_set || it > options.max_iterations / 2)) {
      converged = true;
      ++it;
      break;
    }
  }
  // Contact forces at the final positions.
  contact_forces.setZero(n, 3);
  const MatrixX3d& x = fem->positions();
  double force = 0, max_pen = 0;
  int count = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (fem->is_fixed(i)) continue;
    Eigen::Vector3d nrm;
    const double sd = probe->signed_distance(x.row(i).transpose(), &nrm);
    if (!(sd < 0)) continue;
    const Eigen::Vector3d f = -penalty * sd * nrm;
    contact_forces.row(i) = f.transpose();
    force += f.dot(probe->direction());
    max_pen = std::max(max_pen, -sd);
    ++count;
  }
  s->force_n = force;
  s->active_nodes = count;
  s->iterations = it;
  s->max_penetration_m = max_pen;
  s->converged = converged;
  if (!converged) {
    return failed_precondition("contact: no equilibrium after " + std::to_string(it) +
                               " iterations at depth " + std::to_string(depth) + " m");
  }
  last_depth = depth;
  last_force = force;
  solved_depth = depth;
  return {};
}

Status ContactSolver::solve_depth(double depth_m, ContactSummary* summary) {
  return impl_->solve_depth(depth_m, summary);
}

Status ContactSolver::solve_force(double force_n, ContactSummary* summary) {
  Impl& s = *impl_;
  if (!std::isfinite(force_n) || force_n < 0) {
    return invalid_argument("contact: force must be a finite number >= 0 N, got " +
                            std::to_string(force_n));
  }
  if (force_n == 0) return s.solve_depth(0, summary);
  const double tol = s.options.force_tolerance_rel * force_n;
  // Bracket [lo, hi] with F(lo) < target <= F(hi); secant steps inside, bisection as the fallback.
  double lo = 0, f_lo = 0;
  double hi = -1, f_hi = 0;
  double d = (s.last_force > 0 && s.last_depth > 0) ? s.last_depth * force_n / s.last_force
                                                    : 1e-3 * s.size;
  int total_iterations = 0;
  ContactSummary cs;
  for (int it = 0; it < s.options.max_force_iterations; ++it) {
    HC_RETURN_IF_ERROR(s.solve_depth(d, &cs));
    total_iterations += cs.iterations;
    const double f = cs.force_n;
    if (std::abs(f - force_n) <= tol) {
      cs.iterations = total_iterations;
      *summary = cs;
      return {};
    }
    if (f < force_n) {
      lo = d;
      f_lo = f;
    } else {
      hi = d;
      f_hi = f;
    }
    double next;
    if (hi < 0) {
      // Not bracketed yet: extrapolate through (0, 0)-(lo, f_lo) and overshoot a little, at most
      // x4.
      next = f_lo > 0 ? std::min(4.0 * lo, 1.05 * lo * force_n / f_lo) : 2.0 * std::max(lo, d);
    } else {
      if (hi - lo <= 1e-9 * hi) {
        // The bracket has collapsed onto a jump of F(d) (a node entering or leaving contact):
        // no depth gives the target more closely at this mesh resolution. Accept the nearest side
        // when it is within 1 %.
        if (std::abs(f - force_n) <= 0.01 * force_n) {
          cs.iterations = total_iterations;
          *summary = cs;
          return {};
        }
        break;
      }
      next = lo + (force_n - f_lo) * (hi - lo) / (f_hi - f_lo);
      const double w = hi - lo;
      if (!(next > lo + 0.01 * w && next < hi - 0.01 * w)) next = 0.5 * (lo + hi);
    }
    d = next;
  }
  cs.iterations = total_iterations;
  *summary = cs;
  return failed_precondition("contact: force control did not reach " + std::to_string(force_n) +
                             " N (last " + std::to_string(cs.force_n) + " N at depth " +
                             std::to_string(cs.depth_m) + " m)");
}

Status ContactSolver::solve(const Load& load, ContactSummary* summary) {
  return load.control == LoadControl::kDepth ? solve_depth(load.value, summary)
                                             : solve_force(load.value, summary);
}

}  // namespace hc::fem
