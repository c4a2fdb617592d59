#include "fabrication/printability/mesh_check.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "geometry/mesh_ops.h"

namespace hc::fabrication {
namespace {

using Clock = std::chrono::steady_clock;

// Halfedges are numbered 3 * triangle + corner, in 32 bits.
constexpr Eigen::Index kMaxTriangles = std::numeric_limits<std::int32_t>::max() / 3;
constexpr Eigen::Index kMaxVertices = std::numeric_limits<std::int32_t>::max();
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

// Records the wall time of consecutive stages into report->stage_seconds.
class StageClock {
 public:
  explicit StageClock(MeshCheckReport* report) : report_(report), last_(Clock::now()) {}
  void lap(const char* stage) {
    const auto now = Clock::now();
    report_->stage_seconds.emplace_back(stage, std::chrono::duration<double>(now - last_).count());
    last_ = now;
  }

 private:
  MeshCheckReport* report_;
  Clock::time_point last_;
};

// Union-find with path halving; unions keep the smaller index as root, so roots are stable.
class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) {
    for (std::size_t i = 0; i < n; ++i) parent_[i] = static_cast<std::uint32_t>(i);
  }
  std::uint32_t find(std::uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a < b) {
      parent_[b] = a;
    } else if (b < a) {
      parent_[a] = b;
    }
  }

 private:
  std::vector<std::uint32_t> parent_;
};

std::uint32_t corner(const TriangleMesh& mesh, std::uint32_t he) {
  return static_cast<std::uint32_t>(mesh.triangles(he / 3, he % 3));
}
std::uint32_t corner_after(const TriangleMesh& mesh, std::uint32_t he) {
  return static_cast<std::uint32_t>(mesh.triangles(he / 3, (he % 3 + 1) % 3));
}
// Halfedge 3t+k runs from corner k to corner k+1 of triangle t; this is corner k+1's id.
std::uint32_t next_corner_id(std::uint32_t he) { return he - he % 3 + (he % 3 + 1) % 3; }

bool has_repeated_corner(const TriangleMesh& mesh, Eigen::Index t) {
  const auto& tri = mesh.triangles;
  return tri(t, 0) == tri(t, 1) || tri(t, 1) == tri(t, 2) || tri(t, 2) == tri(t, 0);
}

Status validate_mesh(const TriangleMesh& mesh) {
  if (mesh.num_vertices() > kMaxVertices)
    return invalid_argument(
        fmt::format("{} vertices: at most {} are supported", mesh.num_vertices(), kMaxVertices));
  if (mesh.num_triangles() > kMaxTriangles)
    return invalid_argument(
        fmt::format("{} triangles: at most {} are supported", mesh.num_triangles(), kMaxTriangles));
  const Eigen::Index nv = mesh.num_vertices();
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles(t, k);
      if (v < 0 || v >= nv)
        return invalid_argument(
            fmt::format("triangle {} corner {}: vertex index {} is outside [0, {})", t, k, v, nv));
      // The exact predicates are undefined on NaN and infinity.
      if (!mesh.vertices.row(v).allFinite())
        return invalid_argument(
            fmt::format("triangle {} uses vertex {}, which has a non-finite coordinate", t, v));
    }
  }
  return {};
}

