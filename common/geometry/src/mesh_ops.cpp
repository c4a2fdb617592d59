// CGAL behind geometry/mesh_ops.h.
#include "geometry/mesh_ops.h"

#include "cgal_support.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/distance.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/helpers.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <boost/iterator/function_output_iterator.hpp>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <string_view>
#include <utility>

namespace hc::geometry {
namespace {

namespace PMP = CGAL::Polygon_mesh_processing;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using FaceIndex = SurfaceMesh::Face_index;
using FacePair = std::pair<FaceIndex, FaceIndex>;
using Polygon = std::array<std::size_t, 3>;

Point point_at(const MatrixX3d& vertices, Eigen::Index v) {
  return {vertices(v, 0), vertices(v, 1), vertices(v, 2)};
}

std::vector<Point> to_points(const MatrixX3d& vertices) {
  std::vector<Point> points;
  points.reserve(static_cast<std::size_t>(vertices.rows()));
  for (Eigen::Index v = 0; v < vertices.rows(); ++v) points.push_back(point_at(vertices, v));
  return points;
}

Polygon polygon_of(const MatrixX3i& triangles, Eigen::Index t) {
  return {static_cast<std::size_t>(triangles(t, 0)), static_cast<std::size_t>(triangles(t, 1)),
          static_cast<std::size_t>(triangles(t, 2))};
}

bool is_collinear_face(const SurfaceMesh& sm, FaceIndex f) {
  const auto h = sm.halfedge(f);
  return CGAL::collinear(sm.point(sm.source(h)), sm.point(sm.target(h)),
                         sm.point(sm.target(sm.next(h))));
}

std::int64_t count_collinear_faces(const SurfaceMesh& sm) {
  std::int64_t n = 0;
  for (FaceIndex f : sm.faces()) n += is_collinear_face(sm, f) ? 1 : 0;
  return n;
}

using internal::guarded;

// Thrown by the soup path's output functor once max_pairs pairs are counted, to stop the sweep.
struct StopCounting {};

// Whether original triangles ta and tb intersect in more than the corners they share: CGAL's own
// rule (PMP::internal::do_faces_intersect), applied to the original vertex indices. The soup path
// needs it because orient_polygon_soup duplicates vertices at non-manifold spots: two triangles
// that shared such a vertex or edge no longer share it in the Surface_mesh, so CGAL sees them
// touch and reports them. Pairs sharing nothing keep CGAL's verdict.
bool intersect_beyond_shared_corners(const TriangleMesh& mesh, std::int32_t ta, std::int32_t tb) {
  std::array<int, 3> a{};
  std::array<int, 3> b{};
  for (int k = 0; k < 3; ++k) {
    a[k] = mesh.triangles(ta, k);
    b[k] = mesh.triangles(tb, k);
  }
  int shared = 0;
  int ia = -1;
  int ib = -1;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (a[i] == b[j]) {
        ++shared;
        ia = i;
        ib = j;
      }
    }
  }
  const auto p = [&](int v) { return point_at(mesh.vertices, v); };
  if (shared == 0 || shared == 3) return true;  // CGAL's full test decided; duplicates are excluded
  if (shared == 2) {
    // Shared edge (u, v): they overlap only if coplanar with the opposite corners on one side.
    int u = -1;
    int w = -1;
    int pa = -1;
    int pb = -1;
    for (int i = 0; i < 3; ++i) {
      if (a[i] != b[0] && a[i] != b[1] && a[i] != b[2]) {
        pa = a[i];
      } else if (u < 0) {
        u = a[i];
      } else {
        w = a[i];
      }
      if (b[i] != a[0] && b[i] != a[1] && b[i] != a[2]) pb = b[i];
    }
    return CGAL::coplanar(p(u), p(w), p(pa), p(pb)) &&
           CGAL::coplanar_orientation(p(u), p(w), p(pa), p(pb)) == CGAL::POSITIVE;
  }
  // One shared corner: they intersect if either opposite edge meets the other triangle.
  const Kernel::Triangle_3 tri_a(p(a[0]), p(a[1]), p(a[2]));
  const Kernel::Triangle_3 tri_b(p(b[0]), p(b[1]), p(b[2]));
  const Kernel::Segment_3 opposite_a(p(a[(ia + 1) % 3]), p(a[(ia + 2) % 3]));
  const Kernel::Segment_3 opposite_b(p(b[(ib + 1) % 3]), p(b[(ib + 2) % 3]));
  return CGAL::do_intersect(tri_a, opposite_b) || CGAL::do_intersect(tri_b, opposite_a);
}

