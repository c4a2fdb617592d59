#include "fabrication/printability/mesh_repair.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "geometry/mesh_ops.h"

namespace hc::fabrication {
namespace {

using Clock = std::chrono::steady_clock;
using Triangle = std::array<int, 3>;

// Grid cells are indexed in int64; coordinates this many cells from the origin share the outermost
// cell (still correct, since every candidate's distance is tested, only slower).
constexpr double kMaxCell = 4.0e18;

struct ArrayHash {
  template <class T, std::size_t N>
  std::size_t operator()(const std::array<T, N>& a) const {
    std::uint64_t h = 0x9e3779b97f4a7c15ULL;
    for (const T& x : a) {
      h ^= static_cast<std::uint64_t>(x) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    }
    return static_cast<std::size_t>(h);
  }
};

// Exact position as a hash key; +0.0 and -0.0 are the same position.
std::array<std::uint64_t, 3> position_key(const MatrixX3d& v, Eigen::Index i) {
  std::array<std::uint64_t, 3> key{};
  for (int k = 0; k < 3; ++k) key[k] = std::bit_cast<std::uint64_t>(v(i, k) == 0.0 ? 0.0 : v(i, k));
  return key;
}

// Merges the vertices in `ids` (indices into `vertices`, in order) that share a position
// exactly. Returns the kept positions in order of first appearance; (*welded)[id] is the new index.
MatrixX3d weld_exact(const MatrixX3d& vertices, const std::vector<int>& ids,
                     std::vector<int>* welded) {
  std::vector<int> order = ids;
  const auto less = [&](int a, int b) {
    for (int k = 0; k < 3; ++k) {
      if (vertices(a, k) < vertices(b, k)) return true;
      if (vertices(b, k) < vertices(a, k)) return false;
    }
    return a < b;
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<int> representative(static_cast<std::size_t>(vertices.rows()), -1);
  for (std::size_t i = 0; i < order.size(); ++i) {
    const bool same = i > 0 && vertices.row(order[i]) == vertices.row(order[i - 1]);
    representative[order[i]] = same ? representative[order[i - 1]] : order[i];
  }
  MatrixX3d kept(static_cast<Eigen::Index>(ids.size()), 3);
  Eigen::Index n = 0;
  for (int id : ids) {
    const int rep = representative[id];
    if (rep == id) {
      kept.row(n) = vertices.row(id);
      (*welded)[id] = static_cast<int>(n++);
    } else {
      (*welded)[id] = (*welded)[rep];  // rep < id, so it is already numbered
    }
  }
  kept.conservativeResize(n, 3);
  return kept;
}

// Merges each vertex into the first kept vertex within `tolerance`, found through a grid of
// cells of that size (only the 27 cells around a vertex can hold one). Greedy in input order, so
// a chain of vertices each just within tolerance of the next is not collapsed into one.
MatrixX3d weld_within(const MatrixX3d& vertices, const std::vector<int>& ids, double tolerance,
                      std::vector<int>* welded) {
  using Cell = std::array<std::int64_t, 3>;
  std::unordered_map<Cell, std::vector<int>, ArrayHash> grid;
  MatrixX3d kept(static_cast<Eigen::Index>(ids.size()), 3);
  Eigen::Index n = 0;
  const double squared = tolerance * tolerance;
  for (int id : ids) {
    const Eigen::RowVector3d p = vertices.row(id);
    Cell cell{};
    for (int k = 0; k < 3; ++k)
      cell[k] =
          static_cast<std::int64_t>(std::clamp(std::floor(p[k] / tolerance), -kMaxCell, kMaxCell));
    int found = -1;
    for (std::int64_t dx = -1; dx <= 1 && found < 0; ++dx) {
      for (std::int64_t dy = -1; dy <= 1 && found < 0; ++dy) {
        for (std::int64_t dz = -1; dz <= 1 && found < 0; ++dz) {
          const auto it = grid.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (it == grid.end()) continue;
          for (int k : it->second) {
            if ((kept.row(k) - p).squaredNorm() <= squared) {
              found = k;
              break;
            }
          }
        }
      }
    }
    if (found < 0) {
      found = static_cast<int>(n);
      kept.row(n++) = p;
      grid[cell].push_back(found);
    }
    (*welded)[id] = found;
  }
  kept.conservativeResize(n, 3);
  return kept;
}

// A triangle's vertex set in ascending order, and whether its corner order is an even
// permutation of that (the same orientation as the sorted order).
struct OrientedKey {
  std::array<int, 3> sorted;
  bool even;
  bool operator<(const OrientedKey& o) const { return sorted < o.sorted; }
};
OrientedKey oriented_key(const Triangle& t) {
  const int m = static_cast<int>(std::min_element(t.begin(), t.end()) - t.begin());
  const int x = t[(m + 1) % 3];
  const int y = t[(m + 2) % 3];
  return {{t[m], std::min(x, y), std::max(x, y)}, x < y};
}

// Triangles of `after` whose orientation is opposite to a triangle on the same three positions in
// `before` (whose indices are into before_vertices, with distinct positions). Copies of one
// triangle are matched as multisets, so a kept pair of opposite copies counts no flip. Triangles
// new to `after` are not counted.
std::int64_t count_flipped(const MatrixX3d& before_vertices, const std::vector<Triangle>& before,
                           const TriangleMesh& after) {
  std::unordered_map<std::array<std::uint64_t, 3>, int, ArrayHash> index_of;
  index_of.reserve(static_cast<std::size_t>(before_vertices.rows()));
  for (Eigen::Index v = 0; v < before_vertices.rows(); ++v)
    index_of.emplace(position_key(before_vertices, v), static_cast<int>(v));
  std::vector<OrientedKey> old_keys;
  old_keys.reserve(before.size());
  for (const Triangle& t : before) old_keys.push_back(oriented_key(t));
  std::vector<OrientedKey> new_keys;
  new_keys.reserve(static_cast<std::size_t>(after.num_triangles()));
  for (Eigen::Index t = 0; t < after.num_triangles(); ++t) {
    Triangle mapped{};
    bool known = true;
    for (int k = 0; k < 3 && known; ++k) {
      const auto it = index_of.find(position_key(after.vertices, after.triangles(t, k)));
      known = it != index_of.end();
      if (known) mapped[k] = it->second;
    }
    if (known) new_keys.push_back(oriented_key(mapped));
  }
  std::sort(old_keys.begin(), old_keys.end());
  std::sort(new_keys.begin(), new_keys.end());
  const auto count_even = [](auto first, auto last) {
    return std::count_if(first, last, [](const OrientedKey& k) { return k.even; });
  };
  std::int64_t flipped = 0;
  for (auto run = old_keys.begin(); run != old_keys.end();) {
    const auto run_end = std::upper_bound(run, old_keys.end(), *run);
    const auto [first, last] = std::equal_range(new_keys.begin(), new_keys.end(), *run);
    const std::int64_t even_before = count_even(run, run_end);
    const std::int64_t odd_before = (run_end - run) - even_before;
    const std::int64_t even_after = count_even(first, last);
    const std::int64_t odd_after = (last - first) - even_after;
    const std::int64_t kept_even = std::min(even_before, even_after);
    const std::int64_t kept_odd = std::min(odd_before, odd_after);
    flipped += std::min(even_before - kept_even, odd_after - kept_odd) +
               std::min(odd_before - kept_odd, even_after - kept_even);
    run = run_end;
  }
  return flipped;
}

// The opt-in self-intersection stage, on `mesh` as the earlier steps left it (whose check is
// summary->after). It never fails the repair: whatever goes wrong is recorded in
// summary->self_intersections, and `mesh` and summary->after then stay as they were.
void resolve_self_intersections(const MeshRepairOptions& options,
                                const MeshCheckOptions& check_options, TriangleMesh* mesh,
                                MeshRepairSummary* summary) {
  const auto start = Clock::now();
  SelfIntersectionStage& stage = summary->self_intersections;
  stage.attempted = true;
  stage.pairs_before = summary->after.self_intersecting_pairs;
  stage.pairs_after = stage.pairs_before;
  const auto fail = [&](std::string why) {
    stage.failed = true;
    stage.message = std::move(why);
    stage.time_s = std::chrono::duration<double>(Clock::now() - start).count();
  };

  // CGAL works on the triangles and the vertices they use; the rest (kept when
  // remove_unreferenced_vertices is off) is appended again afterwards.
  std::vector<int> new_index(static_cast<std::size_t>(mesh->num_vertices()), -1);
  for (Eigen::Index t = 0; t < mesh->num_triangles(); ++t) {
    const auto row = mesh->triangles.row(t);
    if (row(0) == row(1) || row(1) == row(2) || row(2) == row(0))
      return fail("a kept triangle has a repeated corner (remove_degenerate_triangles is off)");
    for (int k = 0; k < 3; ++k) new_index[row(k)] = 0;
  }
  std::vector<int> unused;
  int n = 0;
  for (std::size_t v = 0; v < new_index.size(); ++v) {
    if (new_index[v] == 0) {
      new_index[v] = n++;
    } else {
      unused.push_back(static_cast<int>(v));
    }
  }
  TriangleMesh work;
  work.vertices.resize(n, 3);
  for (std::size_t v = 0; v < new_index.size(); ++v)
    if (new_index[v] >= 0) work.vertices.row(new_index[v]) = mesh->vertices.row(v);
  work.triangles.resize(mesh->num_triangles(), 3);
  for (Eigen::Index t = 0; t < mesh->num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) work.triangles(t, k) = new_index[mesh->triangles(t, k)];

  geometry::ResolveOptions resolve;
  resolve.max_deviation =
      options.self_intersection_max_deviation * summary->after.bounding_box.diagonal().norm();
  resolve.parallel = check_options.parallel;
  {
    ProgressTask task(options.progress, "resolve self-intersections", geometry::kResolveSteps);
    resolve.progress = &task;
    if (Status s = geometry::resolve_self_intersections(resolve, &work, &stage.steps); !s.ok())
      return fail(s.message());
  }
  if (std::none_of(stage.steps.begin(), stage.steps.end(),
                   [](const SelfIntersectionStep& s) { return s.kept; })) {
    std::string why = "no CGAL step was kept";
    for (const SelfIntersectionStep& s : stage.steps)
      why += fmt::format("; {}: {}", s.method, s.note);
    return fail(why);
  }
  if (!unused.empty()) {
    const Eigen::Index first = work.vertices.rows();
    work.vertices.conservativeResize(first + static_cast<Eigen::Index>(unused.size()), 3);
    for (std::size_t i = 0; i < unused.size(); ++i)
      work.vertices.row(first + static_cast<Eigen::Index>(i)) = mesh->vertices.row(unused[i]);
  }
  Result<MeshCheckReport> after = check_mesh(work, check_options);
  if (!after.ok()) return fail("checking the result failed: " + after.status().message());
  // The steps judged by their own count; the verdict that is reported is check_mesh's.
  if (after->self_intersecting_pairs >= stage.pairs_before ||
      (summary->after.closed && !after->closed))
    return fail(fmt::format("the check of the result found {} intersecting pairs{}",
                            after->self_intersecting_pairs, after->closed ? "" : ", and it open"));
  *mesh = std::move(work);
  summary->after = std::move(*after);
  stage.pairs_after = summary->after.self_intersecting_pairs;
  summary->resolved_self_intersecting_pairs = stage.pairs_before - stage.pairs_after;
  stage.time_s = std::chrono::duration<double>(Clock::now() - start).count();
}

// The triangles after welding and the removal of degenerate and duplicate triangles, ready for
// the CGAL stage.
struct WeldedSoup {
  MatrixX3d positions;              // welded positions of the used vertices
  std::vector<Triangle> triangles;  // three distinct corners, indices into `positions`
  std::vector<Triangle> repeated;   // kept triangles with a repeated corner
  std::vector<int> unused;          // input vertices no triangle uses
};

WeldedSoup weld_and_filter(const MeshRepairOptions& options, const TriangleMesh& mesh,
                           MeshRepairSummary* summary) {
  WeldedSoup out;
  const auto nv = static_cast<std::size_t>(mesh.num_vertices());
  std::vector<char> referenced(nv, 0);
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) referenced[static_cast<std::size_t>(mesh.triangles(t, k))] = 1;
  std::vector<int> used;
  for (std::size_t v = 0; v < nv; ++v)
    (referenced[v] != 0 ? used : out.unused).push_back(static_cast<int>(v));

  // Only used vertices are welded: unused ones are dropped or carried over untouched (they
  // may hold anything, even NaN, since no triangle reaches them).
  std::vector<int> welded(nv, -1);
  out.positions = options.weld_tolerance > 0.0
                      ? weld_within(mesh.vertices, used, options.weld_tolerance, &welded)
                      : weld_exact(mesh.vertices, used, &welded);
  summary->merged_vertices = static_cast<std::int64_t>(used.size()) - out.positions.rows();

  // Triangles with a repeated corner (some from welding) bound nothing; when kept, they stay
  // out of the CGAL stage, which needs three distinct corners.
  std::vector<Triangle>& triangles = out.triangles;
  triangles.reserve(static_cast<std::size_t>(mesh.num_triangles()));
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    const Triangle tri{welded[mesh.triangles(t, 0)], welded[mesh.triangles(t, 1)],
                       welded[mesh.triangles(t, 2)]};
    if (tri[0] != tri[1] && tri[1] != tri[2] && tri[2] != tri[0]) {
      triangles.push_back(tri);
    } else if (options.remove_degenerate_triangles) {
      ++summary->removed_degenerate_triangles;
    } else {
      out.repeated.push_back(tri);
    }
  }
  if (options.remove_duplicate_triangles) {
    // Keep the first triangle on each vertex set, whatever its orientation.
    std::vector<std::pair<std::array<int, 3>, std::size_t>> keys;
    keys.reserve(triangles.size());
    for (std::size_t i = 0; i < triangles.size(); ++i)
      keys.emplace_back(oriented_key(triangles[i]).sorted, i);
    std::sort(keys.begin(), keys.end());
    std::vector<char> drop(triangles.size(), 0);
    for (std::size_t i = 1; i < keys.size(); ++i)
      if (keys[i].first == keys[i - 1].first) drop[keys[i].second] = 1;
    std::size_t n = 0;
    for (std::size_t i = 0; i < triangles.size(); ++i)
      if (drop[i] == 0) triangles[n++] = triangles[i];
    summary->removed_duplicate_triangles = static_cast<std::int64_t>(triangles.size() - n);
    triangles.resize(n);
  }
  return out;
}

// The CGAL stage (orientation, collinear and late duplicate removal) on the vertices the
// triangles use (CGAL's volume orientation trips on isolated vertices); `welded.triangles` are
// renumbered into the returned soup's numbering before the stage.
Result<TriangleMesh> repair_soup(const MeshRepairOptions& options, WeldedSoup& welded,
                                 MeshRepairSummary* summary) {
  std::vector<Triangle>& triangles = welded.triangles;
  TriangleMesh soup;
  std::vector<int> soup_index(static_cast<std::size_t>(welded.positions.rows()), -1);
  for (const Triangle& tri : triangles)
    for (int v : tri) soup_index[v] = 0;
  int used_welded = 0;
  for (int& index : soup_index)
    if (index == 0) index = used_welded++;
  soup.vertices.resize(used_welded, 3);
  for (Eigen::Index v = 0; v < welded.positions.rows(); ++v)
    if (soup_index[v] >= 0) soup.vertices.row(soup_index[v]) = welded.positions.row(v);
  soup.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      triangles[i][k] = soup_index[triangles[i][k]];
      soup.triangles(static_cast<Eigen::Index>(i), k) = triangles[i][k];
    }
  }
  if (options.orient || options.remove_degenerate_triangles) {
    const MatrixX3d soup_positions = soup.vertices;
    geometry::SoupRepairOptions soup_options;
    soup_options.orient = options.orient;
    soup_options.remove_collinear = options.remove_degenerate_triangles;
    soup_options.remove_duplicates = options.remove_duplicate_triangles;
    geometry::SoupRepairStats stats;
    HC_RETURN_IF_ERROR(geometry::repair_triangle_soup(soup_options, &soup, &stats));
    summary->removed_degenerate_triangles +=
        stats.collinear_before - stats.collinear_after + stats.degenerate_removed_later;
    summary->removed_duplicate_triangles += stats.duplicates_removed_later;
    summary->split_non_manifold_vertices = stats.split_vertices;
    summary->flipped_triangles = count_flipped(soup_positions, triangles, soup);
  }
  return soup;
}