// Edges, fans and components. Written by hand rather than through a CGAL halfedge structure
// because the input need not be a valid one (that is what we are checking), and because a
// bucket sort of halfedges by their lower vertex is several times faster than building one.
// Triangles with a repeated corner take no part: they bound no area, and their two copies of one
// edge would make that edge look non-manifold.
void analyse_topology(const TriangleMesh& mesh, MeshCheckReport* report) {
  const auto nv = static_cast<std::size_t>(mesh.num_vertices());
  const auto nf = static_cast<std::size_t>(mesh.num_triangles());
  std::vector<char> valid(nf, 0);
  std::vector<char> referenced(nv, 0);
  for (std::size_t t = 0; t < nf; ++t) {
    valid[t] = has_repeated_corner(mesh, static_cast<Eigen::Index>(t)) ? 0 : 1;
    for (int k = 0; k < 3; ++k) referenced[static_cast<std::size_t>(mesh.triangles(t, k))] = 1;
  }
  report->unreferenced_vertices = std::count(referenced.begin(), referenced.end(), 0);

  // Bucket the halfedges by their lower vertex (a counting sort), then order each small bucket by
  // the upper vertex: equal (lower, upper) runs are the distinct undirected edges.
  std::vector<std::uint32_t> bucket_start(nv + 1, 0);
  for (std::size_t t = 0; t < nf; ++t) {
    if (valid[t] == 0) continue;
    for (int k = 0; k < 3; ++k) {
      const auto he = static_cast<std::uint32_t>(3 * t + k);
      ++bucket_start[std::min(corner(mesh, he), corner_after(mesh, he)) + 1];
    }
  }
  for (std::size_t v = 0; v < nv; ++v) bucket_start[v + 1] += bucket_start[v];
  std::vector<std::uint32_t> halfedges(bucket_start[nv]);
  {
    std::vector<std::uint32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (std::size_t t = 0; t < nf; ++t) {
      if (valid[t] == 0) continue;
      for (int k = 0; k < 3; ++k) {
        const auto he = static_cast<std::uint32_t>(3 * t + k);
        halfedges[fill[std::min(corner(mesh, he), corner_after(mesh, he))]++] = he;
      }
    }
  }
  const auto upper = [&](std::uint32_t he) {
    return std::max(corner(mesh, he), corner_after(mesh, he));
  };

  UnionFind triangle_sets(nf);
  UnionFind fans(3 * nf);                    // corners joined across manifold edges
  std::vector<std::uint32_t> edge_triangle;  // one triangle per distinct edge
  edge_triangle.reserve(halfedges.size() / 2);
  for (std::size_t v = 0; v < nv; ++v) {
    const auto first = halfedges.begin() + bucket_start[v];
    const auto last = halfedges.begin() + bucket_start[v + 1];
    std::sort(first, last, [&](std::uint32_t a, std::uint32_t b) {
      const std::uint32_t ua = upper(a);
      const std::uint32_t ub = upper(b);
      return ua < ub || (ua == ub && a < b);
    });
    for (auto run = first; run != last;) {
      auto run_end = run + 1;
      while (run_end != last && upper(*run_end) == upper(*run)) ++run_end;
      const auto n = run_end - run;
      ++report->edges;
      edge_triangle.push_back(*run / 3);
      for (auto it = run + 1; it != run_end; ++it) triangle_sets.unite(*run / 3, *it / 3);
      if (n == 1) {
        ++report->boundary_edges;
      } else if (n >= 3) {
        ++report->non_manifold_edges;
      } else {
        const std::uint32_t h1 = run[0];
        const std::uint32_t h2 = run[1];
        if (corner(mesh, h1) == corner(mesh, h2)) {
          ++report->misoriented_edges;
          fans.unite(h1, h2);
          fans.unite(next_corner_id(h1), next_corner_id(h2));
        } else {
          fans.unite(h1, next_corner_id(h2));
          fans.unite(next_corner_id(h1), h2);
        }
      }
      run = run_end;
    }
  }
  report->consistently_oriented = report->misoriented_edges == 0;

  // A vertex whose corners fall into more than one fan is non-manifold.
  std::vector<std::uint32_t> first_fan(nv, kNone);
  std::vector<char> non_manifold(nv, 0);
  for (std::size_t t = 0; t < nf; ++t) {
    if (valid[t] == 0) continue;
    for (int k = 0; k < 3; ++k) {
      const auto c = static_cast<std::uint32_t>(3 * t + k);
      const auto v = static_cast<std::size_t>(mesh.triangles(t, k));
      const std::uint32_t fan = fans.find(c);
      if (first_fan[v] == kNone) {
        first_fan[v] = fan;
      } else if (first_fan[v] != fan) {
        non_manifold[v] = 1;
      }
    }
  }
  report->non_manifold_vertices = std::count(non_manifold.begin(), non_manifold.end(), 1);

  // Components of triangles, numbered densely.
  std::vector<std::uint32_t> component(nf, kNone);
  std::vector<std::uint32_t> id_of_root(nf, kNone);
  for (std::size_t t = 0; t < nf; ++t) {
    if (valid[t] == 0) continue;
    const std::uint32_t root = triangle_sets.find(static_cast<std::uint32_t>(t));
    if (id_of_root[root] == kNone)
      id_of_root[root] = static_cast<std::uint32_t>(report->components++);
    component[t] = id_of_root[root];
  }

  report->closed = report->edges > 0 && report->boundary_edges == 0;
  report->manifold = report->non_manifold_edges == 0 && report->non_manifold_vertices == 0;
  if (!report->closed || !report->manifold) return;

  // Genus from Euler's formula per component: chi = V - E + F = 2 - 2g for a closed orientable
  // surface. On a manifold each vertex lies in one component.
  const auto nc = static_cast<std::size_t>(report->components);
  std::vector<std::int64_t> chi(nc, 0);
  for (std::size_t t = 0; t < nf; ++t)
    if (valid[t] != 0) ++chi[component[t]];
  for (std::uint32_t t : edge_triangle) --chi[component[t]];
  std::vector<char> counted(nv, 0);
  for (std::size_t t = 0; t < nf; ++t) {
    if (valid[t] == 0) continue;
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(mesh.triangles(t, k));
      if (counted[v] == 0) {
        counted[v] = 1;
        ++chi[component[t]];
      }
    }
  }
  std::int64_t genus = 0;
  for (std::int64_t c : chi) {
    // An odd or too large characteristic means a non-orientable surface, which has no genus in
    // this sense (and cannot be embedded without self-intersections).
    if (c > 2 || (2 - c) % 2 != 0) return;
    genus += (2 - c) / 2;
  }
  report->genus = genus;
}

