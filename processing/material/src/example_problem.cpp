#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "processing/material/fit.h"

namespace hc::material {

Eigen::SparseMatrix<double> tet_umbrella_laplacian(const TetMesh& mesh, TetAdjacency adjacency) {
  const Eigen::Index t = mesh.num_tets();
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(t));
  if (adjacency == TetAdjacency::kVertex) {
    std::vector<std::vector<int>> node_tets(static_cast<std::size_t>(mesh.num_nodes()));
    for (Eigen::Index e = 0; e < t; ++e)
      for (int k = 0; k < 4; ++k)
        node_tets[static_cast<std::size_t>(mesh.tets(e, k))].push_back(static_cast<int>(e));
    for (Eigen::Index e = 0; e < t; ++e) {
      std::vector<int>& nb = neighbours[static_cast<std::size_t>(e)];
      for (int k = 0; k < 4; ++k)
        for (int f : node_tets[static_cast<std::size_t>(mesh.tets(e, k))])
          if (f != e) nb.push_back(f);
    }
  } else {
    // Each face as its sorted node triple with its tet; equal triples are adjacent tets.
    std::vector<std::pair<std::array<int, 3>, int>> faces;
    faces.reserve(static_cast<std::size_t>(4 * t));
    for (Eigen::Index e = 0; e < t; ++e)
      for (int skip = 0; skip < 4; ++skip) {
        std::array<int, 3> f{};
        for (int k = 0, j = 0; k < 4; ++k)
          if (k != skip) f[static_cast<std::size_t>(j++)] = mesh.tets(e, k);
        std::sort(f.begin(), f.end());
        faces.emplace_back(f, static_cast<int>(e));
      }
    std::sort(faces.begin(), faces.end());
    for (std::size_t i = 0; i + 1 < faces.size(); ++i)
      if (faces[i].first == faces[i + 1].first && faces[i].second != faces[i + 1].second) {
        neighbours[static_cast<std::size_t>(faces[i].second)].push_back(faces[i + 1].second);
        neighbours[static_cast<std::size_t>(faces[i + 1].second)].push_back(faces[i].second);
      }
  }
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index e = 0; e < t; ++e) {
    std::vector<int>& nb = neighbours[static_cast<std::size_t>(e)];
    std::sort(nb.begin(), nb.end());
    nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
    const auto row = static_cast<int>(e);
    triplets.emplace_back(row, row, static_cast<double>(nb.size()));
    for (int f : nb) triplets.emplace_back(row, f, -1.0);
  }
  Eigen::SparseMatrix<double> l(t, t);
  l.setFromTriplets(triplets.begin(), triplets.end());
  return l;
}

struct ExampleProblem::Impl {
  explicit Impl(fem::CorotationalFem f) : fem(std::move(f)) {}
  fem::CorotationalFem fem;
  MatrixX3d forces;
  std::vector<int> measured_nodes;
  std::vector<int> measured_dofs;  // 3 per measured node, free-dof indices
  Eigen::VectorXd target;          // measured coordinates
  double scale = 0;
  LambdaAlpha guess;
  std::vector<fem::Matrix12d> kg, kh;
  std::vector<std::array<int, 12>> dofs;
  // g_e = R_e (dK_e/dp) (R_eᵀ x_e − X_e) for p = λ_e, α_e at the last solve (Appendix A, Eq.
  // A.2–A.3), computed on first use after each solve.
  mutable std::vector<fem::Vector12d> g_lambda, g_alpha;
  mutable bool sensitivities_current = false;