template <class ConcurrencyTag, class FaceRange, class Output>
void run_self_intersections(const FaceRange& faces, const SurfaceMesh& sm, Output out,
                            std::uint64_t cgal_limit) {
  if (cgal_limit == 0) {
    PMP::self_intersections<ConcurrencyTag>(faces, sm, out);
  } else {
    PMP::self_intersections<ConcurrencyTag>(
        faces, sm, out, CGAL::parameters::maximum_number(static_cast<unsigned int>(cgal_limit)));
  }
}

template <class FaceRange, class Output>
void self_intersections_with(bool parallel, const FaceRange& faces, const SurfaceMesh& sm,
                             Output out, std::uint64_t cgal_limit) {
  if (parallel) {
    run_self_intersections<CGAL::Parallel_if_available_tag>(faces, sm, out, cgal_limit);
  } else {
    run_self_intersections<CGAL::Sequential_tag>(faces, sm, out, cgal_limit);
  }
}

SelfIntersectionCount count_in_polygon_mesh(const TriangleMesh& mesh,
                                            const SelfIntersectionQuery& query) {
  std::vector<Polygon> polygons;
  polygons.reserve(query.triangles.size());
  for (std::int32_t t : query.triangles) polygons.push_back(polygon_of(mesh.triangles, t));
  SurfaceMesh sm;
  // Precondition of polygon_soup_to_polygon_mesh, established by check_mesh's topology stage
  // (is_polygon_soup_a_polygon_mesh would re-check it with a std::set, seconds on 1M triangles).
  PMP::polygon_soup_to_polygon_mesh(to_points(mesh.vertices), polygons, sm);
  if (query.progress != nullptr) query.progress->advance();

  // CGAL reports a collinear face as intersecting itself; leaving them out of the range keeps the
  // count (and CGAL's maximum_number) about pairs only.
  std::vector<FaceIndex> faces;
  faces.reserve(sm.number_of_faces());
  for (FaceIndex f : sm.faces())
    if (!is_collinear_face(sm, f)) faces.push_back(f);

  std::vector<FacePair> pairs;
  const bool limited =
      query.max_pairs > 0 && query.max_pairs <= std::numeric_limits<unsigned int>::max();
  self_intersections_with(query.parallel, faces, sm, std::back_inserter(pairs),
                          limited ? query.max_pairs : 0);
  if (query.progress != nullptr) query.progress->advance();

  SelfIntersectionCount count;
  count.pairs = static_cast<std::int64_t>(pairs.size());
  if (limited && pairs.size() >= query.max_pairs) {
    // Parallel workers may each add a pair after the limit is hit.
    count.pairs = static_cast<std::int64_t>(query.max_pairs);
    count.limit_reached = true;
  }
  if (query.progress != nullptr) query.progress->advance();
  return count;
}

