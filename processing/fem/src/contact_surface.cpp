#include "processing/fem/contact_surface.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "processing/fem/corotational.h"

namespace hc::fem {

namespace {

// Local faces of a positively oriented tet (n0..n3), each oriented outward: the face opposite
// vertex k.
constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

// Largest distance of the probe's bounding box from its axis, and its feature size (half the
// smallest extent of its bounding box: a sphere's or a punch's radius).
void probe_extent(const Probe& probe, double* lateral, double* feature) {
  const Eigen::AlignedBox3d lb = probe.local_bounds();
  const Eigen::Vector3d d = probe.direction();
  const Eigen::Vector3d origin = probe.pose().translation();
  double reach = 0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d w =
        probe.pose() * lb.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)) - origin;
    reach = std::max(reach, (w - w.dot(d) * d).norm());
  }
  *lateral = reach;
  *feature = 0.5 * lb.diagonal().minCoeff();
}

}  // namespace

std::vector<BoundaryFace> boundary_faces(const TetMesh& mesh) {
  struct Key {
    std::array<int, 3> sorted;
    int tet;
    int face;
  };
  std::vector<Key> keys;
  keys.reserve(static_cast<std::size_t>(4 * mesh.num_tets()));
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t)
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> s = {mesh.tets(t, kFaces[f][0]), mesh.tets(t, kFaces[f][1]),
                              mesh.tets(t, kFaces[f][2])};
      std::sort(s.begin(), s.end());
      keys.push_back({s, static_cast<int>(t), f});
    }
  std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
    return a.sorted != b.sorted ? a.sorted < b.sorted
                                : std::make_pair(a.tet, a.face) < std::make_pair(b.tet, b.face);
  });
  std::vector<BoundaryFace> out;
  for (std::size_t i = 0; i < keys.size();) {
    std::size_t j = i + 1;
    while (j < keys.size() && keys[j].sorted == keys[i].sorted) ++j;
    if (j == i + 1) {
      BoundaryFace bf;
      bf.tet = keys[i].tet;
      for (int k = 0; k < 3; ++k) {
        bf.local[static_cast<std::size_t>(k)] = kFaces[keys[i].face][k];
        bf.nodes[static_cast<std::size_t>(k)] = mesh.tets(bf.tet, kFaces[keys[i].face][k]);
      }
      out.push_back(bf);
    }
    i = j;
  }
  std::sort(out.begin(), out.end(), [](const BoundaryFace& a, const BoundaryFace& b) {
    return std::make_pair(a.tet, a.local) < std::make_pair(b.tet, b.local);
  });
  return out;
}

namespace {
// Lattice loops may visit this many times max_points (i, j) pairs of a triangle before giving up.
constexpr double kLatticeLoopFactor = 25;
}  // namespace

Status ContactSamplingOptions::validate() const {
  if (!std::isfinite(spacing_m) || spacing_m < 0)
    return invalid_argument("contact sampling: spacing_m must be >= 0");
  if (!std::isfinite(split_above_m) || split_above_m < 0)
    return invalid_argument("contact sampling: split_above_m must be >= 0");
  if (!std::isfinite(reach_m) || reach_m < 0)
    return invalid_argument("contact sampling: reach_m must be >= 0");
  if (max_points < 1) return invalid_argument("contact sampling: max_points must be >= 1");
  return {};
}

