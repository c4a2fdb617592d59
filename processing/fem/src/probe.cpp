#include "processing/fem/probe.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

namespace hc::fem {

double Probe::signed_distance(const Eigen::Vector3d& p_world, Eigen::Vector3d* normal_world) const {
  const Eigen::Vector3d pl = pose_.inverse(Eigen::Isometry) * p_world;
  Eigen::Vector3d nl;
  const double d = local_signed_distance(pl, normal_world != nullptr ? &nl : nullptr);
  if (normal_world != nullptr) *normal_world = pose_.linear() * nl;
  return d;
}

Eigen::AlignedBox3d Probe::world_bounds() const {
  const Eigen::AlignedBox3d lb = local_bounds();
  Eigen::AlignedBox3d wb;
  for (int c = 0; c < 8; ++c) {
    wb.extend(pose_ * lb.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)));
  }
  return wb;
}

Status Probe::set_direction(const Eigen::Vector3d& direction) {
  const double n = direction.norm();
  if (!direction.allFinite() || !(n > 1e-12)) {
    return invalid_argument("probe direction must be a finite non-zero vector");
  }
  direction_ = direction / n;
  return {};
}

std::optional<double> Probe::travel_to_contact(
    const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& points,
    double max_travel_m) const {
  if (points.rows() == 0) return std::nullopt;
  // Sphere tracing of f(t) = min_i sd(p_i - t dir): f is 1-Lipschitz in t, so stepping by f(t)
  // never passes through the surface. Distances are in the probe frame (isometry), directions too.
  const Eigen::Isometry3d inv = pose_.inverse(Eigen::Isometry);
  const Eigen::Matrix<double, Eigen::Dynamic, 3> local =
      (points * inv.linear().transpose()).rowwise() + inv.translation().transpose();
  const Eigen::Vector3d dir_local = inv.linear() * direction_;
  const Eigen::AlignedBox3d pb(local.colwise().minCoeff().transpose(),
                               local.colwise().maxCoeff().transpose());
  const double scale = std::max(pb.diagonal().norm(), local_bounds().diagonal().norm());
  const double tolerance = 1e-9 * scale;
  double t = 0;
  constexpr int kMaxSteps = 2000;
  for (int step = 0; step < kMaxSteps && t <= max_travel_m; ++step) {
    double f = std::numeric_limits<double>::infinity();
    const Eigen::Vector3d shift = t * dir_local;
    for (Eigen::Index i = 0; i < local.rows(); ++i) {
      const Eigen::Vector3d q = local.row(i).transpose() - shift;
      f = std::min(f, local_signed_distance(q, nullptr));
    }
    if (f <= tolerance) return t;
    t += std::max(f, 0.5 * tolerance);
  }
  return std::nullopt;
}

double SphereProbe::local_signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const {
  const double r = p.norm();
  if (normal != nullptr) *normal = r > 0 ? Eigen::Vector3d(p / r) : Eigen::Vector3d::UnitZ();
  return r - radius_;
}

Eigen::AlignedBox3d SphereProbe::local_bounds() const {
  return {Eigen::Vector3d::Constant(-radius_), Eigen::Vector3d::Constant(radius_)};
}

double CylinderProbe::local_signed_distance(const Eigen::Vector3d& p,
                                            Eigen::Vector3d* normal) const {
  // Exact distance to a capped cylinder (radius r, z in [0, h]) in the (radial, axial) half-plane.
  const double rho = std::hypot(p.x(), p.y());
  const double half = 0.5 * height_;
  const double dz_signed = p.z() - half;
  const double dr = rho - radius_;
  const double dz = std::abs(dz_signed) - half;
  const Eigen::Vector3d radial =
      rho > 1e-300 ? Eigen::Vector3d(p.x() / rho, p.y() / rho, 0) : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d axial(0, 0, dz_signed >= 0 ? 1.0 : -1.0);
  if (dr <= 0 && dz <= 0) {
    // Inside. A punch is driven along its axis, so material enters through a flat face: a point
    // less than one radius under the nearer cap is pushed back out through that cap, even when
    // the side wall is nearer (nodes just inside the rim). With the nearest-surface rule those rim
    // nodes were pushed sideways out of contact, so the punch's footprint lost its rim ring and
    // the depth-force curve jumped as they entered (tests/unit/fem/contact_test.cpp, flat punch
    // with rim nodes). Deeper points take the nearest surface.
    const bool through_cap = -dz <= radius_ || dz >= dr;
    if (normal != nullptr) *normal = through_cap ? axial : radial;
    return through_cap ? dz : dr;
  }
  const double or_ = std::max(dr, 0.0);
  const double oz = std::max(dz, 0.0);
  const double d = std::hypot(or_, oz);
  if (normal != nullptr) *normal = (or_ * radial + oz * axial) / d;
  return d;
}

