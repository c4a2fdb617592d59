#include "processing/fem/contact.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "processing/fem/contact_surface.h"
#include "processing/fem/incremental.h"

namespace hc::fem {

namespace {
// Equilibrium iterations per depth after which the contact's active set is held.
constexpr int kFreezeAfter = 20;
// A depth increment whose active set still changes after this many equilibrium iterations is
// abandoned and solved again as two halves from the last equilibrium (a cutback), at most
// kMaxCutBacks halvings deep; only the smallest increments hold their set (kFreezeAfter). A held
// set is an equilibrium for that set, not for the contact: the active set can cycle between two
// states (a sphere on a fine contact-adaptive mesh, 2e6 Pa / 0.3 / R 6 mm, 0.3 -> 0.4 mm: 58 and
// 32-36 points in turn, positions moving 0.1 mm per iteration), and holding the smaller one gave
// 1.657 N against 1.865 N from 10 or 20 load steps (-8 % against Sneddon instead of +3.4 %).
// Converged increments take 2-8 iterations.
constexpr int kCutBackAfter = 12;
constexpr int kMaxCutBacks = 4;
// Conjugate-gradient iterations preconditioned by an earlier factorisation before K is factorised
// again, and their relative tolerance (in the preconditioned residual norm; the equilibrium
// iteration's own tolerance is on position changes, orders of magnitude coarser).
constexpr int kReuseIterations = 20;
constexpr double kReuseTolerance = 1e-6;
// With the penalty update the preconditioner differs from K only by the rotations, and the solves
// may stop earlier: the next equilibrium iteration moves the positions by more than is left (an
// inexact Newton-like forcing term). Default Hertz scene: 1e-6 3.45 s, 1e-3 2.63 s, 1e-2 2.69 s,
// the same force to 1e-5; 0.1 2.19 s moved it by 2e-4 and failed the contact tests. With the
// factor in single precision (precondition()): 1e-2 1.82-1.88 s, 0.5e-2 1.63-1.72 s. 1e-2 also sat
// at an edge: a force-controlled contact test took 12-20 equilibrium iterations at one depth over
// 0.8-1.2e-2 (kFreezeAfter is 20); 0.3-0.7e-2 pass every contact test.
constexpr double kUpdateTolerance = 0.5e-2;
// The equilibrium iteration's remaining change is estimated from its contraction rate, times this
// margin, while that is below kMaxRate (Hertz scene: rates 0.007-0.026).
constexpr double kRateMargin = 2;
constexpr double kMaxRate = 0.5;
// A preconditioned solve that needed more than this many iterations shows the factorisation has
// gone stale (after a fresh one they take 1-3): the next iteration factorises again. Chosen when
// every contact change made it stale (default Hertz scene, bench_fem_step: never 6.26 s, above 12
// 5.71 s, above 8 5.57 s, above 5 5.46 s, above 3 5.71 s); with the penalties as an update
// (PenaltyUpdate) that scene now factorises once.
constexpr int kRefactorAbove = 5;
// The predictor extrapolates at most this many times the last depth step.
constexpr double kMaxExtrapolation = 2.0;
// The penalties reach the factorisation as a low-rank update while its columns hold at most this
// many numbers (2^25: 256 MB) and ContactOptions::max_update_points allows.
constexpr Eigen::Index kMaxUpdateEntries = Eigen::Index{1} << 25;

// Contact penalties as a low-rank update of a factorisation of the elastic K alone (Woodbury's
// identity): point i adds k_i u_i u_iᵀ, u_i = its weights ⊗ its normal on the free dofs, so for the
// points A in contact, with W = K⁻¹ U_A and S = D⁻¹ + U_Aᵀ W (D = diag k_i),
//   (K + U_A D U_Aᵀ)⁻¹ r = K⁻¹ r − W S⁻¹ Wᵀ r.
// A point's column K⁻¹ u_i is one solve, kept until the next factorisation: points entering or
// leaving contact then never make the factorisation stale, only the rotations do. A column keeps
// the normal its point had when it was computed; the exact K (with today's normals) is what
// conjugate gradients solve, so the small difference costs an iteration at most. Written here:
// CHOLMOD's own update (cholmod_updown) works on simplicial factors only, and converting the
// supernodal factor costs more than factorising again.
struct PenaltyUpdate {
  std::vector<int> column;               // per contact point: its column of w, or -1
  std::vector<Eigen::Vector3d> normals;  // per column: the normal its u was built with
  Eigen::MatrixXd w;                     // K⁻¹ u per column (free dofs × columns)
  Eigen::MatrixXd wa;                    // w's columns of the points in contact, in their order
  std::vector<std::size_t> in_contact;   // the points in contact, in wa's order
  Eigen::LDLT<Eigen::MatrixXd> s;        // S for those points
  bool factor_elastic = false;           // the factorisation is of the elastic K alone ...
  int factor_call = -1;                  // ... and is the factorisation of this call