Result<std::vector<ContactPoint>> sample_contact_points(const MatrixX3d& vertices,
                                                        const MatrixX3i& triangles,
                                                        const Probe& probe,
                                                        const ContactSamplingOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const Eigen::Index nv = vertices.rows();
  if (triangles.size() > 0 && (triangles.minCoeff() < 0 || triangles.maxCoeff() >= nv))
    return invalid_argument("contact sampling: triangle vertex index out of range");
  double lateral = 0, feature = 0;
  probe_extent(probe, &lateral, &feature);
  const double spacing = options.spacing_m > 0 ? options.spacing_m : feature / 8;
  const double split_above = options.split_above_m > 0 ? options.split_above_m : feature;
  const double reach = options.reach_m > 0 ? options.reach_m : 1.5 * lateral;
  const Eigen::Vector3d origin = probe.pose().translation();
  const Eigen::Vector3d dir = probe.direction();
  const auto from_axis = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d w = p - origin;
    return (w - w.dot(dir) * dir).norm();
  };

  std::vector<double> vertex_area(static_cast<std::size_t>(nv), 0.0);
  std::vector<int> vertex_face(static_cast<std::size_t>(nv), -1);
  std::vector<ContactPoint> lattice;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3d a = vertices.row(triangles(f, 0)).transpose();
    const Eigen::Vector3d b = vertices.row(triangles(f, 1)).transpose();
    const Eigen::Vector3d c = vertices.row(triangles(f, 2)).transpose();
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    int m = 1;
    if (longest > split_above && longest > spacing) {
      const Eigen::Vector3d centre = (a + b + c) / 3.0;
      const double radius =
          std::max({(a - centre).norm(), (b - centre).norm(), (c - centre).norm()});
      // A triangle facing away from the probe's travel (outward normal along it: a fixed base
      // under the probe's axis) cannot be touched before the probe has passed through the body.
      const bool facing_away = (b - a).cross(c - a).dot(dir) > 0;
      if (!facing_away && from_axis(centre) - radius <= reach) {
        const double mm = std::ceil(longest / spacing);
        // Only the lattice points within reach are kept (below), so a triangle much larger than
        // the probe (a box's face under a small punch: 1,811² points) costs a loop, not memory;
        // the loop itself is bounded here.
        if (mm * mm > kLatticeLoopFactor * static_cast<double>(options.max_points))
          return invalid_argument(fmt::format(
              "contact sampling: triangle {} ({:.3g} m) would need {:.0f}² contact points at "
              "spacing {:.3g} m",
              f, longest, mm, spacing));
        m = static_cast<int>(mm);
      }
    }
    const double unit = area / (3.0 * m * m);  // a lattice corner's weight
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(triangles(f, k));
      vertex_area[v] += unit;
      if (vertex_face[v] < 0) vertex_face[v] = static_cast<int>(f);
    }
    for (int i = 0; i <= m; ++i)
      for (int j = 0; i + j <= m; ++j) {
        const int corner_count = (i == 0) + (j == 0) + (i + j == m);
        if (corner_count >= 2) continue;  // a vertex: accumulated above
        ContactPoint p;
        p.nodes = {triangles(f, 0), triangles(f, 1), triangles(f, 2)};
        p.weights = Eigen::Vector3d(1.0 - static_cast<double>(i + j) / m,
                                    static_cast<double>(i) / m, static_cast<double>(j) / m);
        if (from_axis(p.weights(0) * a + p.weights(1) * b + p.weights(2) * c) > reach) {
          continue;  // the probe cannot touch it
        }
        p.area_m2 = (corner_count == 1 ? 3.0 : 6.0) * unit;  // edge or interior lattice point
        p.face = static_cast<int>(f);
        lattice.push_back(p);
        if (static_cast<long>(lattice.size()) > options.max_points)
          return invalid_argument(fmt::format(
              "contact sampling: more than {} contact points at spacing {:.3g} m",
              options.max_points, spacing));
      }
  }
  std::vector<ContactPoint> out;
  out.reserve(lattice.size() + static_cast<std::size_t>(nv));
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (vertex_face[static_cast<std::size_t>(v)] < 0) continue;
    ContactPoint p;
    p.nodes = {static_cast<int>(v), static_cast<int>(v), static_cast<int>(v)};
    p.area_m2 = vertex_area[static_cast<std::size_t>(v)];
    p.face = vertex_face[static_cast<std::size_t>(v)];
    out.push_back(p);
  }
  out.insert(out.end(), lattice.begin(), lattice.end());
  return out;
}

Result<ContactSurface> ContactSurface::create(const TetMesh& mesh, const Probe& probe,
                                              const ContactSamplingOptions& options) {
  ContactSurface s;
  s.faces_ = boundary_faces(mesh);
  MatrixX3i tris(static_cast<Eigen::Index>(s.faces_.size()), 3);
  s.node_area_ = Eigen::VectorXd::Zero(mesh.num_nodes());
  for (std::size_t f = 0; f < s.faces_.size(); ++f) {
    const auto& n = s.faces_[f].nodes;
    for (int k = 0; k < 3; ++k) tris(static_cast<Eigen::Index>(f), k) = n[static_cast<std::size_t>(k)];
    const Eigen::Vector3d a = mesh.nodes.row(n[0]).transpose();
    const double area = 0.5 * (mesh.nodes.row(n[1]).transpose() - a)
                                  .cross(mesh.nodes.row(n[2]).transpose() - a)
                                  .norm();
    for (int v : n) s.node_area_(v) += area / 3.0;
  }
  HC_ASSIGN_OR_RETURN(s.points_, sample_contact_points(mesh.nodes, tris, probe, options));
  return s;
}

