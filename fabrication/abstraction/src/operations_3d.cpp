// Offsets and booleans of closed triangle meshes (operations.h). Inside tests are CGAL's
// ray-parity test on an AABB tree (geometry/mesh_distance.h), as the thesis recommends over
// testing against the balls.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <unordered_map>

#include "common/clock.h"
#include "fabrication/abstraction/operations.h"
#include "geometry/booleans.h"
#include "geometry/mesh_distance.h"
#include "operations_internal.h"

namespace hc::abstraction {
namespace {

Result<geometry::MeshDistance> closed_mesh(const TriangleMesh& mesh, std::string_view what) {
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance d, geometry::MeshDistance::build(mesh));
  if (!d.is_closed()) {
    return invalid_argument(
        fmt::format("{}: the mesh is not closed (repair it first: hardcopy mesh repair)", what));
  }
  return d;
}

Eigen::AlignedBox3d box_of(const TriangleMesh& m) {
  Eigen::AlignedBox3d b;
  for (Eigen::Index i = 0; i < m.num_vertices(); ++i) b.extend(m.vertices.row(i).transpose());
  return b;
}

Result<TriangleMesh> crust(const Balls3& balls, OperationSummary* sum) {
  std::size_t in = 0;
  for (const auto l : balls.interior) in += l;
  if (in == 0) return invalid_argument("the result is empty");
  return power_crust_3d(balls, &sum->crust);
}

struct Tri {
  Eigen::Vector3d p[3];
};

// The segment where triangles a and b cross, if they cross in a segment (coplanar pairs are left
// out: their overlap is sampled on both inputs anyway).
std::optional<std::array<Eigen::Vector3d, 2>> tri_tri_segment(const Tri& a, const Tri& b) {
  const auto plane_cut = [](const Tri& t, const Eigen::Vector3d& n, double d,
                            std::vector<Eigen::Vector3d>* pts) {
    double s[3];
    for (int i = 0; i < 3; ++i) s[i] = n.dot(t.p[i]) - d;
    if ((s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0)) return false;
    if (s[0] == 0 && s[1] == 0 && s[2] == 0) return false;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if (s[i] == 0) pts->push_back(t.p[i]);
      if ((s[i] < 0 && s[j] > 0) || (s[i] > 0 && s[j] < 0)) {
        pts->push_back(t.p[i] + (s[i] / (s[i] - s[j])) * (t.p[j] - t.p[i]));
      }
    }
    return !pts->empty();
  };
  const Eigen::Vector3d na = (a.p[1] - a.p[0]).cross(a.p[2] - a.p[0]);
  const Eigen::Vector3d nb = (b.p[1] - b.p[0]).cross(b.p[2] - b.p[0]);
  std::vector<Eigen::Vector3d> pa, pb;
  if (!plane_cut(a, nb, nb.dot(b.p[0]), &pa) || !plane_cut(b, na, na.dot(a.p[0]), &pb))
    return std::nullopt;
  const Eigen::Vector3d dir = na.cross(nb);
  if (dir.squaredNorm() == 0) return std::nullopt;
  const auto range = [&](const std::vector<Eigen::Vector3d>& p, Eigen::Vector3d* lo,
                         Eigen::Vector3d* hi) {
    *lo = *hi = p[0];
    for (const auto& q : p) {
      if (dir.dot(q) < dir.dot(*lo)) *lo = q;
      if (dir.dot(q) > dir.dot(*hi)) *hi = q;
    }
  };
  Eigen::Vector3d alo, ahi, blo, bhi;
  range(pa, &alo, &ahi);
  range(pb, &blo, &bhi);
  const Eigen::Vector3d lo = dir.dot(alo) > dir.dot(blo) ? alo : blo;
  const Eigen::Vector3d hi = dir.dot(ahi) < dir.dot(bhi) ? ahi : bhi;
  if (dir.dot(lo) > dir.dot(hi)) return std::nullopt;
  return std::array<Eigen::Vector3d, 2>{lo, hi};
}