  void sensitivities() const {
    if (sensitivities_current) return;
    const Eigen::Index t = fem.num_elements();
    g_lambda.resize(static_cast<std::size_t>(t));
    g_alpha.resize(static_cast<std::size_t>(t));
    for (Eigen::Index e = 0; e < t; ++e) {
      const Eigen::Matrix3d& r = fem.rotation(e);
      const fem::Vector12d x = fem.current_positions(e);
      const fem::Vector12d x0 = fem.rest_positions(e);
      fem::Vector12d u;
      for (int a = 0; a < 4; ++a)
        u.segment<3>(3 * a) = r.transpose() * x.segment<3>(3 * a) - x0.segment<3>(3 * a);
      const fem::Vector12d gl = kg[static_cast<std::size_t>(e)] * u;
      const fem::Vector12d ga = kh[static_cast<std::size_t>(e)] * u;
      for (int a = 0; a < 4; ++a) {
        g_lambda[static_cast<std::size_t>(e)].segment<3>(3 * a) = r * gl.segment<3>(3 * a);
        g_alpha[static_cast<std::size_t>(e)].segment<3>(3 * a) = r * ga.segment<3>(3 * a);
      }
    }
    sensitivities_current = true;
  }

  Status solve_at(const std::vector<LambdaAlpha>& p) {
    sensitivities_current = false;
    HC_RETURN_IF_ERROR(fem.set_params(p));
    fem.assemble();
    HC_RETURN_IF_ERROR(fem.factorize());
    return fem.solve(forces);
  }
  void measured(Eigen::VectorXd* out) const {
    out->resize(static_cast<Eigen::Index>(measured_nodes.size()) * 3);
    const MatrixX3d& x = fem.positions();
    for (std::size_t i = 0; i < measured_nodes.size(); ++i)
      out->segment<3>(3 * static_cast<Eigen::Index>(i)) = x.row(measured_nodes[i]).transpose();
  }
};