std::array<int, 3> ContactSurface::local(std::size_t i) const {
  const ContactPoint& p = points_[i];
  const BoundaryFace& f = faces_[static_cast<std::size_t>(p.face)];
  std::array<int, 3> out{};
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 3; ++j)
      if (f.nodes[static_cast<std::size_t>(j)] == p.nodes[static_cast<std::size_t>(k)])
        out[static_cast<std::size_t>(k)] = f.local[static_cast<std::size_t>(j)];
  return out;
}

Eigen::Vector3d ContactSurface::position(const MatrixX3d& x, std::size_t i) const {
  const ContactPoint& p = points_[i];
  if (p.is_node()) return x.row(p.nodes[0]).transpose();
  return p.weights(0) * x.row(p.nodes[0]).transpose() + p.weights(1) * x.row(p.nodes[1]).transpose() +
         p.weights(2) * x.row(p.nodes[2]).transpose();
}

Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> ContactSurface::positions(
    const MatrixX3d& x) const {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> out(
      static_cast<Eigen::Index>(points_.size()), 3);
  for (std::size_t i = 0; i < points_.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = position(x, i).transpose();
  return out;
}

Result<double> ContactSurface::travel_to_contact(const Probe& probe, const MatrixX3d& x,
                                                 const std::vector<char>& fixed,
                                                 double max_travel_m) const {
  std::vector<Eigen::Index> movable;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const ContactPoint& p = points_[i];
    for (int k = 0; k < 3; ++k)
      if (p.weights(k) != 0 && !fixed[static_cast<std::size_t>(p.nodes[static_cast<std::size_t>(k)])]) {
        movable.push_back(static_cast<Eigen::Index>(i));
        break;
      }
  }
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> pts(
      static_cast<Eigen::Index>(movable.size()), 3);
  for (std::size_t k = 0; k < movable.size(); ++k)
    pts.row(static_cast<Eigen::Index>(k)) = position(x, static_cast<std::size_t>(movable[k])).transpose();
  const std::optional<double> t = probe.travel_to_contact(pts, max_travel_m);
  if (t) return *t;
  return probe_misses_specimen(
      probe, Eigen::AlignedBox3d(x.colwise().minCoeff().transpose(), x.colwise().maxCoeff().transpose()),
      max_travel_m);
}

Status probe_misses_specimen(const Probe& probe, const Eigen::AlignedBox3d& specimen,
                             double max_travel_m) {
  const Eigen::Vector3d p = probe.pose().translation(), d = probe.direction();
  const Eigen::Vector3d lo = specimen.min(), hi = specimen.max();
  return invalid_argument(fmt::format(
      "contact: the probe's path misses the specimen: the probe at ({:.4g}, {:.4g}, {:.4g}) m "
      "moving along ({:.3g}, {:.3g}, {:.3g}) touches no free part of its surface within {:.3g} m "
      "(specimen bounds ({:.4g}, {:.4g}, {:.4g}) to ({:.4g}, {:.4g}, {:.4g}) m); place the probe "
      "over the specimen or point its direction at it",
      p.x(), p.y(), p.z(), d.x(), d.y(), d.z(), max_travel_m, lo.x(), lo.y(), lo.z(), hi.x(),
      hi.y(), hi.z()));
}

std::vector<double> ContactSurface::penalty_stiffness(const CorotationalFem& fem,
                                                      double penalty_scale,
                                                      double penalty_n_per_m) const {
  const SparseMatrix& k = fem.stiffness();
  const auto diagonal = [&](int node) {
    if (penalty_n_per_m > 0) return penalty_n_per_m / penalty_scale;
    double d = 0;
    for (int a = 0; a < 3; ++a) {
      const int c = fem.dof(node, a);
      d += k.valuePtr()[k.outerIndexPtr()[c + 1] - 1] / 3.0;  // the diagonal ends its column
    }
    return d;
  };
  std::vector<double> out(points_.size(), 0.0);
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const ContactPoint& p = points_[i];
    double sum = 0;
    const int terms = p.is_node() ? 1 : 3;
    for (int j = 0; j < terms; ++j) {
      const int node = p.nodes[static_cast<std::size_t>(j)];
      if (fem.is_fixed(node) || !(node_area_(node) > 0)) continue;
      sum += (p.is_node() ? 1.0 : p.weights(j)) * diagonal(node) / node_area_(node);
    }
    out[i] = penalty_scale * p.area_m2 * sum;
  }
  return out;
}

}  // namespace hc::fem