  // Whether the model's factorisation is still the elastic one (others may factorise it).
  bool elastic(const CorotationalFem& fem) const {
    return factor_elastic && fem.cholesky().summary().factorize_calls == factor_call;
  }

  void clear(std::size_t points) {
    column.assign(points, -1);
    normals.clear();
    w.resize(0, 0);
    wa.resize(0, 0);
  }
};
}  // namespace

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
  if (max_update_points < 0) return invalid_argument("contact: max_update_points must be >= 0");
  return sampling.validate();
}

struct ContactSolver::Impl {
  CorotationalFem* fem = nullptr;
  std::unique_ptr<Probe> probe;
  Eigen::Isometry3d start_pose;
  ContactOptions options;
  ContactSurface surface;
  std::vector<double> stiffness;  // per contact point (N/m), from the first assembly
  double travel = 0;
  double size = 0;          // specimen bounding-box diagonal
  double penalty = 0;       // mean stiffness of the node points (what penalty_n_per_m() reports)
  double max_step = 0;      // largest probe advance per sub-step
  double solved_depth = 0;  // depth of the state fem currently holds
  // The last two equilibria (positions and depths) for a linear predictor of the next one.
  MatrixX3d x_last, x_before;
  double depth_before = -1;
  int last_cg_iterations = 0;  // of the last preconditioned solve (0 after a factorisation)
  double contraction = 0;      // largest rate of the equilibrium iteration seen with a held set
  const MaterialModel* material = nullptr;
  MatrixX3d contact_forces;
  // Last converged (depth, force) pairs for force-control initial guesses.
  double last_depth = 0;
  double last_force = 0;

  // Adds k (w wᵀ ⊗ n nᵀ) of point i to the assembled K.
  void add_penalty(std::size_t i, const Eigen::Matrix3d& knn) {
    const ContactPoint& p = surface.points()[i];
    if (p.is_node()) {
      fem->add_to_node_block(p.nodes[0], knn);
      return;
    }
    const std::array<int, 3> local = surface.local(i);
    const int tet = surface.tet(i);
    for (int a = 0; a < 3; ++a)
      for (int b = a; b < 3; ++b)
        fem->add_to_element_block(tet, local[static_cast<std::size_t>(a)],
                                  local[static_cast<std::size_t>(b)],
                                  p.weights(a) * p.weights(b) * knn);
  }

  // Calls f(first dof, weight) for each free node of point i.
  template <typename F>
  void for_free_nodes(std::size_t i, F&& f) const {
    const ContactPoint& p = surface.points()[i];
    for (int k = 0; k < (p.is_node() ? 1 : 3); ++k) {
      const int d0 = fem->dof(p.nodes[static_cast<std::size_t>(k)], 0);
      if (d0 >= 0) f(d0, p.weights(k));
    }
  }

