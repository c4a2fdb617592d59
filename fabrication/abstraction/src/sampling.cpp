// Adaptive Poisson-disk sampling (sampling.h): the front ends for polygons and triangle meshes and
// the pipeline they share (uniform pass -> approximate medial axis -> radius field -> pools ->
// elimination).
#include "fabrication/abstraction/sampling.h"
#include "common/clock.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numbers>
#include <unordered_map>

#include "fabrication/abstraction/medial_balls.h"
#include "geometry/nearest_point.h"
#include "geometry/regular_triangulation.h"
#include "geometry/triangulation_2d.h"
#include "poisson.h"

namespace hc::abstraction {

using internal::Elements;
using internal::Simplex;
using internal::Vec;

Result<AliasTable> AliasTable::build(std::span<const double> weights) {
  const std::size_t n = weights.size();
  double sum = 0.0;
  for (const double w : weights) {
    if (!std::isfinite(w) || w < 0)
      return invalid_argument("alias table: weights must be finite and >= 0");
    sum += w;
  }
  if (n == 0 || !(sum > 0)) return invalid_argument("alias table: the weights sum to zero");
  AliasTable t;
  t.threshold_.assign(n, 1.0);
  t.alias_.resize(n);
  std::vector<double> p(n);
  std::vector<std::uint32_t> small, large;
  for (std::size_t i = 0; i < n; ++i) {
    p[i] = weights[i] * static_cast<double>(n) / sum;
    t.alias_[i] = static_cast<std::uint32_t>(i);
    (p[i] < 1.0 ? small : large).push_back(static_cast<std::uint32_t>(i));
  }
  // Vose's stable variant: pair each under-full column with an over-full one.
  while (!small.empty() && !large.empty()) {
    const std::uint32_t s = small.back();
    small.pop_back();
    const std::uint32_t l = large.back();
    t.threshold_[s] = p[s];
    t.alias_[s] = l;
    p[l] = (p[l] + p[s]) - 1.0;
    if (p[l] < 1.0) {
      large.pop_back();
      small.push_back(l);
    }
  }
  return t;
}

std::size_t AliasTable::draw(std::mt19937_64& rng) const {
  std::uniform_int_distribution<std::size_t> column(0, threshold_.size() - 1);
  std::uniform_real_distribution<double> coin(0.0, 1.0);
  const std::size_t i = column(rng);
  return coin(rng) < threshold_[i] ? i : alias_[i];
}

Status SamplingOptions::validate() const {
  if (!(epsilon > 0 && epsilon < 1))
    return invalid_argument(fmt::format("sampling: epsilon must be in (0, 1), got {}", epsilon));
  if (!(r_min >= 0) || !(r_uniform >= 0))
    return invalid_argument("sampling: r_min and r_uniform must be >= 0");
  if (!(r_min_fraction > 0) || !(r_uniform_fraction > 0) || !(r_max_fraction > 0)) {
    return invalid_argument("sampling: the radius fractions must be > 0");
  }
  if (!(r_max >= 0)) return invalid_argument("sampling: r_max must be >= 0");
  if (!(sharp_fraction >= 0 && sharp_fraction < 1))
    return invalid_argument("sampling: sharp_fraction must be in [0, 1)");
  if (!(pool_density >= 1)) return invalid_argument("sampling: pool_density must be >= 1");
  if (max_pool < 16) return invalid_argument("sampling: max_pool must be >= 16");
  return {};
}

namespace {

constexpr double kSplitFactor = 1.0;  // simplices split until no longer than their r
constexpr std::size_t kMaxSimplices = 20'000'000;

// Distance to the nearest of a fixed set of sites, queried once per split round: in 3-D by a k-d
// tree built once; 2-D inputs are small enough to triangulate each round.
template <int D>
class NearestSite;

template <>
class NearestSite<2> {
 public:
  static Result<NearestSite> build(std::vector<Vec<2>> sites) {
    NearestSite n;
    n.sites_ = std::move(sites);
    return n;
  }
  Result<std::vector<double>> distance(std::span<const Vec<2>> q) const {
    const std::vector<double> zero(sites_.size(), 0.0);
    HC_ASSIGN_OR_RETURN(geometry::PowerQuery2 pq, geometry::nearest_power_2d(sites_, zero, q));
    for (double& p : pq.power) p = std::sqrt(std::max(0.0, p));
    return std::move(pq.power);
  }

