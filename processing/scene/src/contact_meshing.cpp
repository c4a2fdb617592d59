#include "processing/scene/contact_meshing.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include "processing/fem/contact_surface.h"

namespace hc::scene {

namespace {

// Hertz: F = 4/3 E* √R d^(3/2) solved for d (ANALYTIC_BENCHMARKS.md §1).
double hertz_depth(double force_n, double radius_m, double e_star) {
  return std::pow(3.0 * force_n / (4.0 * e_star * std::sqrt(radius_m)), 2.0 / 3.0);
}

// Half the smallest extent of the probe's bounding box: a sphere's or a punch's radius.
double feature_size(const fem::Probe& probe) {
  return 0.5 * probe.local_bounds().diagonal().minCoeff();
}

}  // namespace

Status ContactMeshingOptions::validate() const {
  if (!(elements_per_patch_radius > 0) || !(fine_region_radii >= 0) || !(growth > 0) ||
      !(coarse_fraction > 0) || !(max_tets >= 100))
    return invalid_argument(
        "contact meshing: elements_per_patch_radius, growth and coarse_fraction must be > 0, "
        "fine_region_radii >= 0, max_tets >= 100");
  return {};
}

Result<ContactPatch> expected_contact_patch(const TriangleMesh& surface, const fem::Probe& probe,
                                            const fem::Load& load, double effective_modulus_pa) {
  HC_ASSIGN_OR_RETURN(const std::vector<fem::ContactPoint> points,
                      fem::sample_contact_points(surface.vertices, surface.triangles, probe));
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> pts(
      static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k)
      x += points[i].weights(k) *
           surface.vertices.row(points[i].nodes[static_cast<std::size_t>(k)]).transpose();
    pts.row(static_cast<Eigen::Index>(i)) = x.transpose();
  }
  const Eigen::AlignedBox3d bounds(surface.vertices.colwise().minCoeff().transpose(),
                                   surface.vertices.colwise().maxCoeff().transpose());
  const double max_travel = 10 * bounds.diagonal().norm();
  const std::optional<double> travel = probe.travel_to_contact(pts, max_travel);
  if (!travel) return fem::probe_misses_specimen(probe, bounds, max_travel);
  std::unique_ptr<fem::Probe> at = probe.clone();
  at->advance(*travel);
  ContactPatch patch;
  double best = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < pts.rows(); ++i) {
    const double sd = at->signed_distance(pts.row(i).transpose(), nullptr);
    if (sd < best) {
      best = sd;
      patch.centre_m = pts.row(i).transpose();
    }
  }
  const double e_star = effective_modulus_pa;
  const bool by_force = load.control == fem::LoadControl::kForce;
  if (by_force && !(e_star > 0 && std::isfinite(e_star)))
    return invalid_argument("contact meshing: force control needs the specimen's modulus");
  const double feature = feature_size(probe);
  if (dynamic_cast<const fem::CylinderProbe*>(&probe) != nullptr) {
    patch.radius_m = feature;
    patch.depth_m = by_force ? load.value / (2 * feature * e_star) : load.value;
    return patch;
  }
  patch.depth_m = by_force ? hertz_depth(load.value, feature, e_star) : load.value;
  patch.radius_m = std::sqrt(feature * std::min(patch.depth_m, feature));
  if (const auto* mesh = dynamic_cast<const fem::MeshProbe*>(&probe); mesh != nullptr) {
    // The widest section of the probe's own surface within the depth of its leading point.
    const Eigen::Vector3d d = at->direction();
    double tip = -std::numeric_limits<double>::infinity();
    for (Eigen::Index v = 0; v < mesh->mesh().num_vertices(); ++v)
      tip = std::max(tip, (at->pose() * mesh->mesh().vertices.row(v).transpose()).dot(d));
    for (Eigen::Index v = 0; v < mesh->mesh().num_vertices(); ++v) {
      const Eigen::Vector3d w = at->pose() * mesh->mesh().vertices.row(v).transpose();
      if (tip - w.dot(d) > patch.depth_m) continue;
      const Eigen::Vector3d off = w - patch.centre_m;
      patch.radius_m = std::max(patch.radius_m, (off - off.dot(d) * d).norm());
    }
  }
  return patch;
}

meshing::GradedSize contact_size_field(const ContactPatch& patch,
                                       const Eigen::AlignedBox3d& specimen,
                                       const ContactMeshingOptions& options) {
  meshing::GradedSize size;
  size.centre = patch.centre_m;
  size.radius = options.fine_region_radii * patch.radius_m;
  size.growth = options.growth;
  size.fine = patch.radius_m / options.elements_per_patch_radius;
  size.coarse = std::max(size.fine, options.coarse_fraction * specimen.sizes().minCoeff());
  // Stay within the tet budget: coarsen the fine size in 1.25x steps (at most ~55x).
  for (int k = 0; k < 18 && meshing::estimate_tet_count(size, specimen) > options.max_tets; ++k) {
    size.fine *= 1.25;
    size.coarse = std::max(size.coarse, size.fine);
  }
  return size;
}

}  // namespace hc::scene