  // Readies `update` for the points `in_contact` (columns for new ones, S).
  Status prepare_update(const std::vector<std::size_t>& in_contact,
                        const std::vector<Eigen::Vector3d>& normals);
  Status precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const;

  Status solve_depth(double depth, ContactSummary* s);
  // The increments to each of `depths` in turn; *s sums their iterations and factorisations.
  Status step_through(std::span<const double> depths, int cutbacks, ContactSummary* s);
  // From the equilibrium fem holds (at solved_depth) to `depth`, solved again as two halves where
  // its active set does not settle (kCutBackAfter), `cutbacks` halvings deep so far.
  Status step_to(double depth, int cutbacks, ContactSummary* s);
  // One increment. With `abandoned`, gives up (sets it, state unchanged but fem's positions) when
  // the active set still changes after kCutBackAfter iterations.
  Status solve_depth_once(double depth, ContactSummary* s, bool* abandoned);

  PenaltyUpdate update;
};

Status ContactSolver::Impl::prepare_update(const std::vector<std::size_t>& in_contact,
                                           const std::vector<Eigen::Vector3d>& normals) {
  const Eigen::Index nfree = fem->num_free_dofs();
  const auto m = static_cast<Eigen::Index>(in_contact.size());
  std::vector<std::size_t> fresh;
  for (std::size_t i : in_contact)
    if (update.column[i] < 0) fresh.push_back(i);
  const auto nf = static_cast<Eigen::Index>(fresh.size());
  if ((update.w.cols() + nf) * nfree > kMaxUpdateEntries) {
    // Keep only the columns of the points in contact now.
    std::vector<std::size_t> kept_points;
    for (std::size_t i : in_contact)
      if (update.column[i] >= 0) kept_points.push_back(i);
    Eigen::MatrixXd kept(nfree, static_cast<Eigen::Index>(kept_points.size()));
    std::vector<Eigen::Vector3d> kept_normals;
    for (std::size_t c = 0; c < kept_points.size(); ++c) {
      const int col = update.column[kept_points[c]];
      kept.col(static_cast<Eigen::Index>(c)) = update.w.col(col);
      kept_normals.push_back(update.normals[static_cast<std::size_t>(col)]);
    }
    std::fill(update.column.begin(), update.column.end(), -1);
    for (std::size_t c = 0; c < kept_points.size(); ++c)
      update.column[kept_points[c]] = static_cast<int>(c);
    update.w = std::move(kept);
    update.normals = std::move(kept_normals);
  }
  if (nf > 0) {
    Eigen::MatrixXd u = Eigen::MatrixXd::Zero(nfree, nf);
    for (Eigen::Index j = 0; j < nf; ++j) {
      const std::size_t i = fresh[static_cast<std::size_t>(j)];
      for_free_nodes(i, [&](int d0, double c) { u.col(j).segment<3>(d0) += c * normals[i]; });
    }
    Eigen::MatrixXd x;
    HC_RETURN_IF_ERROR(fem->cholesky().solve(u, &x));
    const Eigen::Index c0 = update.w.cols();
    update.w.conservativeResize(nfree, c0 + nf);
    update.w.rightCols(nf) = x;
    for (Eigen::Index j = 0; j < nf; ++j) {
      const std::size_t i = fresh[static_cast<std::size_t>(j)];
      update.column[i] = static_cast<int>(c0 + j);
      update.normals.push_back(normals[i]);
    }
  }
  update.wa.resize(nfree, m);
  update.in_contact = in_contact;
  Eigen::MatrixXd sm(m, m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const std::size_t i = in_contact[static_cast<std::size_t>(a)];
    update.wa.col(a) = update.w.col(update.column[i]);
  }
  for (Eigen::Index a = 0; a < m; ++a) {
    const std::size_t i = in_contact[static_cast<std::size_t>(a)];
    const Eigen::Vector3d& n = update.normals[static_cast<std::size_t>(update.column[i])];
    Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(m);
    for_free_nodes(i, [&](int d0, double c) {
      row.noalias() += c * n.transpose() * update.wa.middleRows<3>(d0);
    });
    sm.row(a) = row;
    sm(a, a) += 1 / stiffness[i];
  }
  update.s.compute(0.5 * (sm + sm.transpose()));
  if (update.s.info() != Eigen::Success) return internal_error("contact: penalty update failed");
  return {};
}

