// CGAL's AABB tree over a triangle vector and its exact triangle predicates behind
// geometry/mesh_proximity.h.
#include "geometry/mesh_proximity.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Cartesian_converter.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <vector>

namespace hc::geometry {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

Eigen::Vector3d to_eigen(const Point& p) { return {p.x(), p.y(), p.z()}; }

Result<std::vector<Triangle>> triangles_of(const TriangleMesh& m, const char* what) {
  std::vector<Triangle> out;
  out.reserve(static_cast<std::size_t>(m.num_triangles()));
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    std::array<Point, 3> p;
    for (int k = 0; k < 3; ++k) {
      const int v = m.triangles(t, k);
      if (v < 0 || v >= m.num_vertices())
        return invalid_argument(fmt::format("{}: triangle {} indexes vertex {} of {}", what, t, v,
                                            m.num_vertices()));
      if (!m.vertices.row(v).allFinite())
        return invalid_argument(fmt::format("{}: vertex {} is not finite", what, v));
      p[static_cast<std::size_t>(k)] = Point(m.vertices(v, 0), m.vertices(v, 1), m.vertices(v, 2));
    }
    out.emplace_back(p[0], p[1], p[2]);
  }
  return out;
}

CGAL::Bbox_3 inflated(const CGAL::Bbox_3& b, double r) {
  return {b.xmin() - r, b.ymin() - r, b.zmin() - r, b.xmax() + r, b.ymax() + r, b.zmax() + r};
}

// Closest point to p on triangle (a, b, c): Ericson, Real-Time Collision Detection, 5.1.5.
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// Closest points of segments p1q1 and p2q2: Ericson 5.1.9.
double closest_on_segments(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1,
                           const Eigen::Vector3d& p2, const Eigen::Vector3d& q2,
                           Eigen::Vector3d* c1, Eigen::Vector3d* c2) {
  const Eigen::Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  constexpr double kEps = 1e-30;
  double s = 0, t = 0;
  if (a <= kEps && e <= kEps) {
    s = t = 0;
  } else if (a <= kEps) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= kEps) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > kEps ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  *c1 = p1 + d1 * s;
  *c2 = p2 + d2 * t;
  return (*c1 - *c2).norm();
}

Eigen::Vector3d corner(const Triangle& t, int k) { return to_eigen(t.vertex(k)); }

// A point where two crossing triangles meet (the middle of their intersection), or the first
// triangle's centroid when CGAL's construction returns nothing usable. Constructed with exact
// arithmetic: with inexact constructions CGAL's coplanar triangle-triangle intersection can
// dereference an empty list (it crashed under clang -O1 in MeshProximity's test).
Eigen::Vector3d crossing_point(const Triangle& a, const Triangle& b) {
  using Exact = CGAL::Exact_predicates_exact_constructions_kernel;
  const CGAL::Cartesian_converter<Kernel, Exact> to_exact;
  const auto point = [](const Exact::Point_3& p) {
    return Eigen::Vector3d(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
  };
  const auto x = CGAL::intersection(to_exact(a), to_exact(b));
  if (x) {
    if (const auto* p = boost::get<Exact::Point_3>(&*x)) return point(*p);
    if (const auto* s = boost::get<Exact::Segment_3>(&*x))
      return 0.5 * (point(s->source()) + point(s->target()));
    if (const auto* t = boost::get<Exact::Triangle_3>(&*x))
      return (point(t->vertex(0)) + point(t->vertex(1)) + point(t->vertex(2))) / 3.0;
    if (const auto* v = boost::get<std::vector<Exact::Point_3>>(&*x); v && !v->empty())
      return point(v->front());
  }
  return (corner(a, 0) + corner(a, 1) + corner(a, 2)) / 3.0;
}

}  // namespace

double triangle_closest_points(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1,
                               const Eigen::Vector3d& a2, const Eigen::Vector3d& b0,
                               const Eigen::Vector3d& b1, const Eigen::Vector3d& b2,
                               Eigen::Vector3d* pa, Eigen::Vector3d* pb) {
  const Eigen::Vector3d A[3] = {a0, a1, a2}, B[3] = {b0, b1, b2};
  double best = std::numeric_limits<double>::infinity();
  const auto keep = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
    const double d = (x - y).norm();
    if (d < best) best = d, *pa = x, *pb = y;
  };
  for (int k = 0; k < 3; ++k) {
    keep(A[k], closest_on_triangle(A[k], b0, b1, b2));
    keep(closest_on_triangle(B[k], a0, a1, a2), B[k]);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d x, y;
      closest_on_segments(A[i], A[(i + 1) % 3], B[j], B[(j + 1) % 3], &x, &y);
      keep(x, y);
    }
  return best;
}

struct MeshProximity::Impl {
  std::vector<Triangle> triangles;
  Tree tree;
};

