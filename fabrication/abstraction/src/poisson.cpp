#include "poisson.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

namespace hc::abstraction::internal {
namespace {

template <int D>
double measure(const Elements<D>& e, const Simplex& s) {
  const Vec<D>& a = e.points[static_cast<std::size_t>(s.v[0])];
  const Vec<D>& b = e.points[static_cast<std::size_t>(s.v[1])];
  if (s.k == 2) return (b - a).norm();
  const Vec<D>& c = e.points[static_cast<std::size_t>(s.v[2])];
  if constexpr (D == 3) {
    return 0.5 * (b - a).cross(c - a).norm();
  } else {
    const Vec<D> u = b - a, w = c - a;
    return 0.5 * std::abs(u.x() * w.y() - u.y() * w.x());
  }
}

template <int D>
double radius_of(const Elements<D>& e, const Simplex& s) {
  double r = e.r[static_cast<std::size_t>(s.v[0])];
  for (int i = 1; i < s.k; ++i)
    r = std::min(r, e.r[static_cast<std::size_t>(s.v[static_cast<std::size_t>(i)])]);
  return r;
}

// Index (0..k-1) of the longest edge's first corner (edge i runs from corner i to i + 1) and its
// squared length.
template <int D>
std::pair<int, double> longest_edge(const Elements<D>& e, const Simplex& s) {
  if (s.k == 2) {
    return {
        0, (e.points[static_cast<std::size_t>(s.v[1])] - e.points[static_cast<std::size_t>(s.v[0])])
               .squaredNorm()};
  }
  int best = 0;
  double len = -1.0;
  for (int i = 0; i < 3; ++i) {
    const double l =
        (e.points[static_cast<std::size_t>(s.v[static_cast<std::size_t>((i + 1) % 3)])] -
         e.points[static_cast<std::size_t>(s.v[static_cast<std::size_t>(i)])])
            .squaredNorm();
    if (l > len) {
      len = l;
      best = i;
    }
  }
  return {best, len};
}

}  // namespace

template <int D>
Status split_to_field(const RadiusField<D>& field, double split_factor, std::size_t max_simplices,
                      Elements<D>* elements) {
  auto& e = *elements;
  std::vector<std::size_t> todo(e.simplices.size());
  std::iota(todo.begin(), todo.end(), 0);
  while (!todo.empty()) {
    std::vector<std::size_t> split;
    for (const std::size_t i : todo) {
      const auto [edge, len2] = longest_edge(e, e.simplices[i]);
      (void)edge;
      const double r = split_factor * radius_of(e, e.simplices[i]);
      if (len2 > r * r) split.push_back(i);
    }
    if (split.empty() || e.simplices.size() + split.size() > max_simplices) break;
    std::vector<Vec<D>> mids;
    mids.reserve(split.size());
    for (const std::size_t i : split) {
      const Simplex& s = e.simplices[i];
      const int a = longest_edge(e, s).first;
      const int b = (a + 1) % s.k;
      mids.push_back(0.5 * (e.points[static_cast<std::size_t>(s.v[static_cast<std::size_t>(a)])] +
                            e.points[static_cast<std::size_t>(s.v[static_cast<std::size_t>(b)])]));
    }
    HC_ASSIGN_OR_RETURN(std::vector<double> r, field(mids));
    todo.clear();
    for (std::size_t m = 0; m < split.size(); ++m) {
      const std::size_t i = split[m];
      const int id = static_cast<int>(e.points.size());
      e.points.push_back(mids[m]);
      e.r.push_back(r[m]);
      Simplex s = e.simplices[i];
      const int a = longest_edge(e, s).first;
      const int b = (a + 1) % s.k;
      Simplex first = s;
      Simplex second = s;
      first.v[static_cast<std::size_t>(b)] = id;   // a .. mid (.. c)
      second.v[static_cast<std::size_t>(a)] = id;  // mid .. b (.. c)
      e.simplices[i] = first;
      todo.push_back(i);
      todo.push_back(e.simplices.size());
      e.simplices.push_back(second);
    }
  }
  return {};
}

template <int D>
Status draw_pools(const Elements<D>& elements, std::span<const Vec<D>> corners,
                  std::span<const SampleKind> corner_kinds, std::span<const double> corner_r,
                  const SamplingOptions& options, std::mt19937_64& rng, std::vector<Vec<D>>* points,
                  Pool* pool) {
  points->assign(corners.begin(), corners.end());
  pool->pool.assign(corners.size(), 0);
  pool->kind.assign(corner_kinds.begin(), corner_kinds.end());
  pool->r.assign(corner_r.begin(), corner_r.end());
  const auto& e = elements;
  std::vector<double> expected(e.simplices.size());
  double total = 0.0;
  for (std::size_t i = 0; i < e.simplices.size(); ++i) {
    const Simplex& s = e.simplices[i];
    const double h = options.epsilon * radius_of(e, s);
    expected[i] = options.pool_density * measure(e, s) / (s.k == 2 ? h : h * h);
    total += expected[i];
  }
  if (total <= 0.0) return {};
  const double scale = std::min(1.0, static_cast<double>(options.max_pool) / total);
  // The pools' sizes first, so the outputs are sized once (growing by doubling would touch twice
  // the memory).
  std::array<double, 3> sum{};
  for (std::size_t i = 0; i < expected.size(); ++i) sum[e.simplices[i].pool] += expected[i];
  std::size_t drawn = points->size();
  for (const double s : sum) drawn += static_cast<std::size_t>(std::ceil(s * scale));
  points->reserve(drawn);
  pool->pool.reserve(drawn);
  pool->kind.reserve(drawn);
  pool->r.reserve(drawn);
  // One alias table per pool (E_p and T_p are drawn separately so both keep their density).
  for (const std::uint8_t which : {std::uint8_t{1}, std::uint8_t{2}}) {
    if (sum[which] <= 0.0) continue;
    std::vector<double> w(expected.size(), 0.0);
    for (std::size_t i = 0; i < w.size(); ++i) {
      if (e.simplices[i].pool == which) w[i] = expected[i];
    }
    const auto count = static_cast<std::size_t>(std::ceil(sum[which] * scale));
    HC_ASSIGN_OR_RETURN(AliasTable table, AliasTable::build(w));
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (std::size_t n = 0; n < count; ++n) {
      const Simplex& s = e.simplices[table.draw(rng)];
      const auto ia = static_cast<std::size_t>(s.v[0]);
      const auto ib = static_cast<std::size_t>(s.v[1]);
      Vec<D> p;
      double r = 0.0;
      if (s.k == 2) {
        const double t = u(rng);
        p = e.points[ia] + t * (e.points[ib] - e.points[ia]);
        r = (1 - t) * e.r[ia] + t * e.r[ib];
      } else {
        // Thesis: (1 - sqrt(U1)) a + sqrt(U1)(1 - U2) b + sqrt(U1) U2 c.
        const auto ic = static_cast<std::size_t>(s.v[2]);
        const double s1 = std::sqrt(u(rng));
        const double u2 = u(rng);
        const double wa = 1 - s1, wb = s1 * (1 - u2), wc = s1 * u2;
        p = wa * e.points[ia] + wb * e.points[ib] + wc * e.points[ic];
        r = wa * e.r[ia] + wb * e.r[ib] + wc * e.r[ic];
      }
      points->push_back(p);
      pool->pool.push_back(which);
      pool->kind.push_back(s.kind);
      pool->r.push_back(r);
    }
  }
  return {};
}

template <int D>
std::vector<std::size_t> poisson_eliminate(std::span<const Vec<D>> points, const Pool& pool,
                                           double epsilon, std::mt19937_64& rng) {
  const std::size_t n = points.size();
  std::vector<std::size_t> accepted;
  if (n == 0) return accepted;
  double rho_min = std::numeric_limits<double>::infinity();
  for (const double r : pool.r) rho_min = std::min(rho_min, epsilon * r);
  std::vector<int> levels(n);
  for (std::size_t i = 0; i < n; ++i) {
    levels[i] = static_cast<int>(std::floor(std::log2(epsilon * pool.r[i] / rho_min)));
  }
  const SpatialHash<D> hash(points, levels, rho_min);
  std::vector<std::uint8_t> alive(n, 1);
  for (std::uint8_t which = 0; which <= 2; ++which) {
    std::vector<std::size_t> order;
    for (std::size_t i = 0; i < n; ++i) {
      if (pool.pool[i] == which) order.push_back(i);
    }
    std::shuffle(order.begin(), order.end(), rng);
    for (const std::size_t i : order) {
      if (!alive[i]) continue;
      accepted.push_back(i);
      const double rho = epsilon * pool.r[i];
      const double rho2 = rho * rho;
      hash.for_each_candidate(points[i], rho, [&](std::size_t j, const Vec<D>& p) {
        if ((p - points[i]).squaredNorm() < rho2 && pool.pool[j] >= which) alive[j] = 0;
      });
    }
  }
  return accepted;
}

template Status split_to_field<2>(const RadiusField<2>&, double, std::size_t, Elements<2>*);
template Status split_to_field<3>(const RadiusField<3>&, double, std::size_t, Elements<3>*);
template Status draw_pools<2>(const Elements<2>&, std::span<const Vec<2>>,
                              std::span<const SampleKind>, std::span<const double>,
                              const SamplingOptions&, std::mt19937_64&, std::vector<Vec<2>>*,
                              Pool*);
template Status draw_pools<3>(const Elements<3>&, std::span<const Vec<3>>,
                              std::span<const SampleKind>, std::span<const double>,
                              const SamplingOptions&, std::mt19937_64&, std::vector<Vec<3>>*,
                              Pool*);
template std::vector<std::size_t> poisson_eliminate<2>(std::span<const Vec<2>>, const Pool&, double,
                                                       std::mt19937_64&);
template std::vector<std::size_t> poisson_eliminate<3>(std::span<const Vec<3>>, const Pool&, double,
                                                       std::mt19937_64&);

}  // namespace hc::abstraction::internal
