#include "rig_daemon/simulation/specimen.h"

#include <cmath>
#include <numbers>

namespace hc::devices::sim {

Status HertzSpecimen::Options::validate() const {
  if (!(youngs_modulus_pa > 0.0))
    return invalid_argument("specimen: youngs_modulus_pa must be > 0");
  if (!(poisson_ratio >= 0.0 && poisson_ratio < 0.5))
    return invalid_argument("specimen: poisson_ratio must be in [0, 0.5)");
  if (!(stiffening >= 0.0)) return invalid_argument("specimen: stiffening must be >= 0");
  if (!(size_m.x() > 0.0 && size_m.y() > 0.0))
    return invalid_argument("specimen: size_m must be > 0");
  if (!(marker_spacing_m > 0.0) || !(marker_radius_m > 0.0) ||
      !(2.0 * marker_radius_m < marker_spacing_m))
    return invalid_argument(
        "specimen: marker_radius_m and marker_spacing_m must be > 0 with dots not touching");
  if (!std::isfinite(top_z_m)) return invalid_argument("specimen: top_z_m must be finite");
  return {};
}

std::vector<Eigen::Vector3d> marker_grid(const Eigen::AlignedBox2d& footprint, double spacing_m,
                                         double z_m) {
  std::vector<Eigen::Vector3d> out;
  if (!(spacing_m > 0.0) || footprint.isEmpty()) return out;
  const Eigen::Vector2d size = footprint.sizes();
  // Tiny slack so that a footprint that is an exact multiple of the spacing keeps both edges.
  const auto nx = static_cast<int>(std::floor(size.x() / spacing_m + 1e-9)) + 1;
  const auto ny = static_cast<int>(std::floor(size.y() / spacing_m + 1e-9)) + 1;
  const Eigen::Vector2d c = footprint.center();
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      out.emplace_back(c.x() + (i - 0.5 * (nx - 1)) * spacing_m,
                       c.y() + (j - 0.5 * (ny - 1)) * spacing_m, z_m);
  return out;
}

HertzSpecimen::HertzSpecimen(const Options& options) : options_(options) {
  markers_ = marker_grid(footprint(), options_.marker_spacing_m, options_.top_z_m);
}

Eigen::AlignedBox2d HertzSpecimen::footprint() const {
  return {options_.center_m - 0.5 * options_.size_m, options_.center_m + 0.5 * options_.size_m};
}

double HertzSpecimen::effective_modulus_pa() const {
  const double nu = options_.poisson_ratio;
  return options_.youngs_modulus_pa / (1.0 - nu * nu);
}

double HertzSpecimen::force_n(const Indentation& ind) const {
  if (!(ind.depth_m > 0.0) || !(ind.probe_radius_m > 0.0)) return 0.0;
  if (!footprint().contains(Eigen::Vector2d(ind.center_x_m, ind.center_y_m))) return 0.0;
  const double R = ind.probe_radius_m;
  const double d = ind.depth_m;
  const double hertz = 4.0 / 3.0 * effective_modulus_pa() * std::sqrt(R) * std::pow(d, 1.5);
  return hertz * (1.0 + options_.stiffening * d / R);
}

Eigen::Vector3d HertzSpecimen::displacement(const Eigen::Vector3d& p,
                                            const Indentation& ind) const {
  if (!(ind.depth_m > 0.0) || !(ind.probe_radius_m > 0.0)) return Eigen::Vector3d::Zero();
  if (!footprint().contains(Eigen::Vector2d(ind.center_x_m, ind.center_y_m)))
    return Eigen::Vector3d::Zero();
  const double R = ind.probe_radius_m;
  const double a = std::sqrt(R * ind.depth_m);
  const Eigen::Vector2d rel(p.x() - ind.center_x_m, p.y() - ind.center_y_m);
  const double r = rel.norm();
  const double nu = options_.poisson_ratio;
  const double E = options_.youngs_modulus_pa;
  const double p0 = 2.0 * a * effective_modulus_pa() / (std::numbers::pi * R);
  const double radial_factor = (1.0 - 2.0 * nu) * (1.0 + nu) / (3.0 * E) * a * a * p0;
  double uz = 0.0;
  double ur = 0.0;
  if (r <= a) {
    uz = -(2.0 * a * a - r * r) / (2.0 * R);
    if (r > 0.0) {
      const double s = 1.0 - r * r / (a * a);
      ur = -radial_factor / r * (1.0 - s * std::sqrt(s));
    }
  } else {
    uz = -((2.0 * a * a - r * r) * std::asin(a / r) + a * std::sqrt(r * r - a * a)) /
         (std::numbers::pi * R);
    ur = -radial_factor / r;
  }
  Eigen::Vector3d u(0.0, 0.0, uz);
  if (r > 0.0) u.head<2>() = ur * rel / r;
  return u;
}

}  // namespace hc::devices::sim
