// Generated solids for the 3-D abstraction tests: blocks with holes, slots and grooves of chosen
// widths and depths, and the Menger sponge as a voxel boundary. Cutting uses CGAL's exact
// corefinement (geometry/booleans.h), so the intrusions are exactly the boxes and prisms below.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <vector>

#include "common/mesh.h"
#include "geometry/booleans.h"
#include "synthetic_meshes.h"

namespace hc::testing {

enum class IntrusionKind { kHole, kSlot, kGroove };

struct IntrusionSpec {
  double width, depth;
  Eigen::Vector3d centre;  // of its opening on the top face (z = top)
};

// A closed prism of `n` sides around a vertical axis through (x, y), from z0 to z1.
inline TriangleMesh vertical_prism(double x, double y, double r, double z0, double z1, int n) {
  TriangleMesh m;
  m.vertices.resize(2 * n + 2, 3);
  for (int i = 0; i < n; ++i) {
    const double t = 2 * std::numbers::pi * i / n;
    m.vertices.row(i) << x + r * std::cos(t), y + r * std::sin(t), z0;
    m.vertices.row(n + i) << x + r * std::cos(t), y + r * std::sin(t), z1;
  }
  m.vertices.row(2 * n) << x, y, z0;
  m.vertices.row(2 * n + 1) << x, y, z1;
  m.triangles.resize(4 * n, 3);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.triangles.row(4 * i) << i, j, n + j;
    m.triangles.row(4 * i + 1) << i, n + j, n + i;
    m.triangles.row(4 * i + 2) << 2 * n, j, i;
    m.triangles.row(4 * i + 3) << 2 * n + 1, n + i, n + j;
  }
  return m;
}

// A block with one intrusion per spec, cut from its top face (z = height) downwards. Holes are
// 64-gon prisms of diameter `width` (vertices on the circle: 0.1 % narrower across flats); slots
// are width x 3 width boxes; grooves run through the block along y.
inline Result<TriangleMesh> block_with_intrusions(IntrusionKind kind,
                                                  const std::vector<IntrusionSpec>& specs,
                                                  const Eigen::Vector3d& size) {
  TriangleMesh cutters;
  const double over = 1.0;  // cutters reach this far above the top face
  for (const auto& s : specs) {
    const double z0 = size.z() - s.depth, z1 = size.z() + over;
    TriangleMesh c;
    if (kind == IntrusionKind::kHole) {
      c = vertical_prism(s.centre.x(), s.centre.y(), 0.5 * s.width, z0, z1, 64);
    } else if (kind == IntrusionKind::kSlot) {
      c = box({s.centre.x() - 0.5 * s.width, s.centre.y() - 1.5 * s.width, z0},
              {s.centre.x() + 0.5 * s.width, s.centre.y() + 1.5 * s.width, z1});
    } else {
      c = box({s.centre.x() - 0.5 * s.width, -over, z0},
              {s.centre.x() + 0.5 * s.width, size.y() + over, z1});
    }
    cutters = cutters.num_triangles() == 0 ? c : join(cutters, c);
  }
  return geometry::corefine_boolean(box({0, 0, 0}, size), cutters,
                                    geometry::BooleanOperation::kDifference);
}

// Rotates a mesh so that its +z axis becomes axis `k` (0: x, 1: y, 2: z) by a cyclic
// permutation of the coordinates (a proper rotation: orientation is kept).
inline TriangleMesh permute_axes(const TriangleMesh& m, int k) {
  TriangleMesh out = m;
  for (Eigen::Index i = 0; i < m.num_vertices(); ++i) {
    const Eigen::Vector3d p = m.vertices.row(i).transpose();
    Eigen::Vector3d q = p;
    if (k == 0) q = Eigen::Vector3d(p.z(), p.x(), p.y());
    if (k == 1) q = Eigen::Vector3d(p.y(), p.z(), p.x());
    out.vertices.row(i) = q.transpose();
  }
  return out;
}
inline Eigen::Vector3d permute_point(const Eigen::Vector3d& p, int k) {
  if (k == 0) return {p.z(), p.x(), p.y()};
  if (k == 1) return {p.y(), p.z(), p.x()};
  return p;
}

// Menger sponge of `level` as the boundary of its unit voxels (3^level per side, scaled by
// `unit`): faces between a filled and an empty voxel, two triangles each, welded by position.
inline TriangleMesh menger_sponge(int level, double unit) {
  int n = 1;
  for (int i = 0; i < level; ++i) n *= 3;
  const auto filled = [&](int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n) return false;
    for (int s = 1; s < n; s *= 3) {
      const int a = (x / s) % 3 == 1, b = (y / s) % 3 == 1, c = (z / s) % 3 == 1;
      if (a + b + c >= 2) return false;
    }
    return true;
  };
  std::vector<Eigen::Vector3d> verts;
  std::map<std::array<int, 3>, int> index;
  const auto vid = [&](int x, int y, int z) {
    const auto [it, added] =
        index.emplace(std::array<int, 3>{x, y, z}, static_cast<int>(verts.size()));
    if (added) verts.emplace_back(x * unit, y * unit, z * unit);
    return it->second;
  };
  std::vector<Eigen::Vector3i> tris;
  for (int x = 0; x < n; ++x)
    for (int y = 0; y < n; ++y)
      for (int z = 0; z < n; ++z) {
        if (!filled(x, y, z)) continue;
        for (int axis = 0; axis < 3; ++axis)
          for (const int dir : {-1, 1}) {
            int d[3] = {0, 0, 0};
            d[axis] = dir;
            if (filled(x + d[0], y + d[1], z + d[2])) continue;
            // The face's four corners, counter-clockwise seen from outside.
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            int base[3] = {x, y, z};
            if (dir > 0) base[axis] += 1;
            std::array<int, 4> q{};
            for (int c = 0; c < 4; ++c) {
              int p[3] = {base[0], base[1], base[2]};
              p[u] += (c == 1 || c == 2) ? 1 : 0;
              p[v] += (c >= 2) ? 1 : 0;
              q[static_cast<std::size_t>(c)] = vid(p[0], p[1], p[2]);
            }
            if (dir > 0) {
              tris.emplace_back(q[0], q[1], q[2]);
              tris.emplace_back(q[0], q[2], q[3]);
            } else {
              tris.emplace_back(q[0], q[2], q[1]);
              tris.emplace_back(q[0], q[3], q[2]);
            }
          }
      }
  TriangleMesh m;
  m.vertices.resize(static_cast<Eigen::Index>(verts.size()), 3);
  for (std::size_t i = 0; i < verts.size(); ++i)
    m.vertices.row(static_cast<Eigen::Index>(i)) = verts[i].transpose();
  m.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (std::size_t i = 0; i < tris.size(); ++i)
    m.triangles.row(static_cast<Eigen::Index>(i)) = tris[i].transpose();
  return m;
}

}  // namespace hc::testing
