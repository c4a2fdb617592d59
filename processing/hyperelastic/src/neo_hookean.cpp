// Compressible neo-Hookean material, discrete model, probes.
#include "processing/hyperelastic/neo_hookean.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

namespace hc::hyperelastic {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

double NeoHookeanMaterial::mu_pa() const { return youngs_pa / (2.0 * (1.0 + poisson)); }
double NeoHookeanMaterial::lambda_pa() const {
  return youngs_pa * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
}

Status NeoHookeanMaterial::validate() const {
  if (!(std::isfinite(youngs_pa) && youngs_pa > 0))
    return invalid_argument(fmt::format("Young's modulus {} Pa must be positive", youngs_pa));
  if (!(std::isfinite(poisson) && poisson > -1.0 && poisson < 0.5))
    return invalid_argument(fmt::format("Poisson's ratio {} must be in (-1, 0.5)", poisson));
  if (!(std::isfinite(stiffening) && stiffening >= 0))
    return invalid_argument(fmt::format("stiffening {} must be >= 0", stiffening));
  if (!(std::isfinite(fibre_pa) && fibre_pa >= 0))
    return invalid_argument(fmt::format("fibre modulus {} Pa must be >= 0", fibre_pa));
  if (!fibre_axis.allFinite() || std::abs(fibre_axis.norm() - 1.0) > 1e-9)
    return invalid_argument("fibre axis must be a unit vector");
  return {};
}

Result<std::vector<NeoHookeanMaterial>> layered_materials(const TetMesh& mesh,
                                                          std::span<const MaterialLayer> layers) {
  if (layers.empty()) return invalid_argument("no material layers");
  for (std::size_t l = 0; l < layers.size(); ++l) {
    if (Status s = layers[l].material.validate(); !s.ok())
      return s.with_context(fmt::format("layer {}", l));
    if (!(layers[l].z_min_m < layers[l].z_max_m))
      return invalid_argument(fmt::format("layer {}: z range [{}, {}) is empty", l,
                                          layers[l].z_min_m, layers[l].z_max_m));
  }
  std::size_t top = 0;
  for (std::size_t l = 1; l < layers.size(); ++l)
    if (layers[l].z_max_m > layers[top].z_max_m) top = l;
  std::vector<NeoHookeanMaterial> out(static_cast<std::size_t>(mesh.num_tets()));
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) {
    double z = 0;
    for (int k = 0; k < 4; ++k) z += mesh.nodes(mesh.tets(t, k), 2) / 4.0;
    bool found = false;
    for (std::size_t l = 0; l < layers.size() && !found; ++l) {
      if ((z >= layers[l].z_min_m && z < layers[l].z_max_m) ||
          (l == top && z == layers[l].z_max_m)) {
        out[static_cast<std::size_t>(t)] = layers[l].material;
        found = true;
      }
    }
    if (!found)
      return invalid_argument(
          fmt::format("tet {}: centroid z = {} m lies in no material layer", t, z));
  }
  return out;
}

namespace {

// ψ_f = E_f/8 (I4 − 1)², I4 = |F a|²:  P_f = E_f/2 (I4 − 1) F a aᵀ and, with g = vec(F a aᵀ),
// ∂P_f/∂F = E_f g gᵀ + E_f/2 (I4 − 1) (a aᵀ ⊗ I) in the 3·col + row ordering.
void add_fibre_term(const NeoHookeanMaterial& m, const Eigen::Matrix3d& F, double* psi,
                    Eigen::Matrix3d* P, Eigen::Matrix<double, 9, 9>* dP_dF) {
  const Eigen::Vector3d& a = m.fibre_axis;
  const Eigen::Vector3d fa = F * a;
  const double i4m1 = fa.squaredNorm() - 1.0;
  *psi += 0.125 * m.fibre_pa * i4m1 * i4m1;
  const Eigen::Matrix3d faat = fa * a.transpose();
  if (P != nullptr) *P += 0.5 * m.fibre_pa * i4m1 * faat;
  if (dP_dF != nullptr) {
    const Eigen::Map<const Eigen::Matrix<double, 9, 1>> g(faat.data());
    *dP_dF += m.fibre_pa * g * g.transpose();
    const Eigen::Matrix3d aat = a * a.transpose();
    for (int j = 0; j < 3; ++j)
      for (int l = 0; l < 3; ++l)
        for (int i = 0; i < 3; ++i) (*dP_dF)(3 * j + i, 3 * l + i) += 0.5 * m.fibre_pa * i4m1 * aat(j, l);
  }
}

}  // namespace

