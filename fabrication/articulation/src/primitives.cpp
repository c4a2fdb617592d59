#include "fabrication/articulation/primitives.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace hc::articulation {
namespace {

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
double circumscribed(double r, int n) { return r / std::cos(std::numbers::pi / n); }

}  // namespace

TriangleMesh transformed(const TriangleMesh& mesh, const LocalFrame& frame) {
  TriangleMesh out = mesh;
  for (Eigen::Index i = 0; i < out.num_vertices(); ++i)
    out.vertices.row(i) =
        (frame.origin + frame.axes * mesh.vertices.row(i).transpose()).transpose();
  return out;
}

TriangleMesh sphere_mesh(double radius, int segments, Facet facet) {
  const int bands = std::max(2, segments / 2);
  // A facet of the UV sphere is at least cos(pi / segments) * cos(pi / (2 bands)) * radius from
  // the centre; scaling by its inverse puts every facet outside the sphere.
  const double rho = facet == Facet::kInscribed
                         ? radius
                         : radius / (std::cos(std::numbers::pi / segments) *
                                     std::cos(std::numbers::pi / (2 * bands)));
  Builder b;
  const int south = b.add({0, 0, -rho});
  std::vector<std::vector<int>> rings;
  for (int i = 1; i < bands; ++i) {
    const double lat = -std::numbers::pi / 2 + std::numbers::pi * i / bands;
    std::vector<int> ring;
    for (int j = 0; j < segments; ++j) {
      const double lon = 2 * std::numbers::pi * j / segments;
      ring.push_back(b.add(rho * Eigen::Vector3d(std::cos(lat) * std::cos(lon),
                                                 std::cos(lat) * std::sin(lon), std::sin(lat))));
    }
    rings.push_back(ring);
  }
  const int north = b.add({0, 0, rho});
  for (int j = 0; j < segments; ++j) {
    const int j1 = (j + 1) % segments;
    b.tri(south, rings.front()[static_cast<std::size_t>(j1)],
          rings.front()[static_cast<std::size_t>(j)]);
    b.tri(north, rings.back()[static_cast<std::size_t>(j)],
          rings.back()[static_cast<std::size_t>(j1)]);
    for (std::size_t i = 0; i + 1 < rings.size(); ++i)
      b.quad(rings[i][static_cast<std::size_t>(j)], rings[i][static_cast<std::size_t>(j1)],
             rings[i + 1][static_cast<std::size_t>(j1)], rings[i + 1][static_cast<std::size_t>(j)]);
  }
  return b.mesh();
}

TriangleMesh cone_sector_mesh(const std::function<double(double)>& psi,
                              const std::function<double(const Eigen::Vector3d&)>& reach,
                              int segments, Facet facet, double inner, double near,
                              double theta_offset) {
  Builder b;
  // Direction at polar angle beta from +y, about y at theta (from +z towards +x).
  const auto dir = [](double theta, double beta) {
    return Eigen::Vector3d(std::sin(beta) * std::sin(theta), std::cos(beta),
                           std::sin(beta) * std::cos(theta));
  };
  const auto theta_of = [&](int j) { return 2 * std::numbers::pi * j / segments + theta_offset; };
  std::vector<double> angle(static_cast<std::size_t>(segments));
  double widest = 0.0;
  for (int j = 0; j < segments; ++j) {
    double a = psi(theta_of(j));
    // The polygonal cone through generatrices at psi lies inside the true cone for psi < 90 deg;
    // widening tan(psi) by 1 / cos(pi / N) puts it outside.
    if (facet == Facet::kCircumscribed && a < std::numbers::pi / 2)
      a = std::atan(std::tan(a) / std::cos(std::numbers::pi / segments));
    angle[static_cast<std::size_t>(j)] = std::clamp(a, inner + 1e-3, std::numbers::pi - 1e-3);
    widest = std::max(widest, angle[static_cast<std::size_t>(j)]);
  }
  const int rings = std::max(
      2, static_cast<int>(std::ceil((widest - inner) / (2 * std::numbers::pi / segments))));
  // Rings from the pole (or a shell's inner cone) out to psi, on the cap at reach(direction).
  const bool shell = inner > 0;
  std::vector<std::vector<int>> far, close;
  for (int k = shell ? 0 : 1; k <= rings; ++k) {
    far.emplace_back();
    close.emplace_back();
    for (int j = 0; j < segments; ++j) {
      const double a = angle[static_cast<std::size_t>(j)];
      const Eigen::Vector3d d = dir(theta_of(j), inner + (a - inner) * k / rings);
      far.back().push_back(b.add(reach(d) * d));
      if (shell) close.back().push_back(b.add(near * d));
    }
  }
  for (int j = 0; j < segments; ++j) {
    const auto j0 = static_cast<std::size_t>(j), j1 = static_cast<std::size_t>((j + 1) % segments);
    for (std::size_t k = 0; k + 1 < far.size(); ++k)
      b.quad(far[k][j0], far[k + 1][j0], far[k + 1][j1], far[k][j1]);
    if (shell) {
      // A shell is closed near the apex by the cap at distance `near`, and has two cone sides.
      for (std::size_t k = 0; k + 1 < close.size(); ++k)
        b.quad(close[k][j0], close[k][j1], close[k + 1][j1], close[k + 1][j0]);
      b.quad(close.front()[j0], far.front()[j0], far.front()[j1], close.front()[j1]);
      b.quad(close.back()[j0], close.back()[j1], far.back()[j1], far.back()[j0]);
    }
  }
  if (!shell) {
    const int apex = b.add({0, 0, 0});
    const int pole = b.add(reach(Eigen::Vector3d::UnitY()) * Eigen::Vector3d::UnitY());
    for (int j = 0; j < segments; ++j) {
      const auto j0 = static_cast<std::size_t>(j),
                 j1 = static_cast<std::size_t>((j + 1) % segments);
      b.tri(pole, far.front()[j0], far.front()[j1]);
      b.tri(apex, far.back()[j1], far.back()[j0]);
    }
  }
  return b.mesh();
}

