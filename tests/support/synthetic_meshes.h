// Small meshes built by hand for the geometry and fabrication tests, their facts derived in the
// comments.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <map>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/mesh.h"

namespace hc::testing {

// Axis-aligned box [lo, hi]; vertex i is corner (i & 1, i & 2, i & 4). 12 triangles,
// counter-clockwise seen from outside (each face's normal checked by hand: bottom -z, top +z,
// front -y, back +y, left -x, right +x).
inline TriangleMesh box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  TriangleMesh m;
  m.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    m.vertices.row(i) << ((i & 1) ? hi.x() : lo.x()), ((i & 2) ? hi.y() : lo.y()),
        ((i & 4) ? hi.z() : lo.z());
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 3, 0, 3, 1,  // z = lo
      4, 5, 7, 4, 7, 6,             // z = hi
      0, 1, 5, 0, 5, 4,             // y = lo
      2, 6, 7, 2, 7, 3,             // y = hi
      0, 4, 6, 0, 6, 2,             // x = lo
      1, 3, 7, 1, 7, 5;             // x = hi
  return m;
}

inline TriangleMesh unit_cube() { return box({0, 0, 0}, {1, 1, 1}); }

// All the triangles of `b` added to `a` as a second part of one mesh.
inline TriangleMesh join(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m;
  m.vertices.resize(a.num_vertices() + b.num_vertices(), 3);
  m.vertices << a.vertices, b.vertices;
  m.triangles.resize(a.num_triangles() + b.num_triangles(), 3);
  m.triangles << a.triangles, (b.triangles.array() + static_cast<int>(a.num_vertices())).matrix();
  return m;
}

inline void flip(TriangleMesh* m, Eigen::Index t) {
  std::swap(m->triangles(t, 1), m->triangles(t, 2));
}

// Signed volume enclosed by a closed, outward-oriented mesh (divergence theorem: the sum of the
// signed tetrahedra from the origin to each triangle).
// Calls fn(a, b, c) with the corners of each triangle.
template <class Fn>
void for_each_triangle(const TriangleMesh& m, Fn&& fn) {
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    fn(Eigen::Vector3d(m.vertices.row(m.triangles(t, 0))),
       Eigen::Vector3d(m.vertices.row(m.triangles(t, 1))),
       Eigen::Vector3d(m.vertices.row(m.triangles(t, 2))));
  }
}

inline double signed_volume(const TriangleMesh& m) {
  double v = 0.0;
  for_each_triangle(m, [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c) { v += a.dot(b.cross(c)) / 6.0; });
  return v;
}

// Surface area of a mesh: the sum of its triangles' areas.
inline double surface_area(const TriangleMesh& m) {
  double area = 0.0;
  for_each_triangle(
      m, [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
        area += 0.5 * (b - a).cross(c - a).norm();
      });
  return area;
}

// Icosphere: the regular icosahedron, each triangle split in four `subdivisions` times with the
// new vertices pushed onto the sphere. 20 * 4^s triangles, 10 * 4^s + 2 vertices, outward
// oriented. Its volume approaches 4/3 pi r^3 from below (inscribed polyhedron).
inline TriangleMesh icosphere(const Eigen::Vector3d& centre, double radius, int subdivisions) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0},
                                    {0, -1, g}, {0, 1, g}, {0, -1, -g}, {0, 1, -g},
                                    {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    const auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      const int id = static_cast<int>(v.size()) - 1;
      mid.emplace(key, id);
      return id;
    };
    std::vector<Eigen::Vector3i> next;
    for (const auto& t : f) {
      const int ab = midpoint(t[0], t[1]);
      const int bc = midpoint(t[1], t[2]);
      const int ca = midpoint(t[2], t[0]);
      next.insert(next.end(), {{t[0], ab, ca}, {t[1], bc, ab}, {t[2], ca, bc}, {ab, bc, ca}});
    }
    f = std::move(next);
  }
  TriangleMesh m;
  m.vertices.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) {
    m.vertices.row(static_cast<Eigen::Index>(i)) = (centre + radius * v[i]).transpose();
  }
  m.triangles.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i) m.triangles.row(static_cast<Eigen::Index>(i)) = f[i];
  return m;
}

// One level of 1-to-4 midpoint subdivision; each edge's midpoint is made once and shared.
inline TriangleMesh subdivide_midpoints(const TriangleMesh& in) {
  TriangleMesh out;
  const Eigen::Index nv = in.num_vertices();
  const Eigen::Index nf = in.num_triangles();
  out.vertices.resize(nv + 3 * nf / 2 + 1, 3);  // a closed mesh has 3F/2 edges
  out.vertices.topRows(nv) = in.vertices;
  Eigen::Index next = nv;
  std::unordered_map<std::uint64_t, int> midpoint;
  midpoint.reserve(static_cast<std::size_t>(3 * nf / 2));
  const auto mid = [&](int a, int b) {
    const std::uint64_t key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
                              static_cast<std::uint32_t>(std::max(a, b));
    auto [it, inserted] = midpoint.try_emplace(key, static_cast<int>(next));
    if (inserted) {
      if (next >= out.vertices.rows()) out.vertices.conservativeResize(2 * next, 3);
      out.vertices.row(next++) = 0.5 * (in.vertices.row(a) + in.vertices.row(b));
    }
    return it->second;
  };
  out.triangles.resize(4 * nf, 3);
  for (Eigen::Index t = 0; t < nf; ++t) {
    const int a = in.triangles(t, 0);
    const int b = in.triangles(t, 1);
    const int c = in.triangles(t, 2);
    const int ab = mid(a, b);
    const int bc = mid(b, c);
    const int ca = mid(c, a);
    out.triangles.row(4 * t + 0) << a, ab, ca;
    out.triangles.row(4 * t + 1) << ab, b, bc;
    out.triangles.row(4 * t + 2) << ca, bc, c;
    out.triangles.row(4 * t + 3) << ab, bc, ca;
  }
  out.vertices.conservativeResize(next, 3);
  return out;
}

}  // namespace hc::testing