double neo_hookean_density(const NeoHookeanMaterial& m, const Eigen::Matrix3d& F,
                           Eigen::Matrix3d* P, Eigen::Matrix<double, 9, 9>* dP_dF) {
  const double J = F.determinant();
  if (!(J > 0)) return kInf;
  const double mu = m.mu_pa();
  const double lambda = m.lambda_pa();
  const double beta = m.stiffening;
  const double lnJ = std::log(J);
  const double I1 = F.squaredNorm();
  const double q = I1 - 3.0 - 2.0 * lnJ;
  double psi =
      0.5 * mu * (I1 - 3.0) - mu * lnJ + 0.5 * lambda * lnJ * lnJ + 0.25 * beta * mu * q * q;
  if (P == nullptr && dP_dF == nullptr) {
    if (m.fibre_pa > 0) add_fibre_term(m, F, &psi, nullptr, nullptr);
    return psi;
  }
  const Eigen::Matrix3d Finv = F.inverse();
  const Eigen::Matrix3d FinvT = Finv.transpose();
  const Eigen::Matrix3d A = F - FinvT;  // ∂(I1 − 2 ln J)/∂F / 2
  if (P != nullptr) *P = mu * F + (lambda * lnJ - mu) * FinvT + beta * mu * q * A;
  if (dP_dF != nullptr) {
    // Directional derivative along each unit dF (vec index 3·col + row):
    //   dP = μ dF + (μ − λ ln J) F⁻ᵀ dFᵀ F⁻ᵀ + λ tr(F⁻¹ dF) F⁻ᵀ
    //        + βμ [2 (A : dF) A + q (dF + F⁻ᵀ dFᵀ F⁻ᵀ)]
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) {
        Eigen::Matrix3d dF = Eigen::Matrix3d::Zero();
        dF(r, c) = 1.0;
        const Eigen::Matrix3d G = FinvT * dF.transpose() * FinvT;
        const double tr = Finv(c, r);  // tr(F⁻¹ dF) = F⁻¹(c, r)
        Eigen::Matrix3d dP = mu * dF + (mu - lambda * lnJ) * G + lambda * tr * FinvT;
        if (beta != 0) dP += beta * mu * (2.0 * A(r, c) * A + q * (dF + G));
        dP_dF->col(3 * c + r) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dP.data());
      }
  }
  if (m.fibre_pa > 0) add_fibre_term(m, F, &psi, P, dP_dF);
  return psi;
}

// ---- Probes ----
namespace {

class ProbeBase : public RigidProbe {
 public:
  explicit ProbeBase(const ProbeOptions& o)
      : start_(o.start_position_m),
        dir_(o.direction.normalized()),
        r_(o.radius_m),
        k_(o.stiffness_n_per_m) {}
  void set_depth(double depth_m) override { depth_ = depth_m; }
  double depth() const override { return depth_; }
  Eigen::Vector3d direction() const override { return dir_; }

