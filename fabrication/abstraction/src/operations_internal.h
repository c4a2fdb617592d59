// Internal to hardcopy_abstraction: the rules a boolean applies to samples and balls.
#pragma once

#include "fabrication/abstraction/operations.h"

namespace hc::abstraction::internal {

// Whether a sample of the first (from_a) or second input stays: it lies on the result's boundary.
inline bool keep_sample(BooleanOp op, bool from_a, bool inside_other) {
  switch (op) {
    case BooleanOp::kUnion:
      return !inside_other;
    case BooleanOp::kIntersection:
      return inside_other;
    case BooleanOp::kDifference:
      return from_a ? !inside_other : inside_other;
  }
  return false;
}

// Whether a point inside a (in_a) and/or b (in_b) is inside the result.
inline bool in_result(BooleanOp op, bool in_a, bool in_b) {
  switch (op) {
    case BooleanOp::kUnion:
      return in_a || in_b;
    case BooleanOp::kIntersection:
      return in_a && in_b;
    case BooleanOp::kDifference:
      return in_a && !in_b;
  }
  return false;
}

inline bool is_feature(SampleKind k) {
  return k == SampleKind::kFeatureCorner || k == SampleKind::kFeatureEdge;
}

}  // namespace hc::abstraction::internal
