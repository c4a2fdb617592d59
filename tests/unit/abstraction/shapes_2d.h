// Generated planar shapes for the abstraction tests, their facts derived in the comments.
#pragma once

#include <cmath>
#include <numbers>
#include <vector>

#include "fabrication/abstraction/polygon.h"

namespace hc::testing {

inline abstraction::Polygon2 rectangle(double x0, double y0, double x1, double y1) {
  return {{{{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}}}};
}

// Regular n-gon inscribed in a circle of radius r: area n/2 r^2 sin(2 pi / n).
inline abstraction::Polygon2 circle(double cx, double cy, double r, int n) {
  abstraction::Loop2 l;
  for (int i = 0; i < n; ++i) {
    const double t = 2 * std::numbers::pi * i / n;
    l.push_back({cx + r * std::cos(t), cy + r * std::sin(t)});
  }
  return {{l}};
}

// A star with `points` tips (radius r_out) and notches (radius r_in), counter-clockwise.
inline abstraction::Polygon2 star(int points, double r_out, double r_in) {
  abstraction::Loop2 l;
  for (int i = 0; i < 2 * points; ++i) {
    const double t = std::numbers::pi * i / points;
    const double r = i % 2 == 0 ? r_out : r_in;
    l.push_back({r * std::cos(t), r * std::sin(t)});
  }
  return {{l}};
}

struct Slot {
  double width, depth;
};

// A comb: a base block [0, length] x [0, height] with rectangular slots cut down from the top
// edge, each `gap` apart (slot i starts at x = gap + sum of (width + gap) before it). The area is
// length * height minus the slots' width * depth.
inline abstraction::Polygon2 comb(const std::vector<Slot>& slots, double gap, double height) {
  abstraction::Loop2 l;
  double x = 0.0;
  l.push_back({0, 0});
  double length = gap;
  for (const auto& s : slots) length += s.width + gap;
  l.push_back({length, 0});
  l.push_back({length, height});
  x = length;
  for (auto it = slots.rbegin(); it != slots.rend(); ++it) {
    x -= gap;
    l.push_back({x, height});
    l.push_back({x, height - it->depth});
    x -= it->width;
    l.push_back({x, height - it->depth});
    l.push_back({x, height});
  }
  l.push_back({0, height});
  return {{l}};
}

}  // namespace hc::testing