 private:
  std::vector<Vec<2>> sites_;
};

template <>
class NearestSite<3> {
 public:
  static Result<NearestSite> build(const std::vector<Vec<3>>& sites) {
    HC_ASSIGN_OR_RETURN(geometry::NearestPoint3 tree, geometry::NearestPoint3::build(sites));
    return NearestSite(std::move(tree));
  }
  Result<std::vector<double>> distance(std::span<const Vec<3>> q) const {
    HC_ASSIGN_OR_RETURN(geometry::NearestQuery nq, tree_.query(q));
    return std::move(nq.distance);
  }

 private:
  explicit NearestSite(geometry::NearestPoint3 tree) : tree_(std::move(tree)) {}
  geometry::NearestPoint3 tree_;
};

// The approximate medial axis of a uniform sampling: 2-D all Voronoi vertices, 3-D the poles.
Result<std::vector<Vec<2>>> medial_points(std::vector<Vec<2>> pts, const Eigen::AlignedBox2d& box) {
  for (const auto& b : bounding_points<2>(box.min(), box.max(), 1.0)) pts.push_back(b);
  HC_ASSIGN_OR_RETURN(geometry::Triangulation2 dt, geometry::triangulate_2d(pts));
  std::vector<Vec<2>> m;
  for (std::size_t t = 0; t < dt.triangles.size(); ++t) {
    if (dt.is_finite(static_cast<int>(t))) m.push_back(dt.centres[t]);
  }
  return m;
}
Result<std::vector<Vec<3>>> medial_points(std::vector<Vec<3>> pts, const Eigen::AlignedBox3d& box) {
  const std::size_t n = pts.size();
  for (const auto& b : bounding_points<3>(box.min(), box.max(), 1.0)) pts.push_back(b);
  HC_ASSIGN_OR_RETURN(geometry::Triangulation3 dt, geometry::triangulate_3d(pts));
  const Poles poles = compute_poles(dt, pts, n);
  std::vector<std::uint8_t> used(dt.cells.size(), 0);
  std::vector<Vec<3>> m;
  for (std::size_t i = 0; i < n; ++i) {
    for (const int c : {poles.plus[i], poles.minus[i]}) {
      if (c >= 0 && !used[static_cast<std::size_t>(c)]) {
        used[static_cast<std::size_t>(c)] = 1;
        m.push_back(dt.centres[static_cast<std::size_t>(c)]);
      }
    }
  }
  return m;
}

// The shared pipeline. `elements` carries the unsplit segments / triangles; `corners` the C_p.
template <int D>
Result<Samples<D>> sample(Elements<D> elements, std::vector<Vec<D>> corners,
                          std::vector<SampleKind> corner_kinds,
                          const Eigen::AlignedBox<double, D>& box, const SamplingOptions& o,
                          SamplingSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  SamplingSummary sum;
  const double diag = box.diagonal().norm();
  sum.r_min = o.r_min > 0 ? o.r_min : o.r_min_fraction * diag;
  sum.r_uniform = o.r_uniform > 0 ? o.r_uniform : o.r_uniform_fraction * diag;
  sum.r_max = std::max(o.r_max > 0 ? o.r_max : o.r_max_fraction * diag, sum.r_min);
  sum.corners = corners.size();
  std::mt19937_64 rng(o.seed);

  // 1. The uniform pass: constant disk radius r_uniform (field r_uniform / eps).
  std::vector<Vec<D>> uniform;
  {
    Elements<D> u = elements;
    u.r.assign(u.points.size(), sum.r_uniform / o.epsilon);
    const std::vector<double> cr(corners.size(), sum.r_uniform / o.epsilon);
    std::vector<Vec<D>> pts;
    internal::Pool pool;
    HC_RETURN_IF_ERROR(internal::draw_pools<D>(u, corners, corner_kinds, cr, o, rng, &pts, &pool));
    for (const std::size_t i : internal::poisson_eliminate<D>(pts, pool, o.epsilon, rng)) {
      uniform.push_back(pts[i]);
    }
  }
  sum.uniform_samples = uniform.size();
  if (uniform.size() < static_cast<std::size_t>(D + 1)) {
    return invalid_argument(
        fmt::format("sampling: only {} samples at the uniform radius {}; the "
                    "shape is too small for it",
                    uniform.size(), sum.r_uniform));
  }

  // 2. The approximate medial axis, plus the corners (the axis touches the surface there).
  HC_ASSIGN_OR_RETURN(std::vector<Vec<D>> medial, medial_points(uniform, box));
  medial.insert(medial.end(), corners.begin(), corners.end());
  sum.medial_points = medial.size();
  const double r_min = sum.r_min, r_max = sum.r_max;
  HC_ASSIGN_OR_RETURN(const NearestSite<D> nearest, NearestSite<D>::build(medial));
  const internal::RadiusField<D> field =
      [&](std::span<const Vec<D>> q) -> Result<std::vector<double>> {
    HC_ASSIGN_OR_RETURN(std::vector<double> d, nearest.distance(q));
    for (double& r : d) r = std::clamp(r, r_min, r_max);
    return d;
  };

  // 3. The radius field on the elements, split to it; 4. pools; 5. elimination.
  HC_ASSIGN_OR_RETURN(elements.r, field(elements.points));
  HC_RETURN_IF_ERROR(internal::split_to_field<D>(field, kSplitFactor, kMaxSimplices, &elements));
  sum.elements = elements.simplices.size();
  HC_ASSIGN_OR_RETURN(std::vector<double> corner_r, field(corners));
  std::vector<Vec<D>> pts;
  internal::Pool pool;
  HC_RETURN_IF_ERROR(
      internal::draw_pools<D>(elements, corners, corner_kinds, corner_r, o, rng, &pts, &pool));
  sum.pool = pts.size();
  std::vector<std::size_t> kept = internal::poisson_eliminate<D>(pts, pool, o.epsilon, rng);
  if constexpr (D == 3) {
    // Along a Hilbert curve: everything built from the samples in their order (Delaunay cells,
    // balls, the crust) then keeps neighbours near in memory (regular_triangulation.h).
    std::vector<Vec<D>> at(kept.size());
    for (std::size_t k = 0; k < kept.size(); ++k) at[k] = pts[kept[k]];
    std::vector<std::size_t> sorted(kept.size());
    const std::vector<std::size_t> order = geometry::spatial_order(at);
    for (std::size_t k = 0; k < kept.size(); ++k) sorted[k] = kept[order[k]];
    kept = std::move(sorted);
  }
  Samples<D> out;
  for (const std::size_t i : kept) {
    out.points.push_back(pts[i]);
    out.radii.push_back(pool.r[i]);
    out.kinds.push_back(pool.kind[i]);
    ++sum.samples_by_kind[static_cast<std::size_t>(pool.kind[i])];
  }
  sum.samples = out.size();
  sum.time_s = seconds_since(t0);
  if (summary) *summary = sum;
  return out;
}

template <int D>
void add_extra(const ExtraFeatures<D>& extra, Elements<D>* e, std::vector<Vec<D>>* corners,
               std::vector<SampleKind>* kinds) {
  for (const auto& c : extra.corners) {
    corners->push_back(c);
    kinds->push_back(SampleKind::kFeatureCorner);
  }
  for (const auto& s : extra.segments) {
    const int a = static_cast<int>(e->points.size());
    e->points.push_back(s[0]);
    e->points.push_back(s[1]);
    e->simplices.push_back(Simplex{{a, a + 1, 0}, 2, 1, SampleKind::kFeatureEdge});
  }
}

// Angle a between the edges from p to its neighbours q and r is sharp if (pi - a) / pi > f.
bool sharp_corner(const Eigen::VectorXd& to_q, const Eigen::VectorXd& to_r, double f) {
  const double c = to_q.normalized().dot(to_r.normalized());
  const double a = std::acos(std::clamp(c, -1.0, 1.0));
  return (std::numbers::pi - a) / std::numbers::pi > f;
}

}  // namespace

Result<Samples2> sample_polygon(const Polygon2& polygon, const SamplingOptions& options,
                                const ExtraFeatures<2>& extra, SamplingSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  HC_RETURN_IF_ERROR(validate(polygon, "sample_polygon"));
  Elements<2> e;
  std::vector<Vec<2>> corners;
  std::vector<SampleKind> kinds;
  for (const auto& loop : polygon.loops) {
    const int base = static_cast<int>(e.points.size());
    const int n = static_cast<int>(loop.size());
    for (int i = 0; i < n; ++i) {
      e.points.push_back(loop[static_cast<std::size_t>(i)]);
      e.simplices.push_back(Simplex{{base + i, base + (i + 1) % n, 0}, 2, 1, SampleKind::kEdge});
      const auto& p = loop[static_cast<std::size_t>(i)];
      const auto& q = loop[static_cast<std::size_t>((i + n - 1) % n)];
      const auto& r = loop[static_cast<std::size_t>((i + 1) % n)];
      if (sharp_corner(q - p, r - p, options.sharp_fraction)) {
        corners.push_back(p);
        kinds.push_back(SampleKind::kCorner);
      }
    }
  }
  add_extra<2>(extra, &e, &corners, &kinds);
  return sample<2>(std::move(e), std::move(corners), std::move(kinds), polygon.bounding_box(),
                   options, summary);
}

Result<Samples3> sample_mesh(const TriangleMesh& mesh, const SamplingOptions& options,
                             const ExtraFeatures<3>& extra, SamplingSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  if (mesh.num_triangles() == 0) return invalid_argument("sample_mesh: the mesh has no triangles");
  // Weld by exact position, so that files storing corners per triangle (STL) still share edges.
  Elements<3> e;
  std::map<std::array<double, 3>, int> index;
  std::vector<int> id(static_cast<std::size_t>(mesh.num_vertices()));
  for (Eigen::Index v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d p = mesh.vertices.row(v).transpose();
    if (!p.allFinite())
      return invalid_argument(fmt::format("sample_mesh: vertex {} is not finite", v));
    const auto [it, added] = index.emplace(std::array<double, 3>{p.x(), p.y(), p.z()},
                                           static_cast<int>(e.points.size()));
    if (added) e.points.push_back(p);
    id[static_cast<std::size_t>(v)] = it->second;
  }
  std::unordered_map<std::uint64_t, std::vector<int>> edge_faces;
  std::vector<Eigen::Vector3d> normals;
  double area = 0.0;
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    std::array<int, 3> v{};
    for (int k = 0; k < 3; ++k) {
      const int i = mesh.triangles(t, k);
      if (i < 0 || i >= mesh.num_vertices()) {
        return invalid_argument(
            fmt::format("sample_mesh: triangle {} has index {} out of range", t, i));
      }
      v[static_cast<std::size_t>(k)] = id[static_cast<std::size_t>(i)];
    }
    const Eigen::Vector3d n =
        (e.points[static_cast<std::size_t>(v[1])] - e.points[static_cast<std::size_t>(v[0])])
            .cross(e.points[static_cast<std::size_t>(v[2])] -
                   e.points[static_cast<std::size_t>(v[0])]);
    area += 0.5 * n.norm();
    normals.push_back(n.normalized());
    e.simplices.push_back(Simplex{v, 3, 2, SampleKind::kFace});
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint32_t>(v[static_cast<std::size_t>(k)]);
      const auto b = static_cast<std::uint32_t>(v[static_cast<std::size_t>((k + 1) % 3)]);
      edge_faces[(std::uint64_t{std::min(a, b)} << 32) | std::max(a, b)].push_back(
          static_cast<int>(t));
    }
  }
  if (!(area > 0)) return invalid_argument("sample_mesh: the mesh has no area");
  // Sharp edges: used by other than two triangles, or normals turning by beta with beta/pi > f.
  std::vector<std::vector<int>> sharp_at(e.points.size());
  std::size_t sharp_edges = 0;
  for (const auto& [key, faces] : edge_faces) {
    bool sharp = faces.size() != 2;
    if (!sharp) {
      const double c = normals[static_cast<std::size_t>(faces[0])].dot(
          normals[static_cast<std::size_t>(faces[1])]);
      sharp = std::acos(std::clamp(c, -1.0, 1.0)) / std::numbers::pi > options.sharp_fraction;
    }
    if (!sharp) continue;
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffULL);
    e.simplices.push_back(Simplex{{a, b, 0}, 2, 1, SampleKind::kEdge});
    sharp_at[static_cast<std::size_t>(a)].push_back(b);
    sharp_at[static_cast<std::size_t>(b)].push_back(a);
    ++sharp_edges;
  }
  std::vector<Vec<3>> corners;
  std::vector<SampleKind> kinds;
  for (std::size_t v = 0; v < sharp_at.size(); ++v) {
    const auto& s = sharp_at[v];
    const bool corner =
        s.size() == 1 || s.size() > 2 ||
        (s.size() == 2 && sharp_corner(e.points[static_cast<std::size_t>(s[0])] - e.points[v],
                                       e.points[static_cast<std::size_t>(s[1])] - e.points[v],
                                       options.sharp_fraction));
    if (corner) {
      corners.push_back(e.points[v]);
      kinds.push_back(SampleKind::kCorner);
    }
  }
  add_extra<3>(extra, &e, &corners, &kinds);
  Eigen::AlignedBox3d box;
  for (const auto& p : e.points) box.extend(p);
  auto out = sample<3>(std::move(e), std::move(corners), std::move(kinds), box, options, summary);
  if (summary) summary->sharp_edges = sharp_edges;
  return out;
}

