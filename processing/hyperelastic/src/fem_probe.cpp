// Adapter from processing/fem's probes to the hyperelastic contact interface.
#include "processing/hyperelastic/fem_probe.h"

#include <fmt/format.h>

#include <cmath>

namespace hc::hyperelastic {
namespace {

// A processing/fem probe moved along its axis from its start pose: the part both contact rules
// below share.
class FemRigidProbe : public RigidProbe {
 public:
  // penalty_scale > 0: the stiffnesses are that times the block's own (point_hessian).
  FemRigidProbe(std::unique_ptr<fem::Probe> probe, double penalty_scale)
      : probe_(std::move(probe)),
        penalty_scale_(penalty_scale),
        sphere_(dynamic_cast<const fem::SphereProbe*>(probe_.get()) != nullptr),
        start_(probe_->pose()) {}

  void set_depth(double depth_m) override {
    depth_ = depth_m;
    probe_->set_pose(start_);
    probe_->advance(depth_m);
  }
  double depth() const override { return depth_; }
  Eigen::Vector3d direction() const override { return probe_->direction(); }

 protected:
  std::unique_ptr<fem::Probe> probe_;

  // correct_step() for one node: inside at x and, by the linear model, still inside at x_try,
  // moved along the normal at x_try to the penetration the model predicts.
  void correct_node(const Eigen::VectorXd& x, int node, Eigen::VectorXd* x_try) const {
    const Eigen::Index at = 3 * static_cast<Eigen::Index>(node);
    Eigen::Vector3d n;
    const double s = probe_->signed_distance(x.segment<3>(at), &n);
    if (!(s < 0)) return;
    const double predicted = s + n.dot(x_try->segment<3>(at) - x.segment<3>(at));
    if (!(predicted < 0)) return;  // the model lets it leave the probe
    const double now = probe_->signed_distance(x_try->segment<3>(at), &n);
    x_try->segment<3>(at) -= (now - predicted) * n;
  }

  // The Hessian of the penalty k/2 s² at a point at x (signed distance s < 0, outward normal n):
  // k (n nᵀ + s ∇n). The second part is the curvature of the probe's surface, ∇n = (I − n nᵀ)/ρ
  // on a sphere (ρ: distance from its centre). Without it Newton converges only linearly once the
  // contact forces are large (per point F/ρ against the block's own stiffness: the simulated
  // specimen's default location took 153 Newton iterations instead of 39). It is negative
  // semi-definite (s < 0), so it is left out when `project` asks for a PSD Hessian, and where it
  // exceeds the block's own stiffness at the point, k / penalty_scale (|s| / ρ > 1 /
  // penalty_scale): a penetration that deep is far from equilibrium (the first iteration after the
  // probe moved; at equilibrium |s| = F/k), where the term made the Hessian indefinite and every
  // load step paid a failed factorization and a projected Hessian (that location: 5.9 -> 4.4 s).
  // fem's other probes give no curvature: Gauss–Newton k n nᵀ alone.
  Eigen::Matrix3d point_hessian(const Eigen::Vector3d& x, const Eigen::Vector3d& n, double s,
                                double k, bool project) const {
    const Eigen::Matrix3d nn = n * n.transpose();
    if (!sphere_ || project) return k * nn;
    const double rho = (x - probe_->pose().translation()).norm();
    if (!(rho > 0) || (penalty_scale_ > 0 && -s * penalty_scale_ > rho)) return k * nn;
    return k * (nn + (s / rho) * (Eigen::Matrix3d::Identity() - nn));
  }

 private:
  double penalty_scale_;
  bool sphere_;  // fem::SphereProbe, whose surface curvature the Hessian includes
  Eigen::Isometry3d start_;
  double depth_ = 0;
};

class FemProbeContact final : public FemRigidProbe {
 public:
  FemProbeContact(std::unique_ptr<fem::Probe> probe, double k)
      : FemRigidProbe(std::move(probe), 0), k_(k) {}

  double node_energy(const Eigen::Vector3d& p, Eigen::Vector3d* grad,
                     Eigen::Matrix3d* hess) const override {
    Eigen::Vector3d n;
    const double s = probe_->signed_distance(p, &n);
    if (!(s < 0)) return 0;
    if (grad != nullptr) *grad += k_ * s * n;
    if (hess != nullptr) *hess += point_hessian(p, n, s, k_, false);
    return 0.5 * k_ * s * s;
  }
  void correct_step(const Eigen::VectorXd& x, Eigen::VectorXd* x_try) const override {
    for (Eigen::Index i = 0; i < x.size() / 3; ++i) correct_node(x, static_cast<int>(i), x_try);
  }