// Reassembles the soup, then every welded vertex the soup lost (used by a kept repeated-corner
// triangle, or by nothing any more), looked up by position since the CGAL stage may renumber
// vertices; then drops the vertices left unused when asked to.
TriangleMesh reassemble(const MeshRepairOptions& options, const TriangleMesh& input,
                        const WeldedSoup& welded, const TriangleMesh& soup,
                        MeshRepairSummary* summary) {
  const MatrixX3d& welded_positions = welded.positions;
  TriangleMesh repaired;
  repaired.vertices = soup.vertices;
  std::vector<Triangle> out_triangles;
  out_triangles.reserve(static_cast<std::size_t>(soup.num_triangles()) + welded.repeated.size());
  for (Eigen::Index t = 0; t < soup.num_triangles(); ++t)
    out_triangles.push_back({soup.triangles(t, 0), soup.triangles(t, 1), soup.triangles(t, 2)});
  std::unordered_map<std::array<std::uint64_t, 3>, int, ArrayHash> index_of;
  for (Eigen::Index v = soup.vertices.rows() - 1; v >= 0; --v)
    index_of[position_key(soup.vertices, v)] = static_cast<int>(v);  // lowest index wins
  std::vector<int> welded_to_out(static_cast<std::size_t>(welded_positions.rows()));
  Eigen::Index n_out = repaired.vertices.rows();
  repaired.vertices.conservativeResize(n_out + welded_positions.rows(), 3);
  for (Eigen::Index v = 0; v < welded_positions.rows(); ++v) {
    const auto [it, added] =
        index_of.try_emplace(position_key(welded_positions, v), static_cast<int>(n_out));
    if (added) repaired.vertices.row(n_out++) = welded_positions.row(v);
    welded_to_out[v] = it->second;
  }
  repaired.vertices.conservativeResize(n_out, 3);
  for (const Triangle& tri : welded.repeated)
    out_triangles.push_back({welded_to_out[tri[0]], welded_to_out[tri[1]], welded_to_out[tri[2]]});
  const std::vector<int>& unused = welded.unused;
  if (!options.remove_unreferenced_vertices && !unused.empty()) {
    const Eigen::Index n = repaired.vertices.rows();
    repaired.vertices.conservativeResize(n + static_cast<Eigen::Index>(unused.size()), 3);
    for (std::size_t i = 0; i < unused.size(); ++i)
      repaired.vertices.row(n + static_cast<Eigen::Index>(i)) = input.vertices.row(unused[i]);
  } else {
    summary->removed_unreferenced_vertices = static_cast<std::int64_t>(unused.size());
  }

  // Vertices left unused by the triangle removals above.
  std::vector<int> new_index(static_cast<std::size_t>(repaired.vertices.rows()), -1);
  for (const Triangle& tri : out_triangles)
    for (int v : tri) new_index[v] = 0;
  int n = 0;
  for (Eigen::Index v = 0; v < repaired.vertices.rows(); ++v) {
    const bool keep = new_index[v] == 0 || !options.remove_unreferenced_vertices;
    new_index[v] = keep ? n++ : -1;
    if (keep) repaired.vertices.row(new_index[v]) = repaired.vertices.row(v);
  }
  summary->removed_unreferenced_vertices += repaired.vertices.rows() - n;
  repaired.vertices.conservativeResize(n, 3);
  repaired.triangles.resize(static_cast<Eigen::Index>(out_triangles.size()), 3);
  for (std::size_t i = 0; i < out_triangles.size(); ++i)
    for (int k = 0; k < 3; ++k)
      repaired.triangles(static_cast<Eigen::Index>(i), k) = new_index[out_triangles[i][k]];
  return repaired;
}

}  // namespace

