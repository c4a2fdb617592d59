// Limits a number read from a file must respect (common/config.h for YAML, common/json_reader.h
// for JSON); messages name them ("expected a number in (0, 1]").
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace hc {

struct Bounds {
  std::optional<double> min;
  std::optional<double> max;
  bool min_exclusive = false;
  bool max_exclusive = false;

  static Bounds positive() { return {0.0, std::nullopt, true, false}; }            // > 0
  static Bounds non_negative() { return {0.0, std::nullopt, false, false}; }       // >= 0
  static Bounds at_least(double v) { return {v, std::nullopt, false, false}; }     // >= v
  static Bounds greater_than(double v) { return {v, std::nullopt, true, false}; }  // > v
  static Bounds at_most(double v) { return {std::nullopt, v, false, false}; }      // <= v
  static Bounds between(double lo, double hi) { return {lo, hi, false, false}; }   // [lo, hi]

  // True when `v` satisfies every limit; NaN never does.
  bool contains(double v) const;
  // "a number > 0", "an integer in [1, 16]" (`what` is "a number" or "an integer").
  std::string describe(std::string_view what) const;
};

}  // namespace hc