Eigen::AlignedBox3d CylinderProbe::local_bounds() const {
  return {Eigen::Vector3d(-radius_, -radius_, 0), Eigen::Vector3d(radius_, radius_, height_)};
}

namespace {

// Closest point on triangle (a, b, c) to p (Ericson, Real-Time Collision Detection, Sec. 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// Generalised winding number of a closed triangle mesh at p (Jacobson et al. 2013; solid angle by
// Van Oosterom & Strackee 1983): ~1 inside, ~0 outside.
double winding_number(const TriangleMesh& m, const Eigen::Vector3d& p) {
  double total = 0;
  for (Eigen::Index f = 0; f < m.num_triangles(); ++f) {
    const Eigen::Vector3d a = m.vertices.row(m.triangles(f, 0)).transpose() - p;
    const Eigen::Vector3d b = m.vertices.row(m.triangles(f, 1)).transpose() - p;
    const Eigen::Vector3d c = m.vertices.row(m.triangles(f, 2)).transpose() - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    total += 2.0 * std::atan2(num, den);
  }
  return total / (4.0 * std::numbers::pi);
}

}  // namespace

MeshProbe::MeshProbe(TriangleMesh mesh) : mesh_(std::move(mesh)) {
  for (Eigen::Index i = 0; i < mesh_.num_vertices(); ++i) {
    bounds_.extend(Eigen::Vector3d(mesh_.vertices.row(i).transpose()));
  }
}