TriangleMesh cylinder_mesh(double radius, double x0, double x1, int segments, Facet facet,
                           double phase) {
  const double rho = facet == Facet::kInscribed ? radius : circumscribed(radius, segments);
  Builder b;
  std::vector<int> lo, hi;
  for (int j = 0; j < segments; ++j) {
    const double a = 2 * std::numbers::pi * (j + phase) / segments;
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

double sector_step(double phi0, double phi1, int segments_per_turn) {
  const int n = std::max(
      1, static_cast<int>(std::ceil((phi1 - phi0) / (2 * std::numbers::pi) * segments_per_turn)));
  return (phi1 - phi0) / n;
}

TriangleMesh sector_prism_mesh(double r0, const std::function<double(double, double)>& r1,
                               double phi0, double phi1, double x0, double x1, int stations,
                               int segments_per_turn, Facet inner_facet) {
  const double step = sector_step(phi0, phi1, segments_per_turn);
  const int n = static_cast<int>(std::lround((phi1 - phi0) / step));
  const double inner = inner_facet == Facet::kInscribed ? r0 : r0 / std::cos(step / 2);
  const auto at = [](double x, double r, double phi) {
    return Eigen::Vector3d(x, r * std::cos(phi), r * std::sin(phi));
  };
  Builder b;
  // Per station along x: the outer arc, and the inner arc (a wedge: one point on the axis).
  std::vector<std::vector<int>> out(static_cast<std::size_t>(stations) + 1),
      in(static_cast<std::size_t>(stations) + 1);
  for (int s = 0; s <= stations; ++s) {
    const double x = x0 + (x1 - x0) * s / stations;
    auto& o = out[static_cast<std::size_t>(s)];
    auto& i = in[static_cast<std::size_t>(s)];
    for (int k = 0; k <= n; ++k) {
      const double phi = phi0 + step * k;
      o.push_back(b.add(at(x, std::max(r1(x, phi), inner * 1.001), phi)));
      i.push_back(r0 > 0 || k == 0 ? b.add(at(x, inner, phi)) : i.front());
    }
  }
  for (int s = 0; s < stations; ++s) {
    const auto& o0 = out[static_cast<std::size_t>(s)];
    const auto& o1 = out[static_cast<std::size_t>(s) + 1];
    const auto& i0 = in[static_cast<std::size_t>(s)];
    const auto& i1 = in[static_cast<std::size_t>(s) + 1];
    for (int k = 0; k < n; ++k) {
      const auto a = static_cast<std::size_t>(k), c = static_cast<std::size_t>(k + 1);
      b.quad(o0[a], o0[c], o1[c], o1[a]);              // outer surface
      if (r0 > 0) b.quad(i0[a], i1[a], i1[c], i0[c]);  // inner arc, facing the axis
    }
    // Radial sides at phi0 (facing -phi) and phi1.
    b.quad(i0.front(), o0.front(), o1.front(), i1.front());
    b.quad(i0.back(), i1.back(), o1.back(), o0.back());
  }
  // End caps at x0 (facing -x) and x1.
  const auto& o0 = out.front();
  const auto& i0 = in.front();
  const auto& o1 = out.back();
  const auto& i1 = in.back();
  for (int k = 0; k < n; ++k) {
    const auto a = static_cast<std::size_t>(k), c = static_cast<std::size_t>(k + 1);
    if (r0 > 0) {
      b.quad(i0[a], i0[c], o0[c], o0[a]);
      b.quad(i1[a], o1[a], o1[c], i1[c]);
    } else {
      b.tri(i0[a], o0[c], o0[a]);
      b.tri(i1[a], o1[a], o1[c]);
    }
  }
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