SelfIntersectionCount count_in_soup(const TriangleMesh& mesh, const SelfIntersectionQuery& query) {
  std::vector<Point> points = to_points(mesh.vertices);
  std::vector<Polygon> polygons;
  polygons.reserve(query.triangles.size());
  for (std::int32_t t : query.triangles) polygons.push_back(polygon_of(mesh.triangles, t));
  // A non-manifold or inconsistently oriented soup cannot be a Surface_mesh. orient_polygon_soup
  // reorients (irrelevant to intersection) and duplicates points where the surface is
  // non-manifold; it keeps the polygons in order, so face i is still query.triangles[i].
  const std::size_t points_before = points.size();
  PMP::orient_polygon_soup(points, polygons);
  SelfIntersectionCount count;
  count.duplicated_vertices = static_cast<std::int64_t>(points.size() - points_before);
  SurfaceMesh sm;
  PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);
  if (query.progress != nullptr) query.progress->advance();

  const auto accept = [&](const FacePair& pair) {
    if (pair.first == pair.second) return;  // a collinear face: counted as degenerate instead
    const std::int32_t ta = query.triangles[static_cast<std::size_t>(pair.first.idx())];
    const std::int32_t tb = query.triangles[static_cast<std::size_t>(pair.second.idx())];
    if (count.duplicated_vertices > 0 && !intersect_beyond_shared_corners(mesh, ta, tb)) return;
    ++count.pairs;
    if (query.max_pairs > 0 && static_cast<std::uint64_t>(count.pairs) >= query.max_pairs) {
      count.limit_reached = true;
      throw StopCounting{};
    }
  };
  // CGAL's maximum_number would count pairs before the filter above, so the limit is ours; only
  // the sequential sweep calls the output as it goes, so only it can stop early.
  const bool parallel = query.parallel && query.max_pairs == 0;
  try {
    self_intersections_with(parallel, sm.faces(), sm, boost::make_function_output_iterator(accept),
                            0);
  } catch (const StopCounting&) {
    // The limit is reached: count.pairs == max_pairs.
  }
  if (query.progress != nullptr) query.progress->advance(2);
  return count;
}

// Turns every closed component of `sm` outward: all at once, respecting nesting, when the
// surface bounds a volume; otherwise each closed component to positive signed volume.
void orient_outward(SurfaceMesh* sm, SoupRepairStats* stats) {
  if (sm->is_empty() || sm->number_of_faces() == 0) return;  // CGAL indexes component 0 blindly
  if (CGAL::is_closed(*sm) && !PMP::does_self_intersect<CGAL::Parallel_if_available_tag>(*sm)) {
    PMP::orient_to_bound_a_volume(*sm);
    stats->bounds_volume = true;
    return;
  }
  auto component = sm->add_property_map<FaceIndex, std::size_t>("f:hc_component", 0).first;
  const std::size_t n = PMP::connected_components(*sm, component);
  std::vector<double> six_volume(n, 0.0);
  std::vector<char> open(n, 0);
  for (FaceIndex f : sm->faces()) {
    const std::size_t c = component[f];
    const auto h = sm->halfedge(f);
    const Point& p0 = sm->point(sm->source(h));
    const Point& p1 = sm->point(sm->target(h));
    const Point& p2 = sm->point(sm->target(sm->next(h)));
    // Six times the signed volume (divergence theorem), about the origin.
    six_volume[c] += CGAL::scalar_product(
        p0 - CGAL::ORIGIN, CGAL::cross_product(p1 - CGAL::ORIGIN, p2 - CGAL::ORIGIN));
    for (auto he : CGAL::halfedges_around_face(h, *sm))
      if (sm->is_border(sm->opposite(he))) open[c] = 1;
  }
  std::vector<FaceIndex> to_reverse;
  std::vector<char> reversed(n, 0);
  for (FaceIndex f : sm->faces()) {
    const std::size_t c = component[f];
    if (open[c] == 0 && six_volume[c] < 0.0) {
      to_reverse.push_back(f);
      reversed[c] = 1;
    }
  }
  stats->reversed_components = std::count(reversed.begin(), reversed.end(), 1);
  if (!to_reverse.empty()) PMP::reverse_face_orientations(to_reverse, *sm);
  sm->remove_property_map(component);
}

// CGAL's remove_degenerate_faces flips or collapses edges so that a closed surface stays closed
// (simply deleting a collinear triangle would leave a crack along its longest edge). It is
// undocumented in CGAL 5.5 and "may not remove all"; it works on a copy, which is kept only when
// the result is still a valid triangle mesh.
void remove_collinear_faces(SurfaceMesh* sm, SoupRepairStats* stats) {
  stats->collinear_before = count_collinear_faces(*sm);
  stats->collinear_after = stats->collinear_before;
  if (stats->collinear_before == 0) return;
  SurfaceMesh work = *sm;
  try {
    PMP::remove_degenerate_faces(work);
    work.collect_garbage();
    if (CGAL::is_valid_polygon_mesh(work) && CGAL::is_triangle_mesh(work)) *sm = std::move(work);
  } catch (const std::exception&) {
    // Keep *sm as it was; the after-check counts what is left.
  }
  stats->collinear_after = count_collinear_faces(*sm);
}