Status MeshRepairOptions::validate() const {
  if (!std::isfinite(weld_tolerance) || weld_tolerance < 0.0)
    return invalid_argument(
        fmt::format("weld_tolerance must be finite and >= 0, got {}", weld_tolerance));
  if (!std::isfinite(self_intersection_max_deviation) || self_intersection_max_deviation <= 0.0)
    return invalid_argument(
        fmt::format("self_intersection_max_deviation must be finite and > 0, got {}",
                    self_intersection_max_deviation));
  return {};
}

bool MeshRepairSummary::changed() const {
  return merged_vertices > 0 || removed_degenerate_triangles > 0 ||
         removed_duplicate_triangles > 0 || removed_unreferenced_vertices > 0 ||
         flipped_triangles > 0 || split_non_manifold_vertices > 0 ||
         resolved_self_intersecting_pairs > 0;
}

Status repair_mesh(const MeshRepairOptions& options, TriangleMesh* mesh,
                   MeshRepairSummary* summary) {
  if (mesh == nullptr || summary == nullptr)
    return invalid_argument("mesh repair: mesh and summary must not be null");
  HC_RETURN_IF_ERROR(options.validate().with_context("mesh repair options"));
  const auto start = Clock::now();
  *summary = MeshRepairSummary{};
  MeshCheckOptions check_options;
  check_options.progress = options.progress;
  // The check validates indices and coordinates, which everything below relies on.
  HC_ASSIGN_OR_RETURN(summary->before, check_mesh(*mesh, check_options));

  TriangleMesh repaired;
  {
    ProgressTask task(options.progress, "mesh repair", 3);
    WeldedSoup welded = weld_and_filter(options, *mesh, summary);
    task.advance();
    HC_ASSIGN_OR_RETURN(const TriangleMesh soup, repair_soup(options, welded, summary));
    task.advance();
    repaired = reassemble(options, *mesh, welded, soup, summary);
    task.advance();
    task.set_summary(summary->changed() ? "changed" : "nothing to change");
  }

  HC_ASSIGN_OR_RETURN(summary->after, check_mesh(repaired, check_options));
  if (options.resolve_self_intersections && summary->after.self_intersecting_pairs > 0)
    resolve_self_intersections(options, check_options, &repaired, summary);
  *mesh = std::move(repaired);
  summary->closed = summary->after.closed;
  summary->printable = summary->after.printable;
  summary->time_s = std::chrono::duration<double>(Clock::now() - start).count();
  return {};
}