 protected:
  Eigen::Vector3d centre() const { return start_ + depth_ * dir_; }
  Eigen::Vector3d start_;
  Eigen::Vector3d dir_;
  double r_;
  double k_;
  double depth_ = 0;
};

class SphereProbe final : public ProbeBase {
 public:
  using ProbeBase::ProbeBase;
  double node_energy(const Eigen::Vector3d& p, Eigen::Vector3d* grad,
                     Eigen::Matrix3d* hess) const override {
    const Eigen::Vector3d d = p - centre();
    const double dist = d.norm();
    const double s = dist - r_;  // signed distance, < 0 inside
    if (s >= 0 || dist <= 0) return 0;
    const Eigen::Vector3d n = d / dist;
    if (grad != nullptr) *grad += k_ * s * n;
    if (hess != nullptr) {
      const Eigen::Matrix3d nn = n * n.transpose();
      // Exact: k (n nᵀ + s (I − n nᵀ)/|d|); the second part is negative (s < 0), which the
      // solver's PSD fallback handles if it makes the system indefinite.
      *hess += k_ * (nn + (s / dist) * (Eigen::Matrix3d::Identity() - nn));
    }
    return 0.5 * k_ * s * s;
  }
};

class FlatProbe final : public ProbeBase {
 public:
  using ProbeBase::ProbeBase;
  double node_energy(const Eigen::Vector3d& p, Eigen::Vector3d* grad,
                     Eigen::Matrix3d* hess) const override {
    const Eigen::Vector3d d = p - centre();
    const double s = d.dot(dir_);  // < 0: behind the face, i.e. inside when within the radius
    if (s >= 0) return 0;
    const Eigen::Vector3d radial = d - s * dir_;
    const double rho = radial.norm();
    if (rho >= r_) return 0;
    const double face_pen = -s;
    const double side_pen = r_ - rho;
    if (face_pen <= side_pen || rho <= 0) {
      if (grad != nullptr) *grad += k_ * s * dir_;
      if (hess != nullptr) *hess += k_ * dir_ * dir_.transpose();
      return 0.5 * k_ * s * s;
    }
    // Closer to the cylinder wall: pushed out radially (Gauss–Newton Hessian; a rim case).
    const Eigen::Vector3d e = radial / rho;
    if (grad != nullptr) *grad += -k_ * side_pen * e;
    if (hess != nullptr) *hess += k_ * e * e.transpose();
    return 0.5 * k_ * side_pen * side_pen;
  }
};

}  // namespace

std::unique_ptr<RigidProbe> make_sphere_probe(const ProbeOptions& options) {
  return std::make_unique<SphereProbe>(options);
}
std::unique_ptr<RigidProbe> make_flat_probe(const ProbeOptions& options) {
  return std::make_unique<FlatProbe>(options);
}

double ContactPotential::node_energy(const Eigen::Vector3d&, Eigen::Vector3d*,
                                     Eigen::Matrix3d*) const {
  return 0;
}

void ContactPotential::correct_step(const Eigen::VectorXd& /*x*/,
                                    Eigen::VectorXd* /*x_try*/) const {}

double ContactPotential::energy(const Eigen::VectorXd& x, Eigen::VectorXd* grad,
                                std::vector<Eigen::Triplet<double>>* hessian, bool project) const {
  double e = 0;
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) {
    Eigen::Vector3d gi = Eigen::Vector3d::Zero();
    Eigen::Matrix3d hi = Eigen::Matrix3d::Zero();
    const double ei = node_energy(x.segment<3>(3 * i), grad != nullptr ? &gi : nullptr,
                                  hessian != nullptr ? &hi : nullptr);
    if (ei == 0 && gi.isZero()) continue;
    e += ei;
    if (grad != nullptr) grad->segment<3>(3 * i) += gi;
    if (hessian != nullptr) {
      if (project) {
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(hi);
        hi = es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).asDiagonal() *
             es.eigenvectors().transpose();
      }
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          hessian->emplace_back(static_cast<int>(3 * i + a), static_cast<int>(3 * i + b),
                                hi(a, b));
    }
  }
  return e;
}

Eigen::Vector3d contact_force(const ContactPotential& c, const Eigen::VectorXd& x) {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(x.size());
  c.energy(x, &g, nullptr, false);
  return -Eigen::Map<const MatrixX3d>(g.data(), x.size() / 3, 3).colwise().sum().transpose();
}

MatrixX3d contact_forces(const ContactPotential& c, const Eigen::VectorXd& x) {
  Eigen::VectorXd g = Eigen::VectorXd::Zero(x.size());
  c.energy(x, &g, nullptr, false);
  return -Eigen::Map<const MatrixX3d>(g.data(), x.size() / 3, 3);
}

// ---- The discrete model ----

