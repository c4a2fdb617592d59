#include "fabrication/articulation/primitives.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace hc::articulation {
namespace {

constexpr double kPi = std::numbers::pi;

// Collects vertices and triangles, then packs them into a TriangleMesh.
struct Builder {
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3i> t;
  int add(const Eigen::Vector3d& p) {
    v.push_back(p);
    return static_cast<int>(v.size()) - 1;
  }
  void tri(int a, int b, int c) { t.emplace_back(a, b, c); }
  void quad(int a, int b, int c, int d) {  // a b c d counter-clockwise seen from outside
    tri(a, b, c);
    tri(a, c, d);
  }
  TriangleMesh mesh() const {
    TriangleMesh m;
    m.vertices.resize(static_cast<Eigen::Index>(v.size()), 3);
    for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(static_cast<Eigen::Index>(i)) = v[i];
    m.triangles.resize(static_cast<Eigen::Index>(t.size()), 3);
    for (std::size_t i = 0; i < t.size(); ++i) m.triangles.row(static_cast<Eigen::Index>(i)) = t[i];
    return m;
  }
};

// Radius at which polygon vertices put every edge of a regular N-gon at distance >= r.
double circumscribed(double r, int n) { return r / std::cos(kPi / n); }

}  // namespace

TriangleMesh transformed(const TriangleMesh& mesh, const LocalFrame& frame) {
  TriangleMesh out = mesh;
  for (Eigen::Index i = 0; i < out.num_vertices(); ++i)
    out.vertices.row(i) = (frame.origin + frame.axes * mesh.vertices.row(i).transpose()).transpose();
  return out;
}

TriangleMesh sphere_mesh(double radius, int segments, Facet facet) {
  const int bands = std::max(2, segments / 2);
  // A facet of the UV sphere is at least cos(pi / segments) * cos(pi / (2 bands)) * radius from
  // the centre; scaling by its inverse puts every facet outside the sphere.
  const double rho = facet == Facet::kInscribed
                         ? radius
                         : radius / (std::cos(kPi / segments) * std::cos(kPi / (2 * bands)));
  Builder b;
  const int south = b.add({0, 0, -rho});
  std::vector<std::vector<int>> rings;
  for (int i = 1; i < bands; ++i) {
    const double lat = -kPi / 2 + kPi * i / bands;
    std::vector<int> ring;
    for (int j = 0; j < segments; ++j) {
      const double lon = 2 * kPi * j / segments;
      ring.push_back(b.add(rho * Eigen::Vector3d(std::cos(lat) * std::cos(lon),
                                                 std::cos(lat) * std::sin(lon), std::sin(lat))));
    }
    rings.push_back(ring);
  }
  const int north = b.add({0, 0, rho});
  for (int j = 0; j < segments; ++j) {
    const int j1 = (j + 1) % segments;
    b.tri(south, rings.front()[static_cast<std::size_t>(j1)], rings.front()[static_cast<std::size_t>(j)]);
    b.tri(north, rings.back()[static_cast<std::size_t>(j)], rings.back()[static_cast<std::size_t>(j1)]);
    for (std::size_t i = 0; i + 1 < rings.size(); ++i)
      b.quad(rings[i][static_cast<std::size_t>(j)], rings[i][static_cast<std::size_t>(j1)],
             rings[i + 1][static_cast<std::size_t>(j1)], rings[i + 1][static_cast<std::size_t>(j)]);
  }
  return b.mesh();
}

TriangleMesh cone_sector_mesh(const std::function<double(double)>& psi, double radius,
                              int segments, Facet facet) {
  Builder b;
  // Direction at polar angle beta from +y, about y at theta (from +z towards +x).
  const auto dir = [](double theta, double beta) {
    return Eigen::Vector3d(std::sin(beta) * std::sin(theta), std::cos(beta),
                           std::sin(beta) * std::cos(theta));
  };
  std::vector<double> angle(static_cast<std::size_t>(segments));
  double widest = 0.0;
  for (int j = 0; j < segments; ++j) {
    double a = psi(2 * kPi * j / segments);
    // The polygonal cone through generatrices at psi lies inside the true cone for psi < 90 deg;
    // widening tan(psi) by 1 / cos(pi / N) puts it outside.
    if (facet == Facet::kCircumscribed && a < kPi / 2)
      a = std::atan(std::tan(a) / std::cos(kPi / segments));
    angle[static_cast<std::size_t>(j)] = std::clamp(a, 1e-3, kPi - 1e-3);
    widest = std::max(widest, angle[static_cast<std::size_t>(j)]);
  }
  const int rings = std::max(2, static_cast<int>(std::ceil(widest / (2 * kPi / segments))));
  const int apex = b.add({0, 0, 0});
  const int pole = b.add(radius * Eigen::Vector3d::UnitY());
  std::vector<std::vector<int>> ring(static_cast<std::size_t>(rings));
  for (int k = 1; k <= rings; ++k)
    for (int j = 0; j < segments; ++j)
      ring[static_cast<std::size_t>(k - 1)].push_back(
          b.add(radius * dir(2 * kPi * j / segments, angle[static_cast<std::size_t>(j)] * k / rings)));
  for (int j = 0; j < segments; ++j) {
    const auto j0 = static_cast<std::size_t>(j), j1 = static_cast<std::size_t>((j + 1) % segments);
    b.tri(pole, ring[0][j0], ring[0][j1]);
    for (std::size_t k = 0; k + 1 < ring.size(); ++k)
      b.quad(ring[k][j0], ring[k + 1][j0], ring[k + 1][j1], ring[k][j1]);
    b.tri(apex, ring.back()[j1], ring.back()[j0]);
  }
  return b.mesh();
}