nlohmann::json to_json(const SelfIntersectionStage& stage) {
  nlohmann::json steps = nlohmann::json::array();
  for (const SelfIntersectionStep& s : stage.steps) {
    steps.push_back({
        {"method", s.method},
        {"kept", s.kept},
        {"pairs_before", s.pairs_before},
        {"pairs_after", s.pairs_after < 0 ? nlohmann::json() : nlohmann::json(s.pairs_after)},
        {"deviation", s.deviation < 0.0 ? nlohmann::json() : nlohmann::json(s.deviation)},
        {"deviation_error", s.deviation_error},
        {"time_s", s.time_s},
        {"note", s.note},
    });
  }
  return {
      {"attempted", stage.attempted},     {"failed", stage.failed},
      {"message", stage.message},         {"pairs_before", stage.pairs_before},
      {"pairs_after", stage.pairs_after}, {"steps", std::move(steps)},
      {"time_s", stage.time_s},
  };
}

nlohmann::json to_json(const MeshRepairSummary& summary) {
  return {
      {"changed", summary.changed()},
      {"merged_vertices", summary.merged_vertices},
      {"removed_degenerate_triangles", summary.removed_degenerate_triangles},
      {"removed_duplicate_triangles", summary.removed_duplicate_triangles},
      {"removed_unreferenced_vertices", summary.removed_unreferenced_vertices},
      {"flipped_triangles", summary.flipped_triangles},
      {"split_non_manifold_vertices", summary.split_non_manifold_vertices},
      {"resolved_self_intersecting_pairs", summary.resolved_self_intersecting_pairs},
      {"self_intersections", to_json(summary.self_intersections)},
      {"closed", summary.closed},
      {"printable", summary.printable},
      {"time_s", summary.time_s},
      {"before", to_json(summary.before)},
      {"after", to_json(summary.after)},
  };
}