Result<std::vector<Eigen::Vector3d>> uniform_surface_points(const TriangleMesh& mesh,
                                                            std::size_t count, std::uint64_t seed) {
  std::vector<double> areas(static_cast<std::size_t>(mesh.num_triangles()));
  for (Eigen::Index t = 0; t < mesh.num_triangles(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.row(mesh.triangles(t, 0));
    const Eigen::Vector3d b = mesh.vertices.row(mesh.triangles(t, 1));
    const Eigen::Vector3d c = mesh.vertices.row(mesh.triangles(t, 2));
    areas[static_cast<std::size_t>(t)] = 0.5 * (b - a).cross(c - a).norm();
  }
  HC_ASSIGN_OR_RETURN(AliasTable table, AliasTable::build(areas));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3d> out(count);
  for (auto& p : out) {
    const auto t = static_cast<Eigen::Index>(table.draw(rng));
    const double s1 = std::sqrt(u(rng)), u2 = u(rng);
    p = (1 - s1) * mesh.vertices.row(mesh.triangles(t, 0)).transpose() +
        s1 * (1 - u2) * mesh.vertices.row(mesh.triangles(t, 1)).transpose() +
        s1 * u2 * mesh.vertices.row(mesh.triangles(t, 2)).transpose();
  }
  return out;
}

}  // namespace hc::abstraction