void to_soup(SurfaceMesh* sm, std::vector<Point>* points, std::vector<Polygon>* polygons) {
  sm->collect_garbage();
  points->clear();
  for (auto v : sm->vertices()) points->push_back(sm->point(v));
  polygons->clear();
  for (FaceIndex f : sm->faces()) {
    Polygon polygon{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(sm->halfedge(f), *sm)) polygon[k++] = v.idx();
    polygons->push_back(polygon);
  }
}

void export_mesh(SurfaceMesh& sm, TriangleMesh* out) {
  sm.collect_garbage();
  out->vertices.resize(static_cast<Eigen::Index>(sm.number_of_vertices()), 3);
  for (auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    out->vertices.row(static_cast<Eigen::Index>(v.idx())) << p.x(), p.y(), p.z();
  }
  out->triangles.resize(static_cast<Eigen::Index>(sm.number_of_faces()), 3);
  for (FaceIndex f : sm.faces()) {
    int k = 0;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm))
      out->triangles(static_cast<Eigen::Index>(f.idx()), k++) = static_cast<int>(v.idx());
  }
}

// --- Self-intersection repair ---------------------------------------------------------------

// A triangle whose largest angle exceeds this is a cap: the threshold CGAL's own
// internal::is_badly_shaped names ("angle over 160° ==> cap", repair_degeneracies.h, 5.5.1).
constexpr double kCapAngleDeg = 160.0;
// The Hausdorff distances deciding whether a step stays within max_deviation are measured to
// within this fraction of it (CGAL's bounded-error algorithm stops refining there). Its cost grows
// with the inverse square: on candleStand.stl, 0.04 s at a tenth, 0.35 s at a hundredth, 34 s at a
// ten-thousandth.
constexpr double kDeviationErrorFraction = 0.1;

// Pairs of non-collinear faces of `sm` that intersect beyond a shared vertex or edge: the count
// check_mesh reports (collinear faces are its degenerate triangles, and CGAL would pair each with
// itself).
std::vector<FacePair> intersecting_pairs(const SurfaceMesh& sm, bool parallel) {
  std::vector<FaceIndex> faces;
  faces.reserve(sm.number_of_faces());
  for (FaceIndex f : sm.faces())
    if (!is_collinear_face(sm, f)) faces.push_back(f);
  std::vector<FacePair> pairs;
  self_intersections_with(parallel, faces, sm, std::back_inserter(pairs), 0);
  return pairs;
}

// Hausdorff distance from `a` to `b` (one-sided), or between them (symmetric), to within
// error_bound. Faces present in both are skipped (CGAL's match_faces), so a local change costs
// little. Sequential: CGAL 5.5's parallel version needs METIS as well as TBB.
double hausdorff(const SurfaceMesh& a, const SurfaceMesh& b, bool symmetric, double error_bound) {
  return symmetric ? PMP::bounded_error_symmetric_Hausdorff_distance<CGAL::Sequential_tag>(
                         a, b, error_bound)
                   : PMP::bounded_error_Hausdorff_distance<CGAL::Sequential_tag>(a, b, error_bound);
}

enum class ResolveMethod { kCapFlips, kLocalRemoval, kAutorefine };

const char* method_name(ResolveMethod m) {
  switch (m) {
    case ResolveMethod::kCapFlips:
      return "cap_flips";
    case ResolveMethod::kLocalRemoval:
      return "local_removal";
    case ResolveMethod::kAutorefine:
      return "autorefine";
  }
  return "?";
}