 private:
  double k_;
};

class FemSurfaceContact final : public FemRigidProbe {
 public:
  FemSurfaceContact(std::unique_ptr<fem::Probe> probe, const fem::ContactSurface& surface,
                    std::vector<double> k, double penalty_scale)
      : FemRigidProbe(std::move(probe), penalty_scale), surface_(surface), k_(std::move(k)) {}

  double energy(const Eigen::VectorXd& x, Eigen::VectorXd* grad,
                std::vector<Eigen::Triplet<double>>* hessian, bool project) const override {
    const Eigen::Map<const MatrixX3d> pos(x.data(), x.size() / 3, 3);
    const std::vector<fem::ContactPoint>& points = surface_.points();
    double e = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!(k_[i] > 0)) continue;
      const fem::ContactPoint& p = points[i];
      Eigen::Vector3d xp = Eigen::Vector3d::Zero();
      const int terms = p.is_node() ? 1 : 3;
      for (int a = 0; a < terms; ++a)
        xp += p.weights(a) * pos.row(p.nodes[static_cast<std::size_t>(a)]).transpose();
      Eigen::Vector3d n;
      const double s = probe_->signed_distance(xp, &n);
      if (!(s < 0)) continue;
      e += 0.5 * k_[i] * s * s;
      const Eigen::Matrix3d h =
          hessian == nullptr ? Eigen::Matrix3d::Zero() : point_hessian(xp, n, s, k_[i], project);
      for (int a = 0; a < terms; ++a) {
        const int na = p.nodes[static_cast<std::size_t>(a)];
        if (grad != nullptr) grad->segment<3>(3 * na) += p.weights(a) * k_[i] * s * n;
        if (hessian == nullptr) continue;
        // The point moves as Σ w_a x_a: block (a, b) is w_a w_b times the point's Hessian.
        for (int b = 0; b < terms; ++b) {
          const int nb = p.nodes[static_cast<std::size_t>(b)];
          const Eigen::Matrix3d block = p.weights(a) * p.weights(b) * h;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c)
              hessian->emplace_back(3 * na + r, 3 * nb + c, block(r, c));
        }
      }
    }
    return e;
  }

  // Node points only: a correction of a point on a face would have to be shared among its nodes,
  // and several points share a face; those are left to Newton.
  void correct_step(const Eigen::VectorXd& x, Eigen::VectorXd* x_try) const override {
    const std::vector<fem::ContactPoint>& points = surface_.points();
    for (std::size_t i = 0; i < points.size(); ++i)
      if (points[i].is_node() && k_[i] > 0) correct_node(x, points[i].nodes[0], x_try);
  }

 private:
  fem::ContactSurface surface_;
  std::vector<double> k_;
};

}  // namespace

Result<std::unique_ptr<RigidProbe>> make_fem_surface_contact(const fem::Probe& probe,
                                                             const fem::ContactSurface& surface,
                                                             std::vector<double> stiffness,
                                                             double penalty_scale) {
  if (stiffness.size() != surface.points().size())
    return invalid_argument(fmt::format("{} contact stiffnesses for {} contact points",
                                        stiffness.size(), surface.points().size()));
  for (double k : stiffness)
    if (!(std::isfinite(k) && k >= 0))
      return invalid_argument(fmt::format("contact stiffness {} N/m must be >= 0 and finite", k));
  if (!(std::isfinite(penalty_scale) && penalty_scale >= 0))
    return invalid_argument(fmt::format("penalty scale {} must be >= 0 and finite", penalty_scale));
  return std::unique_ptr<RigidProbe>(std::make_unique<FemSurfaceContact>(
      probe.clone(), surface, std::move(stiffness), penalty_scale));
}

Result<std::unique_ptr<RigidProbe>> make_fem_probe_contact(const fem::Probe& probe,
                                                           double stiffness_n_per_m) {
  if (!(std::isfinite(stiffness_n_per_m) && stiffness_n_per_m > 0))
    return invalid_argument(
        fmt::format("contact stiffness {} N/m must be positive and finite", stiffness_n_per_m));
  return std::unique_ptr<RigidProbe>(
      std::make_unique<FemProbeContact>(probe.clone(), stiffness_n_per_m));
}

}  // namespace hc::hyperelastic