TriangleMesh cylinder_mesh(double radius, double x0, double x1, int segments, Facet facet) {
  const double rho = facet == Facet::kInscribed ? radius : circumscribed(radius, segments);
  Builder b;
  std::vector<int> lo, hi;
  for (int j = 0; j < segments; ++j) {
    const double a = 2 * kPi * j / segments;
    lo.push_back(b.add({x0, rho * std::cos(a), rho * std::sin(a)}));
    hi.push_back(b.add({x1, rho * std::cos(a), rho * std::sin(a)}));
  }
  const int c0 = b.add({x0, 0, 0}), c1 = b.add({x1, 0, 0});
  for (int j = 0; j < segments; ++j) {
    const auto j0 = static_cast<std::size_t>(j), j1 = static_cast<std::size_t>((j + 1) % segments);
    b.quad(lo[j0], lo[j1], hi[j1], hi[j0]);
    b.tri(c0, lo[j1], lo[j0]);
    b.tri(c1, hi[j0], hi[j1]);
  }
  return b.mesh();
}

TriangleMesh sector_prism_mesh(double r0, double r1, double phi0, double phi1, double x0,
                               double x1, int segments_per_turn, Facet inner_facet) {
  const int n = std::max(1, static_cast<int>(std::ceil((phi1 - phi0) / (2 * kPi) * segments_per_turn)));
  const double step = (phi1 - phi0) / n;
  const double inner = inner_facet == Facet::kInscribed ? r0 : r0 / std::cos(step / 2);
  const auto at = [](double x, double r, double phi) {
    return Eigen::Vector3d(x, r * std::cos(phi), r * std::sin(phi));
  };
  Builder b;
  // Columns of (outer, inner) points at each arc angle, at both ends; a wedge shares one inner
  // point per end.
  std::vector<int> out0, out1, in0, in1;
  for (int k = 0; k <= n; ++k) {
    const double phi = phi0 + step * k;
    out0.push_back(b.add(at(x0, r1, phi)));
    out1.push_back(b.add(at(x1, r1, phi)));
    if (r0 > 0 || k == 0) {
      in0.push_back(b.add(at(x0, inner, phi)));
      in1.push_back(b.add(at(x1, inner, phi)));
    } else {
      in0.push_back(in0.front());
      in1.push_back(in1.front());
    }
  }
  for (int k = 0; k < n; ++k) {
    const auto a = static_cast<std::size_t>(k), c = static_cast<std::size_t>(k + 1);
    b.quad(out0[a], out0[c], out1[c], out1[a]);  // outer arc, facing away from the axis
    if (r0 > 0) {
      b.quad(in0[a], in1[a], in1[c], in0[c]);    // inner arc, facing the axis
      b.quad(in0[a], in0[c], out0[c], out0[a]);  // end x0 (faces -x)
      b.quad(in1[a], out1[a], out1[c], in1[c]);  // end x1 (faces +x)
    } else {
      b.tri(in0[a], out0[c], out0[a]);
      b.tri(in1[a], out1[a], out1[c]);
    }
  }
  // Radial sides at phi0 (faces towards -phi) and phi1.
  b.quad(in0.front(), out0.front(), out1.front(), in1.front());
  b.quad(in0.back(), in1.back(), out1.back(), out0.back());
  return b.mesh();
}

TriangleMesh concatenated(const std::vector<TriangleMesh>& meshes) {
  TriangleMesh out;
  Eigen::Index nv = 0, nt = 0;
  for (const TriangleMesh& m : meshes) nv += m.num_vertices(), nt += m.num_triangles();
  out.vertices.resize(nv, 3);
  out.triangles.resize(nt, 3);
  nv = nt = 0;
  for (const TriangleMesh& m : meshes) {
    out.vertices.middleRows(nv, m.num_vertices()) = m.vertices;
    out.triangles.middleRows(nt, m.num_triangles()) =
        (m.triangles.array() + static_cast<int>(nv)).matrix();
    nv += m.num_vertices();
    nt += m.num_triangles();
  }
  return out;
}

double enclosed_volume(const TriangleMesh& m) {
  double v = 0.0;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    const Eigen::Vector3d a = m.vertices.row(m.triangles(t, 0));
    const Eigen::Vector3d b = m.vertices.row(m.triangles(t, 1));
    const Eigen::Vector3d c = m.vertices.row(m.triangles(t, 2));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

}  // namespace hc::articulation