ExampleProblem::ExampleProblem(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ExampleProblem::ExampleProblem(ExampleProblem&&) noexcept = default;
ExampleProblem& ExampleProblem::operator=(ExampleProblem&&) noexcept = default;
ExampleProblem::~ExampleProblem() = default;

Result<ExampleProblem> ExampleProblem::create(const TetMesh& mesh, const Example& example,
                                              double poisson_guess) {
  if (example.fixed_nodes.empty())
    return invalid_argument("example has no fixed nodes: the fit needs an attached region");
  if (example.positions_m.rows() != mesh.num_nodes() ||
      example.visible.size() != static_cast<std::size_t>(mesh.num_nodes()))
    return invalid_argument("example sizes do not match the mesh");
  HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                      fem::CorotationalFem::create(mesh, example.fixed_nodes));
  auto impl = std::make_unique<Impl>(std::move(f));
  fem::CorotationalFem& fem = impl->fem;
  impl->forces = MatrixX3d::Zero(mesh.num_nodes(), 3);
  for (const NodalForce& nf : example.forces) impl->forces.row(nf.node) += nf.force_n.transpose();

  std::vector<int> invisible;
  for (Eigen::Index n = 0; n < mesh.num_nodes(); ++n) {
    if (fem.is_fixed(n)) continue;
    if (!example.visible[static_cast<std::size_t>(n)]) {
      invisible.push_back(static_cast<int>(n));
      continue;
    }
    impl->measured_nodes.push_back(static_cast<int>(n));
    for (int a = 0; a < 3; ++a) impl->measured_dofs.push_back(fem.dof(n, a));
  }
  if (impl->measured_nodes.empty())
    return invalid_argument("example has no visible free node to compare against");
  const auto m = static_cast<Eigen::Index>(impl->measured_nodes.size());
  impl->target.resize(3 * m);
  Eigen::VectorXd measured_u(3 * m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const int n = impl->measured_nodes[static_cast<std::size_t>(i)];
    impl->target.segment<3>(3 * i) = example.positions_m.row(n).transpose();
    measured_u.segment<3>(3 * i) = (example.positions_m.row(n) - mesh.nodes.row(n)).transpose();
    impl->scale = std::max(impl->scale, measured_u.segment<3>(3 * i).norm());
  }
  if (!(impl->scale > 0)) return invalid_argument("example has no measured displacement");

  // Uniform stiffness guess: linear FEM (R = I) at λ = 1 Pa; displacements scale with 1/λ.
  fem.set_rotations_identity();
  const LambdaAlpha unit{1.0, poisson_guess};
  std::vector<LambdaAlpha> p(static_cast<std::size_t>(fem.num_elements()), unit);
  HC_RETURN_IF_ERROR(impl->solve_at(p));
  Eigen::VectorXd x1;
  impl->measured(&x1);
  Eigen::VectorXd rest(3 * m);
  for (Eigen::Index i = 0; i < m; ++i)
    rest.segment<3>(3 * i) =
        mesh.nodes.row(impl->measured_nodes[static_cast<std::size_t>(i)]).transpose();
  const Eigen::VectorXd u1 = x1 - rest;
  const double c = u1.dot(measured_u) / u1.squaredNorm();
  if (!(c > 0) || !std::isfinite(c))
    return invalid_argument(
        "measured displacements do not follow the applied forces (no positive stiffness fits)");
  impl->guess = {1.0 / c, poisson_guess / c};

  // Reference configuration for the rotations: measured where visible, simulated elsewhere.
  MatrixX3d reference = mesh.nodes;
  std::fill(p.begin(), p.end(), impl->guess);
  if (!invisible.empty()) {
    HC_RETURN_IF_ERROR(fem.set_params(p));
    HC_RETURN_IF_ERROR(fem.set_positions(mesh.nodes));
    // Non-convergence of the co-rotational iteration only makes the filled-in positions rougher.
    (void)fem.solve_static(impl->forces, 20, 1e-6 * impl->scale);
    for (int n : invisible) reference.row(n) = fem.positions().row(n);
  }
  for (int n : impl->measured_nodes) reference.row(n) = example.positions_m.row(n);
  HC_RETURN_IF_ERROR(fem.set_positions(reference));
  fem.update_rotations();

  const Eigen::Index t = fem.num_elements();
  impl->kg.resize(static_cast<std::size_t>(t));
  impl->kh.resize(static_cast<std::size_t>(t));
  impl->dofs.resize(static_cast<std::size_t>(t));
  for (Eigen::Index e = 0; e < t; ++e) {
    impl->kg[static_cast<std::size_t>(e)] = fem.stiffness_g(e);
    impl->kh[static_cast<std::size_t>(e)] = fem.stiffness_h(e);
    impl->dofs[static_cast<std::size_t>(e)] = fem.element_dofs(e);
  }
  return ExampleProblem(std::move(impl));
}

const TetMesh& ExampleProblem::mesh() const { return impl_->fem.mesh(); }
Eigen::Index ExampleProblem::num_elements() const { return impl_->fem.num_elements(); }
Eigen::Index ExampleProblem::num_measurements() const {
  return static_cast<Eigen::Index>(impl_->measured_dofs.size());
}
double ExampleProblem::scale_m() const { return impl_->scale; }
const LambdaAlpha& ExampleProblem::stiffness_guess() const { return impl_->guess; }
const MatrixX3d& ExampleProblem::positions() const { return impl_->fem.positions(); }
Eigen::Matrix<double, Eigen::Dynamic, 6> ExampleProblem::strains() const {
  return impl_->fem.strains();
}

void ExampleProblem::update_rotations() {
  impl_->sensitivities_current = false;
  impl_->fem.update_rotations();
}
Eigen::Index ExampleProblem::num_free_dofs() const { return impl_->fem.num_free_dofs(); }
double ExampleProblem::factor_entries() const {
  return impl_->fem.cholesky().summary().nnz_factor;
}
int ExampleProblem::factorizations() const {
  return impl_->fem.cholesky().summary().factorize_calls;
}
double ExampleProblem::factorize_time_s() const {
  return impl_->fem.cholesky().summary().factorize_time_s;
}

Status ExampleProblem::simulate(const std::vector<LambdaAlpha>& p, Eigen::VectorXd* residual) {
  HC_RETURN_IF_ERROR(impl_->solve_at(p));
  impl_->measured(residual);
  *residual -= impl_->target;
  return {};
}