Result<NeoHookeanModel> NeoHookeanModel::create(const TetMesh& mesh,
                                                std::vector<NeoHookeanMaterial> materials) {
  const Eigen::Index n = mesh.num_nodes();
  const Eigen::Index nt = mesh.num_tets();
  if (n < 4 || nt < 1) return invalid_argument("tet mesh is empty");
  if (!mesh.nodes.allFinite()) return invalid_argument("tet mesh has a non-finite node");
  if (materials.size() == 1 && nt > 1)
    materials.assign(static_cast<std::size_t>(nt), materials.front());
  if (std::ssize(materials) != nt)
    return invalid_argument(fmt::format("{} materials for {} tets (expected one per tet, or one)",
                                        materials.size(), nt));
  for (std::size_t t = 0; t < materials.size(); ++t)
    if (Status s = materials[t].validate(); !s.ok())
      return s.with_context(fmt::format("tet {}", t));
  const Eigen::Vector3d extent =
      (mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff()).transpose();
  const double box_volume = std::max(extent.prod(), std::pow(extent.maxCoeff(), 3) * 1e-6);
  NeoHookeanModel model;
  model.mesh_ = mesh;
  model.materials_ = std::move(materials);
  model.rest_volumes_.resize(static_cast<std::size_t>(nt));
  model.dm_inv_.resize(static_cast<std::size_t>(nt));
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 4; ++k)
      if (mesh.tets(t, k) < 0 || mesh.tets(t, k) >= n)
        return invalid_argument(
            fmt::format("tet {}: node index {} out of range", t, mesh.tets(t, k)));
    Eigen::Matrix3d Dm;
    const Eigen::Vector3d x0 = mesh.nodes.row(mesh.tets(t, 0)).transpose();
    for (int k = 0; k < 3; ++k) Dm.col(k) = mesh.nodes.row(mesh.tets(t, k + 1)).transpose() - x0;
    const double v = Dm.determinant() / 6.0;
    if (v < 0)
      return invalid_argument(fmt::format("tet {} is inverted (signed rest volume {} m^3)", t, v));
    if (!(v > 1e-12 * box_volume))
      return invalid_argument(fmt::format("tet {} is degenerate (rest volume {} m^3)", t, v));
    model.rest_volumes_[static_cast<std::size_t>(t)] = v;
    model.dm_inv_[static_cast<std::size_t>(t)] = Dm.inverse();
  }
  // The Hessian's pattern and each element entry's slot in it (binary search in its column).
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(nt) * 144);
  for (Eigen::Index t = 0; t < nt; ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            triplets.emplace_back(3 * mesh.tets(t, a) + i, 3 * mesh.tets(t, b) + j, 0.0);
  model.hessian_pattern_.resize(3 * n, 3 * n);
  model.hessian_pattern_.setFromTriplets(triplets.begin(), triplets.end());
  model.hessian_pattern_.makeCompressed();
  const int* outer = model.hessian_pattern_.outerIndexPtr();
  const int* inner = model.hessian_pattern_.innerIndexPtr();
  model.hessian_slot_.resize(triplets.size());
  for (std::size_t k = 0; k < triplets.size(); ++k) {
    const int col = triplets[k].col();
    const int* at = std::lower_bound(inner + outer[col], inner + outer[col + 1], triplets[k].row());
    model.hessian_slot_[k] = static_cast<int>(at - inner);
  }
  return model;
}

Eigen::VectorXd NeoHookeanModel::rest_positions() const {
  Eigen::VectorXd x(num_dofs());
  for (Eigen::Index i = 0; i < mesh_.num_nodes(); ++i)
    x.segment<3>(3 * i) = mesh_.nodes.row(i).transpose();
  return x;
}

Eigen::Matrix3d NeoHookeanModel::deformation_gradient(const Eigen::VectorXd& x,
                                                      Eigen::Index t) const {
  Eigen::Matrix3d Ds;
  const Eigen::Vector3d x0 = x.segment<3>(3 * mesh_.tets(t, 0));
  for (int k = 0; k < 3; ++k) Ds.col(k) = x.segment<3>(3 * mesh_.tets(t, k + 1)) - x0;
  return Ds * dm_inv_[static_cast<std::size_t>(t)];
}

double NeoHookeanModel::energy(const Eigen::VectorXd& x) const {
  double e = 0;
  for (Eigen::Index t = 0; t < mesh_.num_tets(); ++t) {
    const double psi = neo_hookean_density(materials_[static_cast<std::size_t>(t)],
                                           deformation_gradient(x, t), nullptr, nullptr);
    if (!std::isfinite(psi)) return kInf;
    e += rest_volumes_[static_cast<std::size_t>(t)] * psi;
  }
  return e;
}