// z = (I − W S⁻¹ Uᵀ) K⁻¹ r, Woodbury's identity with Wᵀ r written as Uᵀ (K⁻¹ r): equal in exact
// arithmetic, but then Uᵀ z = D⁻¹ S⁻¹ Uᵀ K⁻¹ r, so along the penalised directions whatever error
// K⁻¹ r carries is scaled down by the penalties (with Wᵀ r the large terms K⁻¹ r and W S⁻¹ Wᵀ r
// had to cancel there). That lets K⁻¹ r come from the factor in single precision
// (SparseCholesky::solve_single_precision), whose rounding conjugate gradients correct as they
// correct the stale rotations: with the cancelling form and the float solve, the flat punches'
// active sets oscillated (m 44 -> 21 -> 44 ... points) and the ν = 0.45 punch of the
// contact-defaults test ended on a wrong set (-35 % force).
Status ContactSolver::Impl::precondition(const Eigen::VectorXd& r, Eigen::VectorXd* z) const {
  HC_RETURN_IF_ERROR(fem->cholesky().solve_single_precision(r, z));
  const Eigen::Index m = update.wa.cols();
  if (m == 0) return {};
  Eigen::VectorXd ut(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const std::size_t i = update.in_contact[static_cast<std::size_t>(a)];
    const Eigen::Vector3d& n = update.normals[static_cast<std::size_t>(update.column[i])];
    double sum = 0;
    for_free_nodes(i, [&](int d0, double c) { sum += c * n.dot(z->segment<3>(d0)); });
    ut(a) = sum;
  }
  z->noalias() -= update.wa * update.s.solve(ut);
  return {};
}

ContactSolver::ContactSolver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ContactSolver::ContactSolver(ContactSolver&&) noexcept = default;
ContactSolver& ContactSolver::operator=(ContactSolver&&) noexcept = default;
ContactSolver::~ContactSolver() = default;