// Runs one CGAL repair on `work` (a copy of the current mesh). Returns what CGAL's own verdict
// says when it admits defeat, empty otherwise; the caller judges the result itself either way.
std::string run_method(ResolveMethod method, const ResolveOptions& options,
                       const std::vector<FacePair>& pairs, SurfaceMesh* work) {
  switch (method) {
    case ResolveMethod::kCapFlips: {
      // Only the faces that intersect: caps elsewhere are the mesh's own business (OpenSCAD
      // output is full of them), and flipping them would change a surface that is fine.
      std::set<FaceIndex> faces;
      for (const FacePair& p : pairs) {
        faces.insert(p.first);
        faces.insert(p.second);
      }
      // A needle threshold of infinity collapses nothing (a collapse moves a vertex); caps
      // taller than max_deviation are left alone (a flip moves the surface by up to the height).
      const bool done = PMP::experimental::remove_almost_degenerate_faces(
          faces, *work, std::cos(kCapAngleDeg * std::numbers::pi / 180.0),
          std::numeric_limits<double>::infinity(), 0.0,
          CGAL::parameters::flip_triangle_height_threshold(options.max_deviation));
      return done ? std::string() : "CGAL could not flip every cap";
    }
    case ResolveMethod::kLocalRemoval: {
      // preserve_genus: a print must keep its holes. apply_per_connected_component is left at its
      // default (true); neither it nor preserve_genus(false) changed the outcome on
      // candleStand.stl or on two overlapping cubes.
      const bool done = PMP::experimental::remove_self_intersections(
          *work, CGAL::parameters::preserve_genus(true));
      return done ? std::string() : "CGAL reports intersections left";
    }
    case ResolveMethod::kAutorefine: {
      const bool done = PMP::experimental::autorefine_and_remove_self_intersections(*work);
      return done ? std::string() : "CGAL reports intersections left";
    }
  }
  return {};
}

std::string join_notes(const std::string& a, const std::string& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return a + "; " + b;
}

// Judges the result of one step against `current` (whose pairs are known); fills step->pairs_after,
// deviation and note, and returns whether `work` should replace `current`.
bool accept_step(ResolveMethod method, const ResolveOptions& options, const SurfaceMesh& current,
                 bool closed, std::int64_t pairs_before, SurfaceMesh* work,
                 std::vector<FacePair>* pairs_after, SelfIntersectionStep* step) {
  work->collect_garbage();
  if (work->number_of_faces() == 0 || !CGAL::is_valid_polygon_mesh(*work) ||
      !CGAL::is_triangle_mesh(*work)) {
    step->note = join_notes(step->note, "result is not a valid triangle mesh");
    return false;
  }
  if (closed && !CGAL::is_closed(*work)) {
    step->note = join_notes(step->note, "result is not closed");
    return false;
  }
  // The local steps are meant to leave the topology alone (a print must keep its holes);
  // autorefine merges the parts that overlap, which is what changes it.
  const auto euler = [](const SurfaceMesh& sm) {
    return static_cast<std::int64_t>(sm.number_of_vertices()) -
           static_cast<std::int64_t>(sm.number_of_edges()) +
           static_cast<std::int64_t>(sm.number_of_faces());
  };
  if (method != ResolveMethod::kAutorefine && euler(*work) != euler(current)) {
    step->note = join_notes(step->note, "result has another Euler characteristic");
    return false;
  }
  *pairs_after = intersecting_pairs(*work, options.parallel);
  step->pairs_after = static_cast<std::int64_t>(pairs_after->size());
  if (step->pairs_after >= pairs_before) {
    step->note = join_notes(step->note, "no fewer intersecting pairs");
    return false;
  }
  // Autorefine removes the parts inside the solid, so only its result must lie on its input.
  const bool symmetric = method != ResolveMethod::kAutorefine;
  step->deviation_error = kDeviationErrorFraction * options.max_deviation;
  step->deviation = hausdorff(*work, current, symmetric, step->deviation_error);
  if (step->deviation > options.max_deviation) {
    step->note = join_notes(step->note,
                            fmt::format("moved the surface by {:.3g}, more than the {:.3g} allowed",
                                        step->deviation, options.max_deviation));
    return false;
  }
  if (method == ResolveMethod::kAutorefine && PMP::volume(*work) <= 0.0) {
    // Autorefine keeps what it takes for the outside; when the input's orientation does not say
    // that (a face pushed through the opposite wall), what is left can be an inside-out scrap.
    step->note = join_notes(step->note, "result bounds no positive volume");
    return false;
  }
  return true;
}

}  // namespace