// Duplicate triangles: same set of three vertices as an earlier triangle, in any order.
// Marks every copy after the first in `duplicate`.
void find_duplicates(const TriangleMesh& mesh, MeshCheckReport* report,
                     std::vector<char>* duplicate) {
  const auto nf = static_cast<std::size_t>(mesh.num_triangles());
  std::vector<std::array<std::uint32_t, 4>> keys(nf);
  for (std::size_t t = 0; t < nf; ++t) {
    std::array<std::uint32_t, 4> key{static_cast<std::uint32_t>(mesh.triangles(t, 0)),
                                     static_cast<std::uint32_t>(mesh.triangles(t, 1)),
                                     static_cast<std::uint32_t>(mesh.triangles(t, 2)),
                                     static_cast<std::uint32_t>(t)};
    std::sort(key.begin(), key.begin() + 3);
    keys[t] = key;
  }
  std::sort(keys.begin(), keys.end());
  duplicate->assign(nf, 0);
  for (std::size_t i = 1; i < nf; ++i) {
    if (std::equal(keys[i].begin(), keys[i].begin() + 3, keys[i - 1].begin())) {
      (*duplicate)[keys[i][3]] = 1;
      ++report->duplicate_triangles;
    }
  }
}

// Area, signed volume and bounding box of the referenced vertices. Volume is taken about the
// bounding-box centre rather than the origin: the sum is the same for a closed surface, and far
// from the origin the per-triangle terms would otherwise cancel in floating point.
void measure(const TriangleMesh& mesh, MeshCheckReport* report) {
  report->bounding_box.setEmpty();
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k)
      report->bounding_box.extend(mesh.vertices.row(mesh.triangles(t, k)).transpose());
  if (report->bounding_box.isEmpty()) return;
  const Eigen::Vector3d centre = report->bounding_box.center();
  double twice_area = 0.0;
  double six_volume = 0.0;
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.row(mesh.triangles(t, 0)).transpose() - centre;
    const Eigen::Vector3d b = mesh.vertices.row(mesh.triangles(t, 1)).transpose() - centre;
    const Eigen::Vector3d c = mesh.vertices.row(mesh.triangles(t, 2)).transpose() - centre;
    twice_area += (b - a).cross(c - a).norm();
    six_volume += a.dot(b.cross(c));
  }
  report->area = twice_area / 2.0;
  report->volume = six_volume / 6.0;
}

