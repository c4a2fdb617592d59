// Adapter from processing/fem's probes to the hyperelastic contact interface.
#include "processing/hyperelastic/fem_probe.h"

#include <fmt/format.h>

#include <cmath>

namespace hc::hyperelastic {
namespace {

class FemProbeContact final : public RigidProbe {
 public:
  FemProbeContact(std::unique_ptr<fem::Probe> probe, double k)
      : probe_(std::move(probe)), start_(probe_->pose()), k_(k) {}

  void set_depth(double depth_m) override {
    depth_ = depth_m;
    probe_->set_pose(start_);
    probe_->advance(depth_m);
  }
  double depth() const override { return depth_; }
  Eigen::Vector3d direction() const override { return probe_->direction(); }

  double node_energy(const Eigen::Vector3d& p, Eigen::Vector3d* grad,
                     Eigen::Matrix3d* hess) const override {
    Eigen::Vector3d n;
    const double s = probe_->signed_distance(p, &n);
    if (!(s < 0)) return 0;
    if (grad != nullptr) *grad += k_ * s * n;
    if (hess != nullptr) *hess += k_ * n * n.transpose();
    return 0.5 * k_ * s * s;
  }

 private:
  std::unique_ptr<fem::Probe> probe_;
  Eigen::Isometry3d start_;
  double k_;
  double depth_ = 0;
};

}  // namespace

Result<std::unique_ptr<RigidProbe>> make_fem_probe_contact(const fem::Probe& probe,
                                                           double stiffness_n_per_m) {
  if (!(std::isfinite(stiffness_n_per_m) && stiffness_n_per_m > 0))
    return invalid_argument(
        fmt::format("contact stiffness {} N/m must be positive and finite", stiffness_n_per_m));
  return std::unique_ptr<RigidProbe>(
      std::make_unique<FemProbeContact>(probe.clone(), stiffness_n_per_m));
}

}  // namespace hc::hyperelastic