Status ExampleProblem::jacobian(Eigen::MatrixXd* j, const std::vector<int>* groups,
                                int num_groups) const {
  const fem::CorotationalFem& fem = impl_->fem;
  if (!fem.cholesky().factorized()) return failed_precondition("jacobian: call simulate() first");
  const Eigen::Index t = fem.num_elements();
  const Eigen::Index nf = fem.num_free_dofs();
  const Eigen::Index m = num_measurements();
  if (groups && static_cast<Eigen::Index>(groups->size()) != t)
    return invalid_argument("jacobian: one group per element expected");
  const Eigen::Index cols = 2 * (groups ? num_groups : t);
  const auto col_of = [&](Eigen::Index e) -> Eigen::Index {
    return 2 * (groups ? (*groups)[static_cast<std::size_t>(e)] : e);
  };

  impl_->sensitivities();
  const std::vector<fem::Vector12d>& g_lambda = impl_->g_lambda;
  const std::vector<fem::Vector12d>& g_alpha = impl_->g_alpha;

  j->setZero(m, cols);
  if (cols <= m) {
    // Few parameter columns: solve K X = G, then keep the measured rows.
    Eigen::MatrixXd g = Eigen::MatrixXd::Zero(nf, cols);
    for (Eigen::Index e = 0; e < t; ++e) {
      const auto& d = impl_->dofs[static_cast<std::size_t>(e)];
      const Eigen::Index c = col_of(e);
      for (int k = 0; k < 12; ++k) {
        if (d[static_cast<std::size_t>(k)] < 0) continue;
        g(d[static_cast<std::size_t>(k)], c) += g_lambda[static_cast<std::size_t>(e)](k);
        g(d[static_cast<std::size_t>(k)], c + 1) += g_alpha[static_cast<std::size_t>(e)](k);
      }
    }
    Eigen::MatrixXd x;
    HC_RETURN_IF_ERROR(fem.cholesky().solve(g, &x));
    for (Eigen::Index i = 0; i < m; ++i)
      j->row(i) = -x.row(impl_->measured_dofs[static_cast<std::size_t>(i)]);
    return {};
  }
  // Few measurements: Z = K⁻¹ Sᵀ (K symmetric), then column (e, p) = −Zᵀ g.
  Eigen::MatrixXd s = Eigen::MatrixXd::Zero(nf, m);
  for (Eigen::Index i = 0; i < m; ++i)
    s(impl_->measured_dofs[static_cast<std::size_t>(i)], i) = 1.0;
  Eigen::MatrixXd z;
  HC_RETURN_IF_ERROR(fem.cholesky().solve(s, &z));
  // zt is m by nf so that a dof's column is contiguous.
  const Eigen::MatrixXd zt = z.transpose();
  for (Eigen::Index e = 0; e < t; ++e) {
    const auto& d = impl_->dofs[static_cast<std::size_t>(e)];
    const Eigen::Index c = col_of(e);
    for (int k = 0; k < 12; ++k) {
      const int dof = d[static_cast<std::size_t>(k)];
      if (dof < 0) continue;
      j->col(c) -= g_lambda[static_cast<std::size_t>(e)](k) * zt.col(dof);
      j->col(c + 1) -= g_alpha[static_cast<std::size_t>(e)](k) * zt.col(dof);
    }
  }
  return {};
}

}  // namespace hc::material

