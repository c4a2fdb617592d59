#include "common/bounds.h"

#include <fmt/format.h>

#include <cmath>

namespace hc {

bool Bounds::contains(double v) const {
  if (std::isnan(v)) return false;
  if (min && (min_exclusive ? !(v > *min) : !(v >= *min))) return false;
  if (max && (max_exclusive ? !(v < *max) : !(v <= *max))) return false;
  return true;
}

std::string Bounds::describe(std::string_view what) const {
  if (min && max)
    return fmt::format("{} in {}{}, {}{}", what, min_exclusive ? '(' : '[', *min, *max,
                       max_exclusive ? ')' : ']');
  if (min) return fmt::format("{} {} {}", what, min_exclusive ? ">" : ">=", *min);
  if (max) return fmt::format("{} {} {}", what, max_exclusive ? "<" : "<=", *max);
  return std::string(what);
}

}  // namespace hc
