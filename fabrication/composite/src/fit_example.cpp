#include "fit_example.h"

#include <fmt/format.h>

#include <cmath>

#include "processing/fem/incremental.h"

namespace hc::composite {

Result<FitExample> FitExample::create(const material::Samples& samples, std::size_t index,
                                      BaseModel model, const ForwardOptions& forward) {
  const material::Example& ex = samples.examples[index];
  if (ex.fixed_nodes.empty())
    return invalid_argument("has no fixed node (the specimen would float)");
  if (ex.forces.empty()) return invalid_argument("has no applied force");
  HC_ASSIGN_OR_RETURN(fem::CorotationalFem f,
                      fem::CorotationalFem::create(samples.mesh, ex.fixed_nodes));
  FitExample out(&samples, index, model, forward, std::move(f));
  out.forces_ = example_forces(ex, samples.mesh.num_nodes());
  std::vector<double> target, rest;
  for (Eigen::Index n = 0; n < samples.mesh.num_nodes(); ++n) {
    if (!ex.visible[static_cast<std::size_t>(n)] || out.fem_.is_fixed(n)) continue;
    for (int c = 0; c < 3; ++c) {
      out.dofs_.push_back(out.fem_.dof(n, c));
      target.push_back(ex.positions_m(n, c));
      rest.push_back(samples.mesh.nodes(n, c));
    }
  }
  if (out.dofs_.empty()) return invalid_argument("measures no free node");
  out.target_ = Eigen::Map<const Eigen::VectorXd>(target.data(), static_cast<Eigen::Index>(target.size()));
  out.rest_ = Eigen::Map<const Eigen::VectorXd>(rest.data(), static_cast<Eigen::Index>(rest.size()));
  out.state_ = samples.mesh.nodes;
  return out;
}

void FitExample::hold_state(const BaseMaterial& material, bool at_rest) {
  const Eigen::Index t = fem_.num_elements();
  if (at_rest) {
    (void)fem_.set_positions(samples_->mesh.nodes);
    fem_.set_rotations_identity();
  } else {
    (void)fem_.set_positions(state_);
    fem_.update_rotations();
  }
  features_.resize(static_cast<std::size_t>(t));
  weights_.resize(t, material.num_centres());
  for (Eigen::Index e = 0; e < t; ++e) {
    const Vector6d strain = at_rest ? Vector6d::Zero().eval() : fem_.strain(e);
    features_[static_cast<std::size_t>(e)] = strain_features(model_, strain);
    weights_.row(e) = material.weights(strain).transpose();
  }
}

Status FitExample::simulate_full(const BaseMaterial& material) {
  const CompositeMaterial composite(std::vector<const BaseMaterial*>(
      static_cast<std::size_t>(fem_.num_elements()), &material));
  HC_RETURN_IF_ERROR(simulate_forces(&fem_, composite, forces_, forward_));
  state_ = fem_.positions();
  fem_.update_rotations();
  const Eigen::Index t = fem_.num_elements();
  features_.resize(static_cast<std::size_t>(t));
  for (Eigen::Index e = 0; e < t; ++e)
    features_[static_cast<std::size_t>(e)] = strain_features(model_, fem_.strain(e));
  return {};
}

void FitExample::set_material(const BaseMaterial& material) {
  const Eigen::Index t = fem_.num_elements();
  const Eigen::MatrixXd p = weights_ * material.values();  // #T by |p|, before projection
  // The material's own model: the start of a transverse fit simulates an isotropic unit material.
  const BaseModel model = material.model();
  if (model == BaseModel::kIsotropic) {
    std::vector<fem::LambdaAlpha> la(static_cast<std::size_t>(t));
    for (Eigen::Index e = 0; e < t; ++e) {
      const Eigen::VectorXd q = project_feasible(model, p.row(e).transpose(), material.limits());
      // Lame (lambda, mu) as Eq. 4.6's (lambda G + alpha H): alpha = lambda, "lambda" = 2 (lambda + mu).
      la[static_cast<std::size_t>(e)] = {2 * (q(0) + q(1)), q(0)};
    }
    fem_.clear_elasticity();
    (void)fem_.set_params(la);  // finite by projection
    return;
  }
  std::vector<Matrix6d> em(static_cast<std::size_t>(t));
  for (Eigen::Index e = 0; e < t; ++e)
    em[static_cast<std::size_t>(e)] = elasticity_matrix(
        model, project_feasible(model, p.row(e).transpose(), material.limits()));
  (void)fem_.set_elasticity(std::move(em));
}

Status FitExample::residual(const BaseMaterial& material, Eigen::VectorXd* r) {
  set_material(material);
  fem_.assemble();
  HC_RETURN_IF_ERROR(fem_.factorize());
  HC_RETURN_IF_ERROR(fem_.solve(forces_));
  r->resize(static_cast<Eigen::Index>(dofs_.size()));
  const MatrixX3d& x = fem_.positions();
  Eigen::Index at = 0;
  for (Eigen::Index n = 0; n < x.rows(); ++n) {
    if (fem_.is_fixed(n) || !example().visible[static_cast<std::size_t>(n)]) continue;
    for (int c = 0; c < 3; ++c, ++at) (*r)(at) = x(n, c) - target_(at);
  }
  return {};
}

Status FitExample::jacobian(const BaseMaterial& material, Eigen::MatrixXd* j) {
  // Appendix A (Eq. A.2) through the RBF: K dx = -[R^ dK_e (R^T x_e - X_e)]_e for every centre
  // value, dK_e = l_j(e) V_e B_e^T (dE/dp_k) B_e, with rotations and weights held.
  const Eigen::Index t = fem_.num_elements();
  const int k = parameter_count(model_);
  const Eigen::Index m = material.num_centres() * k;
  std::vector<Matrix6d> de(static_cast<std::size_t>(k));
  for (int q = 0; q < k; ++q) de[static_cast<std::size_t>(q)] = elasticity_derivative(model_, q);
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(fem_.num_free_dofs(), m);
  const auto& tets = samples_->mesh.tets;
  for (Eigen::Index e = 0; e < t; ++e) {
    const Eigen::Matrix3d& rot = fem_.rotation(e);
    const fem::Matrix6x12d b = fem_.b_matrix(e);
    fem::Vector12d u;
    for (int a = 0; a < 4; ++a)
      u.segment<3>(3 * a) = rot.transpose() * fem_.positions().row(tets(e, a)).transpose() -
                            samples_->mesh.nodes.row(tets(e, a)).transpose();
    const Vector6d eps = b * u;
    const std::array<int, 12> dofs = fem_.element_dofs(e);
    for (int q = 0; q < k; ++q) {
      const fem::Vector12d fl = fem_.volume(e) * b.transpose() * (de[static_cast<std::size_t>(q)] * eps);
      fem::Vector12d fw;
      for (int a = 0; a < 4; ++a) fw.segment<3>(3 * a) = rot * fl.segment<3>(3 * a);
      for (Eigen::Index c = 0; c < material.num_centres(); ++c) {
        const double w = weights_(e, c);
        if (w == 0) continue;
        for (int i = 0; i < 12; ++i)
          if (dofs[static_cast<std::size_t>(i)] >= 0)
            g(dofs[static_cast<std::size_t>(i)], c * k + q) += w * fw(i);
      }
    }
  }
  Eigen::MatrixXd z;
  HC_RETURN_IF_ERROR(fem_.cholesky().solve(g, &z));
  j->resize(static_cast<Eigen::Index>(dofs_.size()), m);
  for (std::size_t i = 0; i < dofs_.size(); ++i)
    j->row(static_cast<Eigen::Index>(i)) = -z.row(dofs_[i]);
  return {};
}

Result<std::pair<double, double>> FitExample::unit_displacement_dots(const BaseMaterial& unit) {
  hold_state(unit, /*at_rest=*/true);
  Eigen::VectorXd r;
  HC_RETURN_IF_ERROR(residual(unit, &r));
  const Eigen::VectorXd u = r + target_ - rest_;  // simulated displacement
  const Eigen::VectorXd ubar = target_ - rest_;   // measured displacement
  return std::make_pair(u.squaredNorm(), u.dot(ubar));
}

bool FitExample::forces_parallel(double tolerance) const {
  Eigen::Vector3d total = Eigen::Vector3d::Zero();
  for (const material::NodalForce& f : example().forces) total += f.force_n;
  if (!(total.norm() > 0)) return false;
  const Eigen::Vector3d d = total.normalized();
  for (const material::NodalForce& f : example().forces)
    if ((f.force_n - f.force_n.dot(d) * d).norm() > tolerance * f.force_n.norm()) return false;
  return true;
}

Status FitExample::recover_tangential_forces(const BaseMaterial& material) {
  const material::Example& ex = example();
  Eigen::Vector3d total = Eigen::Vector3d::Zero();
  for (const material::NodalForce& f : ex.forces) total += f.force_n;
  if (!(total.norm() > 0)) return {};
  const Eigen::Vector3d d = total.normalized();
  std::vector<int> held = ex.fixed_nodes;
  std::vector<int> probed;
  for (const material::NodalForce& f : ex.forces)
    if (ex.visible[static_cast<std::size_t>(f.node)] && !fem_.is_fixed(f.node) &&
        f.force_n.norm() > 0)
      probed.push_back(f.node);
  if (probed.empty()) return {};
  held.insert(held.end(), probed.begin(), probed.end());
  std::sort(held.begin(), held.end());
  HC_ASSIGN_OR_RETURN(fem::CorotationalFem f, fem::CorotationalFem::create(samples_->mesh, held));
  MatrixX3d x = samples_->mesh.nodes;
  for (int n : probed) x.row(n) = ex.positions_m.row(n);
  HC_RETURN_IF_ERROR(f.set_positions(x));
  const CompositeMaterial composite(std::vector<const BaseMaterial*>(
      static_cast<std::size_t>(f.num_elements()), &material));
  fem::update_params_from_strain(&f, composite);
  const double size = (samples_->mesh.nodes.colwise().maxCoeff() -
                       samples_->mesh.nodes.colwise().minCoeff()).norm();
  HC_RETURN_IF_ERROR(f.solve_static(MatrixX3d::Zero(x.rows(), 3), forward_.max_iterations,
                                    forward_.tolerance_rel * 1e-3 * size));
  const MatrixX3d elastic = f.elastic_forces();
  for (int n : probed) {
    const Eigen::Vector3d reaction = -elastic.row(n).transpose();
    forces_.row(n) += (reaction - reaction.dot(d) * d).transpose();
  }
  return {};
}

double FitExample::rms_error(const std::vector<FitExample>& examples) {
  double sum = 0;
  Eigen::Index nodes = 0;
  for (const FitExample& ex : examples) {
    const ExampleError e = example_error(ex.example(), ex.state_);
    sum += e.sum_sq_m2;
    nodes += e.nodes;
  }
  return nodes > 0 ? std::sqrt(sum / static_cast<double>(nodes)) : 0.0;
}

}  // namespace hc::composite
