// Template definitions of SpatialHash (included by sampling.h).
#pragma once

#include <algorithm>
#include <cmath>

namespace hc::abstraction {

template <int D>
SpatialHash<D>::SpatialHash(std::span<const Vec> points, std::span<const int> levels,
                            double base_cell)
    : base_cell_(base_cell) {
  std::size_t table = 16;
  while (table < 2 * points.size()) table *= 2;
  start_.assign(table + 1, 0);
  std::vector<std::uint64_t> slots(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double h = std::ldexp(base_cell_, levels[i]);
    const Eigen::Matrix<std::int64_t, D, 1> cell =
        (points[i] / h).array().floor().template cast<std::int64_t>();
    slots[i] = slot(cell, levels[i]);
    ++start_[slots[i] + 1];
  }
  for (std::size_t h = 0; h < table; ++h) start_[h + 1] += start_[h];
  items_.resize(points.size());
  std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    items_[fill[slots[i]]++] = static_cast<std::uint32_t>(i);
  }
  item_points_.resize(points.size());
  item_levels_.resize(points.size());
  for (std::size_t k = 0; k < items_.size(); ++k) {
    item_points_[k] = points[items_[k]];
    item_levels_[k] = levels[items_[k]];
  }
  levels_present_.assign(levels.begin(), levels.end());
  std::sort(levels_present_.begin(), levels_present_.end());
  levels_present_.erase(std::unique(levels_present_.begin(), levels_present_.end()),
                        levels_present_.end());
}

template <int D>
std::uint64_t SpatialHash<D>::slot(const Eigen::Matrix<std::int64_t, D, 1>& cell, int level) const {
  constexpr std::uint64_t kPrimes[4] = {73856093ULL, 19349663ULL, 83492791ULL, 2654435761ULL};
  std::uint64_t h = static_cast<std::uint64_t>(level) * kPrimes[3];
  for (int k = 0; k < D; ++k) h ^= static_cast<std::uint64_t>(cell[k]) * kPrimes[k];
  h ^= h >> 29;
  return h & (start_.size() - 2);
}

template <int D>
template <class Fn>
void SpatialHash<D>::for_each_candidate(const Vec& centre, double radius, Fn&& fn) const {
  constexpr double kMaxCellsPerRadius = 4.0;
  for (const int level : levels_present_) {
    const double h = std::ldexp(base_cell_, level);
    if (radius > kMaxCellsPerRadius * h) continue;
    const Eigen::Matrix<std::int64_t, D, 1> lo =
        ((centre.array() - radius) / h).floor().template cast<std::int64_t>();
    const Eigen::Matrix<std::int64_t, D, 1> hi =
        ((centre.array() + radius) / h).floor().template cast<std::int64_t>();
    Eigen::Matrix<std::int64_t, D, 1> c = lo;
    while (true) {
      const std::uint64_t s = slot(c, level);
      for (std::uint32_t k = start_[s]; k < start_[s + 1]; ++k) {
        if (item_levels_[k] == level) fn(static_cast<std::size_t>(items_[k]), item_points_[k]);
      }
      int axis = 0;
      while (axis < D && ++c[axis] > hi[axis]) {
        c[axis] = lo[axis];
        ++axis;
      }
      if (axis == D) break;
    }
  }
}

}  // namespace hc::abstraction