Result<std::vector<std::uint8_t>> collinear_triangles(const TriangleMesh& mesh) {
  return guarded<std::vector<std::uint8_t>>("degeneracy test", [&]() {
    std::vector<std::uint8_t> collinear(static_cast<std::size_t>(mesh.num_triangles()), 0);
    for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
      collinear[static_cast<std::size_t>(t)] =
          CGAL::collinear(point_at(mesh.vertices, mesh.triangles(t, 0)),
                          point_at(mesh.vertices, mesh.triangles(t, 1)),
                          point_at(mesh.vertices, mesh.triangles(t, 2)))
              ? 1
              : 0;
    }
    return collinear;
  });
}

Result<SelfIntersectionCount> count_self_intersecting_pairs(const TriangleMesh& mesh,
                                                            const SelfIntersectionQuery& query) {
  return guarded<SelfIntersectionCount>("self-intersection test", [&]() {
    return query.is_polygon_mesh ? count_in_polygon_mesh(mesh, query) : count_in_soup(mesh, query);
  });
}

Status repair_triangle_soup(const SoupRepairOptions& options, TriangleMesh* soup,
                            SoupRepairStats* stats) {
  Result<bool> done = guarded<bool>("mesh repair", [&]() {
    std::vector<Point> points = to_points(soup->vertices);
    std::vector<Polygon> polygons;
    polygons.reserve(static_cast<std::size_t>(soup->num_triangles()));
    for (Eigen::Index t = 0; t < soup->num_triangles(); ++t)
      polygons.push_back(polygon_of(soup->triangles, t));
    if (options.orient) {
      const std::size_t before = points.size();
      PMP::orient_polygon_soup(points, polygons);
      stats->split_vertices = static_cast<std::int64_t>(points.size() - before);
      stats->polygon_mesh = true;
    } else {
      stats->polygon_mesh = PMP::is_polygon_soup_a_polygon_mesh(polygons);
    }
    if (!stats->polygon_mesh) {
      // Not a Surface_mesh and not to be reoriented: there is no mesh to flip edges in, so
      // collinear triangles are dropped (which may open a crack the after-check will report).
      if (options.remove_collinear) {
        const std::size_t before = polygons.size();
        std::erase_if(polygons, [&](const Polygon& q) {
          return CGAL::collinear(points[q[0]], points[q[1]], points[q[2]]);
        });
        stats->collinear_before = static_cast<std::int64_t>(before - polygons.size());
      }
      soup->triangles.resize(static_cast<Eigen::Index>(polygons.size()), 3);
      for (std::size_t i = 0; i < polygons.size(); ++i)
        for (int k = 0; k < 3; ++k)
          soup->triangles(static_cast<Eigen::Index>(i), k) = static_cast<int>(polygons[i][k]);
      return true;
    }
    SurfaceMesh sm;
    PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);
    if (options.remove_collinear) remove_collinear_faces(&sm, stats);
    if (options.orient && stats->collinear_after < stats->collinear_before) {
      // The removal changes the topology the first orientation worked on: it can rejoin sheets
      // that were split apart (a collinear triangle on a non-manifold edge) or pinch the surface
      // into a new non-manifold vertex. Merge the copies and orient afresh, so that what is split
      // is what must be, and a second repair finds nothing to do.
      // Flips can also recreate a triangle that exists already.
      to_soup(&sm, &points, &polygons);
      PMP::merge_duplicate_points_in_polygon_soup(points, polygons);
      stats->degenerate_removed_later = static_cast<std::int64_t>(std::erase_if(
          polygons, [](const Polygon& q) { return q[0] == q[1] || q[1] == q[2] || q[2] == q[0]; }));
      if (options.remove_duplicates) {
        stats->duplicates_removed_later = static_cast<std::int64_t>(
            PMP::merge_duplicate_polygons_in_polygon_soup(points, polygons));
      }
      const std::size_t before = points.size();
      PMP::orient_polygon_soup(points, polygons);
      stats->split_vertices = static_cast<std::int64_t>(points.size() - before);
      sm.clear();
      PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);
    }
    // Isolated vertices have no halfedge, which volume_connected_components does not expect.
    for (auto v : sm.vertices())
      if (sm.is_isolated(v)) sm.remove_vertex(v);
    if (options.orient) orient_outward(&sm, stats);
    export_mesh(sm, soup);
    return true;
  });
  return done.status();
}

