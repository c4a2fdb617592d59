// Small meshes built by hand for the fabrication tests, their facts derived in the comments.
#pragma once

#include <Eigen/Core>
#include <utility>

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

}  // namespace hc::testing