MeshProximity::MeshProximity(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MeshProximity::MeshProximity(MeshProximity&&) noexcept = default;
MeshProximity& MeshProximity::operator=(MeshProximity&&) noexcept = default;
MeshProximity::~MeshProximity() = default;

Result<MeshProximity> MeshProximity::build(const TriangleMesh& b) {
  if (b.num_triangles() == 0) return invalid_argument("mesh proximity: the mesh has no triangles");
  auto impl = std::make_unique<Impl>();
  HC_ASSIGN_OR_RETURN(impl->triangles, triangles_of(b, "mesh proximity"));
  try {
    impl->tree.rebuild(impl->triangles.cbegin(), impl->triangles.cend());
  } catch (const std::exception& e) {
    return internal_error(fmt::format("mesh proximity: CGAL failed: {}", e.what()));
  }
  return MeshProximity(std::move(impl));
}

Result<ClosestApproach> MeshProximity::closest_approach(const TriangleMesh& a,
                                                        double radius) const {
  if (!(radius > 0) || !std::isfinite(radius))
    return invalid_argument(fmt::format("closest approach: radius must be > 0, got {}", radius));
  HC_ASSIGN_OR_RETURN(const std::vector<Triangle> query, triangles_of(a, "closest approach"));
  ClosestApproach out;
  out.distance = std::numeric_limits<double>::infinity();
  std::vector<Primitive::Id> hits;
  try {
    for (std::size_t i = 0; i < query.size(); ++i) {
      const Triangle& ta = query[i];
      hits.clear();
      impl_->tree.all_intersected_primitives(inflated(ta.bbox(), radius), std::back_inserter(hits));
      for (const Primitive::Id& id : hits) {
        const Triangle& tb = *id;
        Eigen::Vector3d pa, pb;
        double dist;
        if (!ta.is_degenerate() && !tb.is_degenerate() && CGAL::do_intersect(ta, tb)) {
          dist = 0.0;
          pa = pb = crossing_point(ta, tb);
        } else {
          dist = triangle_closest_points(corner(ta, 0), corner(ta, 1), corner(ta, 2),
                                         corner(tb, 0), corner(tb, 1), corner(tb, 2), &pa, &pb);
        }
        if (dist <= radius && dist < out.distance) {
          out.found = true;
          out.distance = dist;
          out.point_a = pa;
          out.point_b = pb;
          out.triangle_a = static_cast<Eigen::Index>(i);
          out.triangle_b = static_cast<Eigen::Index>(id - impl_->triangles.cbegin());
        }
      }
    }
  } catch (const std::exception& e) {
    return internal_error(fmt::format("closest approach: CGAL failed: {}", e.what()));
  }
  if (!out.found) out.distance = 0.0;
  return out;
}

Result<std::vector<CrossingPair>> MeshProximity::crossings(const TriangleMesh& a,
                                                           std::size_t max_pairs) const {
  HC_ASSIGN_OR_RETURN(const std::vector<Triangle> query, triangles_of(a, "crossings"));
  std::vector<CrossingPair> out;
  std::vector<Primitive::Id> hits;
  try {
    for (std::size_t i = 0; i < query.size(); ++i) {
      const Triangle& ta = query[i];
      if (ta.is_degenerate()) continue;
      hits.clear();
      impl_->tree.all_intersected_primitives(ta.bbox(), std::back_inserter(hits));
      for (const Primitive::Id& id : hits) {
        if (id->is_degenerate() || !CGAL::do_intersect(ta, *id)) continue;
        out.push_back({static_cast<Eigen::Index>(i),
                       static_cast<Eigen::Index>(id - impl_->triangles.cbegin()),
                       crossing_point(ta, *id)});
        if (max_pairs > 0 && out.size() >= max_pairs) return out;
      }
    }
  } catch (const std::exception& e) {
    return internal_error(fmt::format("crossings: CGAL failed: {}", e.what()));
  }
  return out;
}

bool MeshProximity::contains(const Eigen::Vector3d& p) const {
  // Three directions no axis-aligned or diagonal face is parallel to; a ray through an edge or
  // vertex can miscount, the majority of three rarely does.
  static const Kernel::Vector_3 kDirections[3] = {
      {0.5773, 0.6172, 0.5345}, {-0.2673, 0.8018, -0.5345}, {0.7071, -0.1414, -0.6928}};
  int inside = 0;
  const Point origin(p.x(), p.y(), p.z());
  for (const auto& d : kDirections) {
    const Kernel::Ray_3 ray(origin, d);
    if (impl_->tree.number_of_intersected_primitives(ray) % 2 == 1) ++inside;
  }
  return inside >= 2;
}

Result<bool> MeshProximity::solids_overlap(const TriangleMesh& a) const {
  HC_ASSIGN_OR_RETURN(const std::vector<CrossingPair> pairs, crossings(a, 1));
  if (!pairs.empty()) return true;
  if (a.num_vertices() > 0 && contains(a.vertices.row(a.triangles(0, 0)).transpose())) return true;
  HC_ASSIGN_OR_RETURN(const MeshProximity other, MeshProximity::build(a));
  const Point& p = impl_->triangles.front().vertex(0);
  return other.contains(to_eigen(p));
}

}  // namespace hc::geometry