Result<ContactSolver> ContactSolver::create(CorotationalFem* fem, const Probe& probe,
                                            const ContactOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  if (fem == nullptr) return invalid_argument("contact: no FEM model");
  if (!probe.pose().matrix().allFinite()) return invalid_argument("contact: non-finite probe pose");
  auto impl = std::make_unique<Impl>();
  impl->fem = fem;
  impl->probe = probe.clone();
  impl->start_pose = probe.pose();
  impl->options = options;
  const MatrixX3d& rest = fem->mesh().nodes;
  impl->size = (rest.colwise().maxCoeff() - rest.colwise().minCoeff()).norm();
  const double max_travel = options.max_travel_m > 0 ? options.max_travel_m : 10 * impl->size;
  HC_ASSIGN_OR_RETURN(impl->surface, ContactSurface::create(fem->mesh(), probe, options.sampling));
  // Only points that move can be pushed: a probe that only touches fixed nodes cannot load the
  // specimen.
  std::vector<char> fixed(static_cast<std::size_t>(rest.rows()), 0);
  for (int f : fem->fixed_nodes()) fixed[static_cast<std::size_t>(f)] = 1;
  HC_ASSIGN_OR_RETURN(const double t,
                      impl->surface.travel_to_contact(probe, rest, fixed, max_travel));
  impl->travel = t;
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
const ContactSurface& ContactSolver::surface() const { return impl_->surface; }

Status ContactSolver::Impl::solve_depth(double depth, ContactSummary* s) {
  if (!std::isfinite(depth) || depth < 0) {
    return invalid_argument("contact: depth must be a finite number >= 0 m, got " +
                            std::to_string(depth));
  }
  const double from = solved_depth;
  const int substeps = std::max(1, static_cast<int>(std::ceil(std::abs(depth - from) / max_step)));
  if (substeps > 100000) return invalid_argument("contact: depth too large for this mesh");
  std::vector<double> depths(static_cast<std::size_t>(substeps));
  for (int k = 1; k <= substeps; ++k)
    depths[static_cast<std::size_t>(k - 1)] =
        (k == substeps) ? depth : from + (depth - from) * k / substeps;
  return step_through(depths, 0, s);
}

Status ContactSolver::Impl::step_through(std::span<const double> depths, int cutbacks,
                                         ContactSummary* s) {
  int iterations = 0, factorizations = 0;
  for (const double d : depths) {
    const Status st = step_to(d, cutbacks, s);
    iterations += s->iterations;
    factorizations += s->factorizations;
    if (!st.ok()) return st;
  }
  s->iterations = iterations;
  s->factorizations = factorizations;
  return {};
}

Status ContactSolver::Impl::step_to(double depth, int cutbacks, ContactSummary* s) {
  const double from = solved_depth;
  const MatrixX3d start = fem->positions();
  bool abandoned = false;
  HC_RETURN_IF_ERROR(solve_depth_once(depth, s, cutbacks < kMaxCutBacks ? &abandoned : nullptr));
  if (!abandoned) return {};
  const int iterations = s->iterations, factorizations = s->factorizations;
  HC_RETURN_IF_ERROR(fem->set_positions(start));
  const double halves[] = {0.5 * (from + depth), depth};
  HC_RETURN_IF_ERROR(step_through(halves, cutbacks + 1, s));
  s->iterations += iterations;
  s->factorizations += factorizations;
  return {};
}

Status ContactSolver::Impl::solve_depth_once(double depth, ContactSummary* s, bool* abandoned) {
  // Start from the line through the last two equilibria when fem still holds the last one and the
  // depth goes on the same way: the equilibrium iteration then starts near its answer.
  if (depth_before >= 0 && x_last.rows() == fem->num_nodes() && fem->positions() == x_last &&
      (depth - solved_depth) * (solved_depth - depth_before) > 0) {
    const double t = (depth - solved_depth) / (solved_depth - depth_before);
    if (t <= kMaxExtrapolation)
      HC_RETURN_IF_ERROR(fem->set_positions(x_last + t * (x_last - x_before)));
  }
  probe->set_pose(start_pose);
  probe->advance(travel + depth);
  const Eigen::Index n = fem->num_nodes();
  const std::vector<ContactPoint>& points = surface.points();
  const std::size_t np = points.size();
  const double tolerance = options.tolerance_rel * (depth + 1e-3 * size);
  std::vector<char> active(np, 0), prev_active;
  // Points kept in the active set although slightly outside: sliding along the linearised (tangent
  // plane) constraint of a curved probe leaves a point just outside the surface by a second-order
  // amount larger than its penalty penetration; dropping it would make the active set chatter. A
  // point stays active while its linearised contact force is compressive; at a fixed point this is
  // equivalent to sd < 0, so only true contact states are accepted.
  std::vector<char> keep(np, 0);
  std::vector<Eigen::Vector3d> normals(np), targets(np);
  Eigen::VectorXd extra(fem->num_free_dofs());
  const MatrixX3d zero = MatrixX3d::Zero(n, 3);
  *s = ContactSummary{};
  s->depth_m = depth;
  bool converged = false;
  double last_change = 0;  // of the last iteration
  bool set_held = false;   // the last iteration kept the active set
  int it = 0;
  for (; it < options.max_iterations; ++it) {
    fem->update_rotations();
    if (material != nullptr) update_params_from_strain(fem, *material);
    fem->assemble();
    if (stiffness.empty()) {
      stiffness = surface.penalty_stiffness(*fem, options.penalty_scale, options.penalty_n_per_m);
      double sum = 0;
      int count = 0;
      for (std::size_t i = 0; i < np; ++i)
        if (points[i].is_node() && stiffness[i] > 0) {
          sum += stiffness[i];
          ++count;
        }
      penalty = count > 0 ? sum / count : 0;
      if (!(penalty > 0) || !std::isfinite(penalty)) {
        return failed_precondition(
            "contact: stiffness matrix has no positive diagonal (parameters not set?)");
      }
    }
    // Linearised penalty field: points inside the probe get k n nᵀ (target − x), target = the
    // closest surface point; frictionless, so only the normal part acts. A point's force reaches
    // its nodes by its weights.
    prev_active = active;
    const MatrixX3d& x = fem->positions();
    // A point on the edge of the contact (a punch's rim) can enter and leave at every iteration:
    // after kFreezeAfter iterations the active set is held, and the result is the equilibrium for
    // that set (measured without it: a period-12 cycle between sets of 23-44 points under a flat
    // punch's rim on faces split into contact points).
    // The held points keep their last tangent planes too: near a punch's rim edge the closest
    // surface point jumps between the face and the edge as a point moves.
    const bool frozen = it >= kFreezeAfter;
    std::vector<std::size_t> in_contact;
    for (std::size_t i = 0; i < np; ++i) {
      if (!frozen) {
        active[i] = 0;
        if (!(stiffness[i] > 0)) continue;
        Eigen::Vector3d nrm;
        const Eigen::Vector3d xi = surface.position(x, i);
        const double sd = probe->signed_distance(xi, &nrm);
        if (!(sd < 0) && !keep[i]) continue;
        active[i] = 1;
        normals[i] = nrm;
        targets[i] = xi - sd * nrm;
      }
      if (active[i]) in_contact.push_back(i);
    }
    const MatrixX3d before = x;
    // K is solved by conjugate gradients preconditioned by an earlier factorisation (of an earlier
    // iteration or depth): between iterations the rotations change K little. While few points are
    // in contact the factorisation is of the elastic K and their penalties are added to it as a
    // low-rank update (PenaltyUpdate), so it is refactorised only when the rotations have made it
    // stale; with many, K is factorised with its penalties whenever CG does not converge quickly.
    const auto m = static_cast<Eigen::Index>(in_contact.size());
    const bool low_rank =
        m <= options.max_update_points && m * fem->num_free_dofs() <= kMaxUpdateEntries;
    if (low_rank && (!update.elastic(*fem) || last_cg_iterations > kRefactorAbove)) {
      HC_RETURN_IF_ERROR(fem->factorize());
      ++s->factorizations;
      update.factor_elastic = true;
      update.factor_call = fem->cholesky().summary().factorize_calls;
      update.clear(np);
      last_cg_iterations = 0;
    }
    extra.setZero();
    for (std::size_t i : in_contact) {
      const Eigen::Vector3d& nrm = normals[i];
      add_penalty(i, stiffness[i] * nrm * nrm.transpose());
      const Eigen::Vector3d f = stiffness[i] * nrm * nrm.dot(targets[i]);
      for_free_nodes(i, [&](int d0, double c) { extra.segment<3>(d0) += c * f; });
    }
    CorotationalFem::PcgOptions pcg;
    pcg.max_iterations = kReuseIterations;
    pcg.relative_tolerance = kReuseTolerance;
    CorotationalFem::PcgSummary cg;
    if (low_rank) {
      pcg.relative_tolerance = kUpdateTolerance;
      HC_RETURN_IF_ERROR(prepare_update(in_contact, normals));
      pcg.precondition = [this](const Eigen::VectorXd& r, Eigen::VectorXd* z) {
        return precondition(r, z);
      };
      HC_RETURN_IF_ERROR(fem->solve_preconditioned(extra, pcg, &cg));
    } else if (!update.elastic(*fem) && last_cg_iterations <= kRefactorAbove) {
      HC_RETURN_IF_ERROR(fem->solve_preconditioned(extra, pcg, &cg));
    }
    last_cg_iterations = cg.iterations;
    const bool solved = cg.converged;
    if (!solved) {
      last_cg_iterations = 0;
      HC_RETURN_IF_ERROR(fem->factorize());
      ++s->factorizations;
      update.factor_elastic = false;
      update.clear(np);
      HC_RETURN_IF_ERROR(fem->solve(zero, extra));
    }
    const double change = (fem->positions() - before).cwiseAbs().maxCoeff();
    for (std::size_t i = 0; i < np; ++i)
      keep[i] = active[i] && normals[i].dot(targets[i] - surface.position(fem->positions(), i)) > 0;
    const bool same_set = active == prev_active;
    // With the active set held the iteration contracts linearly: at rate ρ what remains after a
    // change is at most change ρ / (1 − ρ), so the iteration that would only confirm it is
    // skipped. ρ is the largest rate seen over two iterations that both kept the set (this
    // solver's earlier depths included), with a margin.
    if (same_set && set_held && last_change > 0)
      contraction = std::max(contraction, change / last_change);
    const double rho = kRateMargin * contraction;
    const bool contracted =
        same_set && contraction > 0 && rho < kMaxRate && change * rho / (1 - rho) <= tolerance;
    set_held = same_set;
    last_change = change;
    if ((change <= tolerance || contracted) && (same_set || frozen)) {
      converged = true;
      ++it;
      break;
    }
    if (abandoned != nullptr && it + 1 >= kCutBackAfter && !same_set) {
      *abandoned = true;
      s->iterations = it + 1;
      return {};
    }
  }
  // Contact forces at the final positions.
  contact_forces.setZero(n, 3);
  const MatrixX3d& x = fem->positions();
  double force = 0, max_pen = 0;
  int count = 0;
  for (std::size_t i = 0; i < np; ++i) {
    if (!active[i]) continue;
    // The linearised penalty force of the last solve (= −k sd n for a point inside the probe):
    // what balances the elastic forces.
    const double sd = normals[i].dot(surface.position(x, i) - targets[i]);
    const Eigen::Vector3d nrm = normals[i];
    const Eigen::Vector3d f = -stiffness[i] * sd * nrm;
    const ContactPoint& p = points[i];
    for (int k = 0; k < (p.is_node() ? 1 : 3); ++k)
      contact_forces.row(p.nodes[static_cast<std::size_t>(k)]) += p.weights(k) * f.transpose();
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
    return failed_precondition(fmt::format(
        "contact: no equilibrium after {} iterations at depth {:.4g} m (try more load steps)", it,
        depth));
  }
  last_depth = depth;
  last_force = force;
  x_before = std::move(x_last);
  x_last = fem->positions();
  depth_before = x_before.rows() > 0 ? solved_depth : -1;
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
  int total_iterations = 0, total_factorizations = 0;
  ContactSummary cs;
  // The last depth's summary with the work of every depth tried.
  const auto report = [&] {
    cs.iterations = total_iterations;
    cs.factorizations = total_factorizations;
    *summary = cs;
  };
  for (int it = 0; it < s.options.max_force_iterations; ++it) {
    HC_RETURN_IF_ERROR(s.solve_depth(d, &cs));
    total_iterations += cs.iterations;
    total_factorizations += cs.factorizations;
    const double f = cs.force_n;
    if (std::abs(f - force_n) <= tol) {
      report();
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
          report();
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
  report();
  return failed_precondition("contact: force control did not reach " + std::to_string(force_n) +
                             " N (last " + std::to_string(cs.force_n) + " N at depth " +
                             std::to_string(cs.depth_m) + " m)");
}

Status ContactSolver::solve(const Load& load, ContactSummary* summary) {
  return load.control == LoadControl::kDepth ? solve_depth(load.value, summary)
                                             : solve_force(load.value, summary);
}

}  // namespace hc::fem