Result<std::unique_ptr<MeshProbe>> MeshProbe::create(const TriangleMesh& mesh) {
  if (mesh.num_triangles() < 4 || mesh.num_vertices() < 4) {
    return invalid_argument("mesh probe: a closed mesh needs at least 4 triangles");
  }
  if (!mesh.vertices.allFinite()) return invalid_argument("mesh probe: non-finite vertex");
  if (mesh.triangles.minCoeff() < 0 || mesh.triangles.maxCoeff() >= mesh.num_vertices()) {
    return invalid_argument("mesh probe: triangle vertex index out of range");
  }
  auto probe = std::unique_ptr<MeshProbe>(new MeshProbe(mesh));
  // Closed and consistently oriented: every directed edge (a, b) has exactly one twin (b, a).
  std::vector<std::pair<int, int>> edges;
  edges.reserve(static_cast<size_t>(3 * mesh.num_triangles()));
  for (Eigen::Index f = 0; f < mesh.num_triangles(); ++f) {
    for (int k = 0; k < 3; ++k)
      edges.emplace_back(mesh.triangles(f, k), mesh.triangles(f, (k + 1) % 3));
  }
  std::sort(edges.begin(), edges.end());
  for (const auto& [a, b] : edges) {
    const auto range = std::equal_range(edges.begin(), edges.end(), std::make_pair(b, a));
    if (range.second - range.first != 1) {
      return invalid_argument("mesh probe: mesh is not closed and consistently oriented (edge " +
                              std::to_string(a) + "-" + std::to_string(b) + ")");
    }
  }
  double volume = 0;  // divergence theorem: positive for a closed outward-oriented mesh
  for (Eigen::Index f = 0; f < mesh.num_triangles(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.row(mesh.triangles(f, 0));
    const Eigen::Vector3d b = mesh.vertices.row(mesh.triangles(f, 1));
    const Eigen::Vector3d c = mesh.vertices.row(mesh.triangles(f, 2));
    volume += a.dot(b.cross(c)) / 6.0;
  }
  if (!(volume > 0)) {
    return invalid_argument(
        "mesh probe: mesh encloses no positive volume (open or inward-oriented)");
  }
  return probe;
}

double MeshProbe::local_signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const {
  // Outside the (slightly enlarged) bounding box the box distance is a valid lower bound of the
  // distance, which is all sphere tracing and contact (negative values only) need; it saves the
  // O(F) scan for the many specimen nodes far from the probe.
  const double box_distance = bounds_.exteriorDistance(p);
  if (box_distance > 1e-3 * bounds_.diagonal().norm()) {
    if (normal != nullptr) {
      const Eigen::Vector3d q = p.cwiseMax(bounds_.min()).cwiseMin(bounds_.max());
      *normal = (p - q).normalized();
    }
    return box_distance;
  }
  // Brute force over triangles: probe meshes are small (hundreds to a few thousand triangles).
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_point = p;
  for (Eigen::Index f = 0; f < mesh_.num_triangles(); ++f) {
    const Eigen::Vector3d q = closest_on_triangle(p, mesh_.vertices.row(mesh_.triangles(f, 0)),
                                                  mesh_.vertices.row(mesh_.triangles(f, 1)),
                                                  mesh_.vertices.row(mesh_.triangles(f, 2)));
    const double d2 = (q - p).squaredNorm();
    if (d2 < best) {
      best = d2;
      best_point = q;
    }
  }
  const double d = std::sqrt(best);
  const bool inside = winding_number(mesh_, p) > 0.5;
  if (normal != nullptr) {
    Eigen::Vector3d n = (p - best_point);
    if (n.norm() > 1e-15) {
      n.normalize();
      if (inside) n = -n;
    } else {
      n = Eigen::Vector3d::UnitZ();
    }
    *normal = n;
  }
  return inside ? -d : d;
}

Eigen::AlignedBox3d MeshProbe::local_bounds() const { return bounds_; }

namespace {

Status check_pose(const Eigen::Vector3d& position, const Eigen::Vector3d& direction) {
  if (!position.allFinite()) return invalid_argument("probe position must be finite");
  if (!direction.allFinite() || !(direction.norm() > 1e-12)) {
    return invalid_argument("probe direction must be a finite non-zero vector");
  }
  return {};
}

}  // namespace

Result<std::unique_ptr<Probe>> make_sphere_probe(double radius_m, const Eigen::Vector3d& position_m,
                                                 const Eigen::Vector3d& direction) {
  if (!std::isfinite(radius_m) || !(radius_m > 0)) {
    return invalid_argument("sphere probe radius must be > 0 m, got " + std::to_string(radius_m));
  }
  HC_RETURN_IF_ERROR(check_pose(position_m, direction));
  auto p = std::make_unique<SphereProbe>(radius_m);
  p->set_pose(Eigen::Isometry3d(Eigen::Translation3d(position_m)));
  HC_RETURN_IF_ERROR(p->set_direction(direction));
  return std::unique_ptr<Probe>(std::move(p));
}

Result<std::unique_ptr<Probe>> make_flat_probe(double radius_m, const Eigen::Vector3d& position_m,
                                               const Eigen::Vector3d& direction, double height_m) {
  if (!std::isfinite(radius_m) || !(radius_m > 0)) {
    return invalid_argument("flat probe radius must be > 0 m, got " + std::to_string(radius_m));
  }
  if (height_m == 0) height_m = 4 * radius_m;
  if (!std::isfinite(height_m) || !(height_m > 0)) {
    return invalid_argument("flat probe height must be > 0 m");
  }
  HC_RETURN_IF_ERROR(check_pose(position_m, direction));
  auto p = std::make_unique<CylinderProbe>(radius_m, height_m);
  HC_RETURN_IF_ERROR(p->set_direction(direction));
  // Probe-frame -z along the pushing direction: the flat face (z = 0) leads.
  const Eigen::Quaterniond q =
      Eigen::Quaterniond::FromTwoVectors(-Eigen::Vector3d::UnitZ(), p->direction());
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.toRotationMatrix();
  pose.translation() = position_m;
  p->set_pose(pose);
  return std::unique_ptr<Probe>(std::move(p));
}

Result<std::unique_ptr<Probe>> make_mesh_probe(const TriangleMesh& mesh,
                                               const Eigen::Vector3d& position_m,
                                               const Eigen::Vector3d& direction) {
  HC_RETURN_IF_ERROR(check_pose(position_m, direction));
  HC_ASSIGN_OR_RETURN(std::unique_ptr<MeshProbe> p, MeshProbe::create(mesh));
  p->set_pose(Eigen::Isometry3d(Eigen::Translation3d(position_m)));
  HC_RETURN_IF_ERROR(p->set_direction(direction));
  return std::unique_ptr<Probe>(std::move(p));
}

}  // namespace hc::fem
