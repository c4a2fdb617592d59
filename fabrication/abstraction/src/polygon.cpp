#include "fabrication/abstraction/polygon.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace hc::abstraction {

std::size_t Polygon2::num_points() const {
  std::size_t n = 0;
  for (const auto& l : loops) n += l.size();
  return n;
}

Eigen::AlignedBox2d Polygon2::bounding_box() const {
  Eigen::AlignedBox2d box;
  for (const auto& l : loops)
    for (const auto& p : l) box.extend(p);
  return box;
}

double signed_area(const Loop2& loop) {
  double a = 0.0;
  for (std::size_t i = 0, n = loop.size(); i < n; ++i) {
    const auto& p = loop[i];
    const auto& q = loop[(i + 1) % n];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * a;
}

namespace {

bool inside_loop(const Loop2& loop, const Eigen::Vector2d& p) {
  bool in = false;
  for (std::size_t i = 0, n = loop.size(), j = n - 1; i < n; j = i++) {
    const auto& a = loop[i];
    const auto& b = loop[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      in = !in;
    }
  }
  return in;
}

// Number of other loops containing loop i (its first point): its nesting depth.
int depth(const Polygon2& polygon, std::size_t i) {
  int d = 0;
  for (std::size_t j = 0; j < polygon.loops.size(); ++j) {
    if (j != i && inside_loop(polygon.loops[j], polygon.loops[i].front())) ++d;
  }
  return d;
}

}  // namespace

double area(const Polygon2& polygon) {
  double a = 0.0;
  for (std::size_t i = 0; i < polygon.loops.size(); ++i) {
    const double s = std::abs(signed_area(polygon.loops[i]));
    a += depth(polygon, i) % 2 == 0 ? s : -s;
  }
  return a;
}

bool inside(const Polygon2& polygon, const Eigen::Vector2d& p) {
  bool in = false;
  for (const auto& l : polygon.loops) in ^= inside_loop(l, p);
  return in;
}

Status validate(const Polygon2& polygon, std::string_view what) {
  if (polygon.loops.empty()) return invalid_argument(fmt::format("{}: no closed paths", what));
  for (std::size_t i = 0; i < polygon.loops.size(); ++i) {
    const auto& l = polygon.loops[i];
    if (l.size() < 3) {
      return invalid_argument(fmt::format(
          "{}: path {} has {} points; a closed path needs at least 3", what, i, l.size()));
    }
    for (std::size_t k = 0; k < l.size(); ++k) {
      if (!l[k].allFinite()) {
        return invalid_argument(fmt::format("{}: path {} point {} is not finite", what, i, k));
      }
      if (l[k] == l[(k + 1) % l.size()]) {
        return invalid_argument(
            fmt::format("{}: path {} repeats point {} (zero-length segment)", what, i, k));
      }
    }
    if (signed_area(l) == 0.0) {
      return invalid_argument(fmt::format("{}: path {} encloses no area", what, i));
    }
  }
  return {};
}

void orient(Polygon2* polygon) {
  std::vector<int> depths(polygon->loops.size());
  for (std::size_t i = 0; i < polygon->loops.size(); ++i) depths[i] = depth(*polygon, i);
  for (std::size_t i = 0; i < polygon->loops.size(); ++i) {
    auto& l = polygon->loops[i];
    const bool ccw = signed_area(l) > 0;
    if (ccw != (depths[i] % 2 == 0)) std::reverse(l.begin(), l.end());
  }
}

}  // namespace hc::abstraction