std::string plural(std::int64_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

void explain(MeshCheckReport* report) {
  auto& problems = report->problems;
  auto& warnings = report->warnings;
  if (report->triangles == 0) problems.push_back("The mesh has no triangles.");
  if (report->boundary_edges > 0)
    problems.push_back(fmt::format("{} on a single triangle: the surface has holes.",
                                   plural(report->boundary_edges, "edge lies", "edges lie")));
  if (report->non_manifold_edges > 0)
    problems.push_back(fmt::format("{} shared by three or more triangles.",
                                   plural(report->non_manifold_edges, "edge is", "edges are")));
  if (report->non_manifold_vertices > 0)
    problems.push_back(fmt::format("{} where separate sheets of surface touch.",
                                   plural(report->non_manifold_vertices, "vertex", "vertices")));
  if (report->misoriented_edges > 0)
    problems.push_back(fmt::format(
        "{} traversed in the same direction by both triangles: inconsistent orientation.",
        plural(report->misoriented_edges, "edge is", "edges are")));
  if (!report->self_intersections_checked) {
    problems.push_back("Self-intersections were not checked.");
  } else if (report->self_intersecting_pairs > 0) {
    problems.push_back(fmt::format(
        "{}{} intersect each other.", report->self_intersection_limit_reached ? "At least " : "",
        plural(report->self_intersecting_pairs, "pair of triangles", "pairs of triangles")));
  }
  // The sign of the volume means something only for a closed, consistently oriented surface.
  if (report->closed && report->consistently_oriented && report->volume <= 0.0)
    problems.push_back(report->volume < 0.0 ? "The volume is negative: the triangles face inward."
                                            : "The enclosed volume is zero.");
  if (report->degenerate_triangles > 0)
    warnings.push_back(fmt::format(
        "{} (repeated or collinear corners).",
        plural(report->degenerate_triangles, "degenerate triangle", "degenerate triangles")));
  if (report->duplicate_triangles > 0)
    warnings.push_back(
        fmt::format("{} the vertices of an earlier one.",
                    plural(report->duplicate_triangles, "triangle repeats", "triangles repeat")));
  if (report->unreferenced_vertices > 0)
    warnings.push_back(
        fmt::format("{} by no triangle.",
                    plural(report->unreferenced_vertices, "vertex is used", "vertices are used")));
}

}  // namespace

Status MeshCheckOptions::validate() const { return {}; }

Result<MeshCheckReport> check_mesh(const TriangleMesh& mesh, const MeshCheckOptions& options) {
  HC_RETURN_IF_ERROR(options.validate().with_context("mesh check options"));
  const auto start = Clock::now();
  MeshCheckReport report;
  StageClock clock(&report);
  HC_RETURN_IF_ERROR(validate_mesh(mesh).with_context("mesh check"));
  report.vertices = mesh.num_vertices();
  report.triangles = mesh.num_triangles();
  clock.lap("validate");

  analyse_topology(mesh, &report);
  clock.lap("topology");

  HC_ASSIGN_OR_RETURN(const std::vector<std::uint8_t> collinear,
                      geometry::collinear_triangles(mesh));
  std::vector<char> duplicate;
  find_duplicates(mesh, &report, &duplicate);
  report.degenerate_triangles = std::count(collinear.begin(), collinear.end(), 1);
  clock.lap("degeneracy");

  measure(mesh, &report);
  clock.lap("geometry");

  if (options.check_self_intersections) {
    geometry::SelfIntersectionQuery query;
    query.triangles.reserve(static_cast<std::size_t>(mesh.num_triangles()));
    for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
      // Repeated-corner triangles cannot enter a Surface_mesh, and a second copy of a triangle
      // would intersect the first everywhere: both are counted by their own stages instead.
      if (!has_repeated_corner(mesh, t) && duplicate[static_cast<std::size_t>(t)] == 0)
        query.triangles.push_back(static_cast<std::int32_t>(t));
    }
    query.is_polygon_mesh = report.manifold && report.consistently_oriented;
    query.parallel = options.parallel;
    query.max_pairs = options.max_self_intersecting_pairs;
    ProgressTask task(options.progress, "mesh check: self-intersections",
                      geometry::kSelfIntersectionSteps);
    query.progress = &task;
    HC_ASSIGN_OR_RETURN(const geometry::SelfIntersectionCount count,
                        geometry::count_self_intersecting_pairs(mesh, query));
    report.self_intersections_checked = true;
    report.self_intersecting_pairs = count.pairs;
    report.self_intersection_limit_reached = count.limit_reached;
    task.set_summary(plural(count.pairs, "intersecting pair", "intersecting pairs"));
    clock.lap("self_intersections");
  }

  report.printable = report.self_intersections_checked && report.closed && report.manifold &&
                     report.consistently_oriented && report.self_intersecting_pairs == 0 &&
                     report.volume > 0.0;
  explain(&report);
  report.stage_seconds.emplace_back("total",
                                    std::chrono::duration<double>(Clock::now() - start).count());
  return report;
}