std::string to_text(const MeshRepairSummary& summary) {
  std::string out;
  const auto line = [&out](std::string_view label, std::int64_t value) {
    out += fmt::format("{:<32}{}\n", label, value);
  };
  out += summary.changed() ? "repaired\n" : "nothing to repair\n";
  line("merged vertices", summary.merged_vertices);
  line("removed degenerate triangles", summary.removed_degenerate_triangles);
  line("removed duplicate triangles", summary.removed_duplicate_triangles);
  line("removed unreferenced vertices", summary.removed_unreferenced_vertices);
  line("flipped triangles", summary.flipped_triangles);
  line("split non-manifold vertices", summary.split_non_manifold_vertices);
  const SelfIntersectionStage& stage = summary.self_intersections;
  if (stage.attempted) {
    line("resolved intersecting pairs", summary.resolved_self_intersecting_pairs);
    for (const SelfIntersectionStep& s : stage.steps) {
      out += fmt::format("  {:<30}{}, pairs {} -> {}", s.method, s.kept ? "kept" : "not kept",
                         s.pairs_before, s.pairs_after < 0 ? "?" : std::to_string(s.pairs_after));
      if (s.deviation >= 0.0)
        out += fmt::format(", deviation {:.3g} (+-{:.3g})", s.deviation, s.deviation_error);
      out += fmt::format(", {:.3f} s", s.time_s);
      if (!s.note.empty()) out += " (" + s.note + ")";
      out += "\n";
    }
    if (stage.failed)
      out += fmt::format(
          "WARNING: self-intersections not resolved, mesh kept as repaired before: {}\n",
          stage.message);
  }
  out += fmt::format("{:<32}{}\n", "closed", summary.closed ? "yes" : "no");
  out += fmt::format("{:<32}{}\n", "printable", summary.printable ? "yes" : "no");
  out += fmt::format("{:<32}{:.3f} s\n", "time", summary.time_s);
  out += "\nafter repair:\n" + to_text(summary.after);
  return out;
}

}  // namespace hc::fabrication