namespace hc::material {

Status ExampleProblem::apply_jacobian(const Eigen::VectorXd& v, Eigen::VectorXd* jv) const {
  const Impl& s = *impl_;
  const Eigen::Index t = s.fem.num_elements();
  if (!s.fem.cholesky().factorized()) return failed_precondition("jacobian: call simulate() first");
  if (v.size() != 2 * t) return invalid_argument("apply_jacobian: v needs 2 entries per element");
  s.sensitivities();
  // J v = −S K⁻¹ Σ_e (v_λe g_λe + v_αe g_αe).
  Eigen::VectorXd b = Eigen::VectorXd::Zero(s.fem.num_free_dofs());
  for (Eigen::Index e = 0; e < t; ++e) {
    const auto ue = static_cast<std::size_t>(e);
    const fem::Vector12d ge = v(2 * e) * s.g_lambda[ue] + v(2 * e + 1) * s.g_alpha[ue];
    const auto& d = s.dofs[ue];
    for (int k = 0; k < 12; ++k)
      if (d[static_cast<std::size_t>(k)] >= 0) b(d[static_cast<std::size_t>(k)]) += ge(k);
  }
  Eigen::VectorXd y;
  HC_RETURN_IF_ERROR(s.fem.cholesky().solve(b, &y));
  jv->resize(num_measurements());
  for (std::size_t i = 0; i < s.measured_dofs.size(); ++i)
    (*jv)(static_cast<Eigen::Index>(i)) = -y(s.measured_dofs[i]);
  return {};
}

Status ExampleProblem::apply_jacobian_transpose(const Eigen::MatrixXd& w,
                                                Eigen::MatrixXd* jtw) const {
  const Impl& s = *impl_;
  const Eigen::Index t = s.fem.num_elements();
  if (!s.fem.cholesky().factorized()) return failed_precondition("jacobian: call simulate() first");
  if (w.rows() != num_measurements())
    return invalid_argument("apply_jacobian_transpose: w needs one row per measurement");
  s.sensitivities();
  // Jᵀ w = −Gᵀ K⁻¹ Sᵀ w (K symmetric: the adjoint solve uses the same factor).
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(s.fem.num_free_dofs(), w.cols());
  for (std::size_t i = 0; i < s.measured_dofs.size(); ++i)
    b.row(s.measured_dofs[i]) = w.row(static_cast<Eigen::Index>(i));
  Eigen::MatrixXd z;
  HC_RETURN_IF_ERROR(s.fem.cholesky().solve(b, &z));
  // Accumulated in place (a row temporary per element was a heap allocation each: 5 % of the
  // per-example fits' time at 3,000 tets); one column (the matrix-free CG's products) in scalars.
  if (w.cols() == 1) {
    jtw->resize(2 * t, 1);
    for (Eigen::Index e = 0; e < t; ++e) {
      const auto ue = static_cast<std::size_t>(e);
      const auto& d = s.dofs[ue];
      double gl = 0, ga = 0;
      for (int k = 0; k < 12; ++k) {
        const int dof = d[static_cast<std::size_t>(k)];
        if (dof < 0) continue;
        gl -= s.g_lambda[ue](k) * z(dof, 0);
        ga -= s.g_alpha[ue](k) * z(dof, 0);
      }
      (*jtw)(2 * e, 0) = gl;
      (*jtw)(2 * e + 1, 0) = ga;
    }
    return {};
  }
  jtw->setZero(2 * t, w.cols());
  for (Eigen::Index e = 0; e < t; ++e) {
    const auto ue = static_cast<std::size_t>(e);
    const auto& d = s.dofs[ue];
    for (int k = 0; k < 12; ++k) {
      const int dof = d[static_cast<std::size_t>(k)];
      if (dof < 0) continue;
      jtw->row(2 * e).noalias() -= s.g_lambda[ue](k) * z.row(dof);
      jtw->row(2 * e + 1).noalias() -= s.g_alpha[ue](k) * z.row(dof);
    }
  }
  return {};
}

Status ExampleProblem::apply_jacobian_transpose(const Eigen::VectorXd& w,
                                                Eigen::VectorXd* jtw) const {
  Eigen::MatrixXd out;
  HC_RETURN_IF_ERROR(apply_jacobian_transpose(Eigen::MatrixXd(w), &out));
  *jtw = out.col(0);
  return {};
}

}  // namespace hc::material