nlohmann::json to_json(const MeshCheckReport& report) {
  nlohmann::json j;
  j["vertices"] = report.vertices;
  j["triangles"] = report.triangles;
  j["unreferenced_vertices"] = report.unreferenced_vertices;
  j["components"] = report.components;
  j["edges"] = report.edges;
  j["boundary_edges"] = report.boundary_edges;
  j["non_manifold_edges"] = report.non_manifold_edges;
  j["non_manifold_vertices"] = report.non_manifold_vertices;
  j["misoriented_edges"] = report.misoriented_edges;
  j["consistently_oriented"] = report.consistently_oriented;
  j["degenerate_triangles"] = report.degenerate_triangles;
  j["duplicate_triangles"] = report.duplicate_triangles;
  j["self_intersections_checked"] = report.self_intersections_checked;
  j["self_intersecting_pairs"] = report.self_intersections_checked
                                     ? nlohmann::json(report.self_intersecting_pairs)
                                     : nlohmann::json(nullptr);
  j["self_intersection_limit_reached"] = report.self_intersection_limit_reached;
  j["area"] = report.area;
  j["volume"] = report.volume;
  j["genus"] = report.genus ? nlohmann::json(*report.genus) : nlohmann::json(nullptr);
  if (report.bounding_box.isEmpty()) {
    j["bounding_box"] = nullptr;
  } else {
    const auto& box = report.bounding_box;
    j["bounding_box"] = {{"min", {box.min().x(), box.min().y(), box.min().z()}},
                         {"max", {box.max().x(), box.max().y(), box.max().z()}}};
  }
  j["closed"] = report.closed;
  j["manifold"] = report.manifold;
  j["printable"] = report.printable;
  j["problems"] = report.problems;
  j["warnings"] = report.warnings;
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& [stage, seconds] : report.stage_seconds) stages[stage] = seconds;
  j["stage_seconds"] = stages;
  return j;
}

std::string to_text(const MeshCheckReport& report) {
  std::string out;
  const auto yes_no = [](bool b) { return b ? "yes" : "no"; };
  const auto line = [&out](std::string_view label, const std::string& value) {
    out += fmt::format("{:<24}{}\n", label, value);
  };
  line("printable", yes_no(report.printable));
  line("vertices",
       fmt::format("{} ({} unreferenced)", report.vertices, report.unreferenced_vertices));
  line("triangles", fmt::format("{} ({} degenerate, {} duplicate)", report.triangles,
                                report.degenerate_triangles, report.duplicate_triangles));
  line("edges", fmt::format("{} ({} boundary, {} non-manifold)", report.edges,
                            report.boundary_edges, report.non_manifold_edges));
  line("non-manifold vertices", std::to_string(report.non_manifold_vertices));
  line("components", std::to_string(report.components));
  line("closed", yes_no(report.closed));
  line("manifold", yes_no(report.manifold));
  line("consistently oriented",
       fmt::format("{} ({} misoriented edges)", yes_no(report.consistently_oriented),
                   report.misoriented_edges));
  line("self-intersections",
       report.self_intersections_checked
           ? fmt::format("{}{} pairs", report.self_intersection_limit_reached ? ">= " : "",
                         report.self_intersecting_pairs)
           : std::string("not checked"));
  line("genus",
       report.genus ? std::to_string(*report.genus) : std::string("n/a (not closed and manifold)"));
  line("area", fmt::format("{:.6g}", report.area));
  line("volume", fmt::format("{:.6g}", report.volume));
  if (!report.bounding_box.isEmpty()) {
    const auto& b = report.bounding_box;
    line("bounding box",
         fmt::format("[{:.6g}, {:.6g}, {:.6g}] .. [{:.6g}, {:.6g}, {:.6g}]", b.min().x(),
                     b.min().y(), b.min().z(), b.max().x(), b.max().y(), b.max().z()));
  }
  for (const auto& p : report.problems) out += "problem: " + p + "\n";
  for (const auto& w : report.warnings) out += "warning: " + w + "\n";
  std::string stages;
  for (const auto& [stage, seconds] : report.stage_seconds)
    stages += fmt::format("{}{} {:.3f} s", stages.empty() ? "" : ", ", stage, seconds);
  line("time", stages);
  return out;
}

}  // namespace hc::fabrication
