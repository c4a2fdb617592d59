// The occlusion fill's probe contact and the boundary nodes of the template (session_tracking_
// internal.h).
#include <algorithm>
#include <array>
#include <cmath>

#include "session_tracking_internal.h"

namespace hc::tracking {

std::vector<std::uint8_t> boundary_nodes(const TetMesh& mesh) {
  std::vector<std::array<int, 4>> faces;  // sorted face nodes + tet (for stable sort)
  faces.reserve(static_cast<std::size_t>(mesh.num_tets()) * 4);
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 4> f{};
      int k = 0;
      for (int i = 0; i < 4; ++i)
        if (i != skip) f[static_cast<std::size_t>(k++)] = mesh.tets(t, i);
      std::sort(f.begin(), f.begin() + 3);
      f[3] = 0;
      faces.push_back(f);
    }
  std::sort(faces.begin(), faces.end());
  std::vector<std::uint8_t> on(static_cast<std::size_t>(mesh.num_nodes()), 0);
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1)
      for (int k = 0; k < 3; ++k)
        on[static_cast<std::size_t>(faces[i][static_cast<std::size_t>(k)])] = 1;
    i = j;
  }
  return on;
}

std::vector<Eigen::Vector3d> fill_with_probe_contact(
    const std::vector<Eigen::Vector3d>& known_p, const std::vector<Eigen::Vector3d>& known_d,
    const std::vector<Eigen::Vector3d>& query, const std::vector<std::uint8_t>& query_on_surface,
    const std::vector<Eigen::Vector3d>& surface_nodes, const Eigen::Vector3d& tip,
    const Eigen::Vector3d& down, const SessionTrackOptions& options,
    std::vector<Eigen::Vector3d> filled) {
  const double R = *options.probe_radius_m;
  const Eigen::Vector3d centre = tip - R * down;
  const auto lateral = [&](const Eigen::Vector3d& x) {
    const Eigen::Vector3d w = x - tip;
    return Eigen::Vector3d(w - w.dot(down) * down);
  };
  // The rest surface along the axis at lateral offset l from the tip: axial position (along
  // `down`, from the tip) interpolated from the nearest rest surface nodes (inverse lateral
  // distance weights; nodes farther than 2 R along the axis are the specimen's other side).
  const auto rest_axial = [&](const Eigen::Vector3d& l, double* out) {
    std::vector<std::pair<double, double>> near;  // lateral distance, axial position
    for (const Eigen::Vector3d& p : surface_nodes) {
      const double s = (p - tip).dot(down);
      if (std::abs(s) > 2.0 * R) continue;
      near.emplace_back((lateral(p) - l).norm(), s);
    }
    const std::size_t k = std::min<std::size_t>(4, near.size());
    if (k == 0) return false;
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(k), near.end());
    double ws = 0.0, ss = 0.0;
    for (std::size_t i = 0; i < k; ++i) {
      const double w = 1.0 / std::max(near[i].first, 1e-6);
      ws += w;
      ss += w * near[i].second;
    }
    *out = ss / ws;
    return true;
  };
  double s_tip = 0.0;
  if (!rest_axial(Eigen::Vector3d::Zero(), &s_tip)) return filled;
  const double depth = -s_tip;  // the tip below the rest surface: > 0
  const double contact_radius = depth > 0 ? std::sqrt(R * std::min(depth, R)) : 0.0;
  // The contact patch as constraints of its own: points of the sphere cap at the tip and on rings
  // of radius a / 2 and a (8 each), with rest positions straight above them on the rest surface
  // (their lateral displacement, (1 - 2 nu) times smaller, is neglected). Without them the
  // interpolant between a measured deep point under the tip and the shallow markers around
  // overshoots below the sphere near the patch's edge. A patch point nearer than a / 4 to a
  // measured marker is left out (the measurement decides there).
  std::vector<Eigen::Vector3d> base_p = known_p, base_d = known_d;
  if (contact_radius > 0) {
    const Eigen::Vector3d e1 = down.unitOrthogonal(), e2 = down.cross(e1);
    std::vector<Eigen::Vector3d> lat{Eigen::Vector3d::Zero()};
    for (double f : {0.5, 1.0})
      for (int i = 0; i < 8; ++i) {
        const double t = M_PI * i / 4.0;
        lat.push_back(f * contact_radius * (std::cos(t) * e1 + std::sin(t) * e2));
      }
    for (const Eigen::Vector3d& l : lat) {
      double s_rest = 0.0;
      if (!rest_axial(l, &s_rest)) continue;
      const Eigen::Vector3d rest = tip + l + s_rest * down;
      const Eigen::Vector3d on = centre + l + std::sqrt(R * R - l.squaredNorm()) * down;
      bool near_known = false;
      for (const Eigen::Vector3d& p : known_p)
        near_known = near_known || (p - rest).norm() < 0.25 * contact_radius;
      if (near_known) continue;
      base_p.push_back(rest);
      base_d.push_back(on - rest);
    }
    if (base_p.size() > known_p.size())
      filled = interpolate_displacements(base_p, base_d, query, options.fill_regularization_m);
  }
  for (int pass = 0; pass < 3; ++pass) {
    std::vector<Eigen::Vector3d> cp = base_p, cd = base_d;
    std::size_t contacts = 0;
    for (std::size_t q = 0; q < query.size(); ++q) {
      const Eigen::Vector3d x = query[q] + filled[q];
      const Eigen::Vector3d l = lateral(x);
      const double rho = l.norm();
      if (rho >= R) continue;
      // The sphere's lower surface at this lateral position.
      const Eigen::Vector3d on = centre + l + std::sqrt(R * R - rho * rho) * down;
      const bool inside = (x - centre).norm() < R;
      // A surface node under the probe (not the far side of a thin specimen).
      const bool in_patch =
          query_on_surface[q] && rho <= contact_radius && std::abs((x - on).dot(down)) < R;
      if (!inside && !in_patch) continue;
      cp.push_back(query[q]);
      cd.push_back(on - query[q]);
      ++contacts;
    }
    if (contacts == 0) break;
    filled = interpolate_displacements(cp, cd, query, options.fill_regularization_m);
  }
  return filled;
}

}  // namespace hc::tracking