double NeoHookeanModel::energy_gradient_hessian(const Eigen::VectorXd& x, Eigen::VectorXd* gradient,
                                                Eigen::SparseMatrix<double>* hessian,
                                                bool project_psd) const {
  const Eigen::Index nt = mesh_.num_tets();
  // Elements in parallel into per-element buffers, then gathered in element order (the sums are
  // the same, bit for bit, whatever the thread count).
  std::vector<double> energy(static_cast<std::size_t>(nt));
  std::vector<Eigen::Matrix<double, 12, 1>> element_gradient(
      gradient != nullptr ? static_cast<std::size_t>(nt) : 0);
  std::vector<Eigen::Matrix<double, 12, 12>> element_hessian(
      hessian != nullptr ? static_cast<std::size_t>(nt) : 0);
  std::atomic<bool> inverted = false;
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, nt, 256), [&](const auto& range) {
    Eigen::Matrix3d P;
    Eigen::Matrix<double, 9, 9> dPdF;
    for (Eigen::Index t = range.begin(); t != range.end(); ++t) {
      const auto ts = static_cast<std::size_t>(t);
      const Eigen::Matrix3d F = deformation_gradient(x, t);
      const double psi =
          neo_hookean_density(materials_[ts], F, &P, hessian != nullptr ? &dPdF : nullptr);
      if (!std::isfinite(psi)) {
        inverted = true;
        return;
      }
      const double V = rest_volumes_[ts];
      energy[ts] = V * psi;
      // B: 9×12, vec(F) = B·[x0; x1; x2; x3]; ∂F(r,c)/∂x_a(r) = g_a(c), g_{k+1} = Dm⁻¹ row k,
      // g_0 = −Σ rows.
      const Eigen::Matrix3d& Dinv = dm_inv_[ts];
      Eigen::Matrix<double, 4, 3> g;
      g.block<3, 3>(1, 0) = Dinv;
      g.row(0) = -Dinv.colwise().sum();
      Eigen::Matrix<double, 9, 12> B = Eigen::Matrix<double, 9, 12>::Zero();
      for (int a = 0; a < 4; ++a)
        for (int c = 0; c < 3; ++c)
          for (int r = 0; r < 3; ++r) B(3 * c + r, 3 * a + r) = g(a, c);
      if (gradient != nullptr)
        element_gradient[ts] =
            V * B.transpose() * Eigen::Map<const Eigen::Matrix<double, 9, 1>>(P.data());
      if (hessian != nullptr) {
        Eigen::Matrix<double, 12, 12> He = V * B.transpose() * dPdF * B;
        He = 0.5 * (He + He.transpose());
        if (project_psd) {
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(He);
          const Eigen::Matrix<double, 12, 1> ev = es.eigenvalues().cwiseMax(0.0);
          He = es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
        }
        element_hessian[ts] = He;
      }
    }
  });
  if (inverted) return kInf;
  double e = 0;
  for (const double et : energy) e += et;
  if (gradient != nullptr) {
    gradient->setZero(num_dofs());
    for (Eigen::Index t = 0; t < nt; ++t)
      for (int a = 0; a < 4; ++a)
        gradient->segment<3>(3 * mesh_.tets(t, a)) +=
            element_gradient[static_cast<std::size_t>(t)].segment<3>(3 * a);
  }
  if (hessian != nullptr) {
    *hessian = hessian_pattern_;
    double* value = hessian->valuePtr();
    std::fill(value, value + hessian->nonZeros(), 0.0);
    const int* slot = hessian_slot_.data();
    for (Eigen::Index t = 0; t < nt; ++t) {
      const Eigen::Matrix<double, 12, 12>& He = element_hessian[static_cast<std::size_t>(t)];
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) value[*slot++] += He(3 * a + i, 3 * b + j);
    }
  }
  return e;
}

Eigen::VectorXd NeoHookeanModel::internal_forces(const Eigen::VectorXd& x) const {
  Eigen::VectorXd g;
  if (!std::isfinite(energy_gradient_hessian(x, &g, nullptr)))
    return Eigen::VectorXd::Constant(num_dofs(), kInf);
  return g;
}

}  // namespace hc::hyperelastic
