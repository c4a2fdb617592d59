// Internal to hardcopy_abstraction: the dimension-generic machinery of adaptive Poisson-disk
// sampling (sampling.h describes the method): simplices (segments, triangles) carrying a radius
// field at their corners, splitting them to the field, pools drawn by the alias method, and the
// eliminating pass over the pools in a spatial hash.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <random>
#include <span>
#include <vector>

#include "common/status.h"
#include "fabrication/abstraction/sampling.h"

namespace hc::abstraction::internal {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;

// A segment (k = 2) or triangle (k = 3) of a pool, its corners as indices into Elements::points.
struct Simplex {
  std::array<int, 3> v{};
  int k = 2;
  std::uint8_t pool = 1;  // 1: E_p, 2: T_p
  SampleKind kind = SampleKind::kEdge;
};

template <int D>
struct Elements {
  std::vector<Vec<D>> points;
  std::vector<double> r;  // radius field at each point (>= r_min)
  std::vector<Simplex> simplices;
};

// Evaluates the radius field at a batch of points: max(r_min, distance to the medial points).
template <int D>
using RadiusField = std::function<Result<std::vector<double>>(std::span<const Vec<D>>)>;

// Splits every simplex whose longest edge exceeds split_factor times its radius (the smallest r of
// its corners) at the midpoint of that edge, evaluating the field at new points in one batch per
// round, until none is left or `max_simplices` is reached.
template <int D>
Status split_to_field(const RadiusField<D>& field, double split_factor, std::size_t max_simplices,
                      Elements<D>* elements);

struct Pool {
  std::vector<std::uint8_t> pool;  // 0: C_p, 1: E_p, 2: T_p
  std::vector<SampleKind> kind;
  std::vector<double> r;
};

// Draws pool samples on the simplices (expected count pool_density * measure / (eps r)^dim each,
// all scaled down evenly if the total exceeds max_pool), uniform within a simplex, r
// interpolated from the corners. Corners (given with their r) come first, in C_p.
template <int D>
Status draw_pools(const Elements<D>& elements, std::span<const Vec<D>> corners,
                  std::span<const SampleKind> corner_kinds, std::span<const double> corner_r,
                  const SamplingOptions& options, std::mt19937_64& rng, std::vector<Vec<D>>* points,
                  Pool* pool);

// The elimination pass: pools in order C_p, E_p, T_p, each in random order; an accepted sample
// invalidates samples of its own and later pools within eps * r. Returns the accepted indices.
template <int D>
std::vector<std::size_t> poisson_eliminate(std::span<const Vec<D>> points, const Pool& pool,
                                           double epsilon, std::mt19937_64& rng);

}  // namespace hc::abstraction::internal