Tri triangle(const TriangleMesh& m, Eigen::Index t) {
  Tri tri;
  for (int k = 0; k < 3; ++k) tri.p[k] = m.vertices.row(m.triangles(t, k)).transpose();
  return tri;
}

}  // namespace

Result<Balls3> mesh_balls(const TriangleMesh& mesh, const ShapeOptions& options,
                          OperationSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance d, closed_mesh(mesh, "mesh"));
  HC_ASSIGN_OR_RETURN(Samples3 samples,
                      sample_mesh(mesh, options.sampling, {}, &summary->sampling));
  summary->samples = samples.size();
  HC_ASSIGN_OR_RETURN(Balls3 balls,
                      medial_balls_3d(
                          samples, [&](const Eigen::Vector3d& p) { return d.inside(p); },
                          options.medial, &summary->medial));
  summary->balls = balls.size();
  return balls;
}

Result<TriangleMesh> reconstruct_3d(const TriangleMesh& mesh, const ShapeOptions& options,
                                    OperationSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  OperationSummary sum;
  HC_ASSIGN_OR_RETURN(Balls3 balls, mesh_balls(mesh, options, &sum));
  HC_ASSIGN_OR_RETURN(TriangleMesh out, crust(balls, &sum));
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

Result<TriangleMesh> offset_3d(const TriangleMesh& mesh, double distance,
                               const ShapeOptions& options, OperationSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!std::isfinite(distance)) return invalid_argument("offset: the distance is not finite");
  OperationSummary sum;
  HC_ASSIGN_OR_RETURN(Balls3 balls, mesh_balls(mesh, options, &sum));
  auto out = crust(offset_balls(balls, distance), &sum);
  if (!out.ok()) return out.status().with_context(fmt::format("offset by {}", distance));
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

ExtraFeatures<3> intersection_features_3d(const TriangleMesh& a, const TriangleMesh& b) {
  // Broad phase: b's triangles in a uniform grid (cell = mean bounding-box edge of b's triangles),
  // a's triangles look up the cells their box overlaps. Written here rather than with CGAL's
  // corefinement because only sample positions are needed, not a combinatorially exact curve.
  ExtraFeatures<3> f;
  if (a.num_triangles() == 0 || b.num_triangles() == 0) return f;
  double cell = 0.0;
  for (Eigen::Index t = 0; t < b.num_triangles(); ++t) {
    const Tri tb = triangle(b, t);
    cell +=
        (tb.p[0].cwiseMax(tb.p[1]).cwiseMax(tb.p[2]) - tb.p[0].cwiseMin(tb.p[1]).cwiseMin(tb.p[2]))
            .maxCoeff();
  }
  cell = std::max(cell / static_cast<double>(b.num_triangles()), 1e-12);
  const auto key = [&](const Eigen::Vector3d& p) {
    const Eigen::Array3d c = (p / cell).array().floor();
    return (static_cast<std::uint64_t>(static_cast<std::int64_t>(c.x()) & 0x1fffff) << 42) |
           (static_cast<std::uint64_t>(static_cast<std::int64_t>(c.y()) & 0x1fffff) << 21) |
           static_cast<std::uint64_t>(static_cast<std::int64_t>(c.z()) & 0x1fffff);
  };
  std::unordered_map<std::uint64_t, std::vector<int>> grid;
  const auto for_cells = [&](const Tri& t, auto&& fn) {
    const Eigen::Vector3d lo = t.p[0].cwiseMin(t.p[1]).cwiseMin(t.p[2]);
    const Eigen::Vector3d hi = t.p[0].cwiseMax(t.p[1]).cwiseMax(t.p[2]);
    const Eigen::Array3d l = (lo / cell).array().floor(), h = (hi / cell).array().floor();
    for (double x = l.x(); x <= h.x(); ++x)
      for (double y = l.y(); y <= h.y(); ++y)
        for (double z = l.z(); z <= h.z(); ++z)
          fn(key(Eigen::Vector3d((x + 0.5) * cell, (y + 0.5) * cell, (z + 0.5) * cell)));
  };
  for (Eigen::Index t = 0; t < b.num_triangles(); ++t) {
    for_cells(triangle(b, t), [&](std::uint64_t k) { grid[k].push_back(static_cast<int>(t)); });
  }
  std::vector<Eigen::Index> stamp(static_cast<std::size_t>(b.num_triangles()), -1);
  for (Eigen::Index t = 0; t < a.num_triangles(); ++t) {
    const Tri ta = triangle(a, t);
    for_cells(ta, [&](std::uint64_t k) {
      const auto it = grid.find(k);
      if (it == grid.end()) return;
      for (const int u : it->second) {
        if (stamp[static_cast<std::size_t>(u)] == t) continue;
        stamp[static_cast<std::size_t>(u)] = t;
        if (const auto s = tri_tri_segment(ta, triangle(b, u))) {
          f.segments.push_back(*s);
          f.corners.push_back((*s)[0]);
          f.corners.push_back((*s)[1]);
        }
      }
    });
  }
  return f;
}

geometry::BooleanOperation to_geometry(BooleanOp op) {
  return op == BooleanOp::kUnion        ? geometry::BooleanOperation::kUnion
         : op == BooleanOp::kDifference ? geometry::BooleanOperation::kDifference
                                        : geometry::BooleanOperation::kIntersection;
}

Result<TriangleMesh> boolean_3d(const TriangleMesh& a, const TriangleMesh& b, BooleanOp op,
                                const ShapeOptions& options, OperationSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance da, closed_mesh(a, "boolean: first input"));
  HC_ASSIGN_OR_RETURN(geometry::MeshDistance db, closed_mesh(b, "boolean: second input"));
  OperationSummary sum;
  const ExtraFeatures<3> features = intersection_features_3d(a, b);
  sum.intersection_points = features.corners.size();
  ShapeOptions o = options;
  const double diag = box_of(a).merged(box_of(b)).diagonal().norm();
  if (o.sampling.r_min <= 0) o.sampling.r_min = o.sampling.r_min_fraction * diag;
  if (o.sampling.r_uniform <= 0) o.sampling.r_uniform = o.sampling.r_uniform_fraction * diag;
  HC_ASSIGN_OR_RETURN(Samples3 sa, sample_mesh(a, o.sampling, features, &sum.sampling));
  HC_ASSIGN_OR_RETURN(Samples3 sb, sample_mesh(b, o.sampling, features));
  Samples3 all;
  for (int which = 0; which < 2; ++which) {
    const Samples3& s = which == 0 ? sa : sb;
    const geometry::MeshDistance& other = which == 0 ? db : da;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (internal::is_feature(s.kinds[i])
              ? which == 0
              : internal::keep_sample(op, which == 0, other.inside(s.points[i]))) {
        all.points.push_back(s.points[i]);
        all.radii.push_back(s.radii[i]);
        all.kinds.push_back(s.kinds[i]);
      }
    }
  }
  sum.samples = all.size();
  if (all.size() < 4)
    return invalid_argument(fmt::format("boolean {}: the result is empty", to_string(op)));
  HC_ASSIGN_OR_RETURN(Balls3 balls, medial_balls_3d(
                                        all,
                                        [&](const Eigen::Vector3d& p) {
                                          return internal::in_result(op, da.inside(p),
                                                                     db.inside(p));
                                        },
                                        o.medial, &sum.medial));
  sum.balls = balls.size();
  auto out = crust(balls, &sum);
  if (!out.ok() && out.status().code() == StatusCode::kInternal) {
    // The crust is not a valid solid: the exact boolean of the same inputs instead.
    auto exact = geometry::corefine_boolean(a, b, to_geometry(op));
    if (!exact.ok()) {
      return out.status().with_context(fmt::format("boolean {} (and its exact fallback: {})",
                                                   to_string(op), exact.status().message()));
    }
    if (exact->num_triangles() == 0)
      return invalid_argument(fmt::format("boolean {}: the result is empty", to_string(op)));
    sum.exact_fallback = true;
    sum.fallback_reason = out.status().message();
    out = std::move(exact);
  }
  if (!out.ok()) return out.status().with_context(fmt::format("boolean {}", to_string(op)));
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

}  // namespace hc::abstraction