Status resolve_self_intersections(const ResolveOptions& options, TriangleMesh* mesh,
                                  std::vector<SelfIntersectionStep>* steps) {
  if (!(options.max_deviation > 0.0) || !std::isfinite(options.max_deviation))
    return invalid_argument(
        fmt::format("self-intersection repair: max_deviation must be finite and > 0, got {}",
                    options.max_deviation));
  SurfaceMesh current;
  Result<bool> built = guarded<bool>("self-intersection repair", [&]() {
    std::vector<Polygon> polygons;
    polygons.reserve(static_cast<std::size_t>(mesh->num_triangles()));
    std::vector<char> used(static_cast<std::size_t>(mesh->num_vertices()), 0);
    for (Eigen::Index t = 0; t < mesh->num_triangles(); ++t) {
      const Polygon q = polygon_of(mesh->triangles, t);
      if (q[0] == q[1] || q[1] == q[2] || q[2] == q[0]) return false;
      for (std::size_t v : q) used[v] = 1;
      polygons.push_back(q);
    }
    if (std::find(used.begin(), used.end(), 0) != used.end()) return false;
    if (!PMP::is_polygon_soup_a_polygon_mesh(polygons)) return false;
    PMP::polygon_soup_to_polygon_mesh(to_points(mesh->vertices), polygons, current);
    return true;
  });
  if (!built.ok()) return built.status();
  if (!*built)
    return invalid_argument(
        "self-intersection repair: needs a manifold, consistently oriented triangle mesh without "
        "repeated corners or unreferenced vertices");

  Result<std::vector<FacePair>> first = guarded<std::vector<FacePair>>(
      "self-intersection repair", [&]() { return intersecting_pairs(current, options.parallel); });
  if (!first.ok()) return first.status();
  std::vector<FacePair> pairs = std::move(*first);
  const bool closed = CGAL::is_closed(current);
  bool changed = false;
  for (ResolveMethod method :
       {ResolveMethod::kCapFlips, ResolveMethod::kLocalRemoval, ResolveMethod::kAutorefine}) {
    if (pairs.empty()) break;
    SelfIntersectionStep step;
    step.method = method_name(method);
    step.pairs_before = static_cast<std::int64_t>(pairs.size());
    if (method == ResolveMethod::kAutorefine && !closed) {
      // Which side is inside is what autorefine keeps or removes by; an open surface has none.
      step.note = "skipped: the mesh is not closed";
      steps->push_back(std::move(step));
      if (options.progress != nullptr) options.progress->advance();
      continue;
    }
    const auto start = std::chrono::steady_clock::now();
    try {
      SurfaceMesh work = current;
      std::vector<FacePair> pairs_after;
      step.note = run_method(method, options, pairs, &work);
      if (accept_step(method, options, current, closed, step.pairs_before, &work, &pairs_after,
                      &step)) {
        step.kept = true;
        current = std::move(work);
        pairs = std::move(pairs_after);
        changed = true;
      }
    } catch (const std::exception& e) {
      step.note = join_notes(step.note, fmt::format("CGAL failed: {}", e.what()));
    } catch (...) {
      step.note = join_notes(step.note, "CGAL failed with an unknown exception");
    }
    step.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    steps->push_back(std::move(step));
    if (options.progress != nullptr) options.progress->advance();
  }
  if (!changed) return {};
  return guarded<bool>("self-intersection repair",
                       [&]() {
                         export_mesh(current, mesh);
                         return true;
                       })
      .status();
}

}  // namespace hc::geometry
