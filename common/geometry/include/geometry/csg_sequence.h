// A sequence of boolean operations on closed triangle meshes evaluated in exact arithmetic end to
// end (CGAL corefinement on Epeck), rounded to doubles once at the end: ((base op1 m1) op2 m2) ...
// Joint hulls (a dozen solids each) and carving many hulls out of one character need this:
// rounding after every step (geometry/booleans.h) would let rounding errors accumulate and make a
// later step refuse its input.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/mesh.h"
#include "common/progress.h"
#include "common/status.h"
#include "geometry/booleans.h"

namespace hc::geometry {

struct CsgStep {
  BooleanOperation op = BooleanOperation::kUnion;
  TriangleMesh operand;
  std::string name;  // names the operand in messages
};

struct CsgSummary {
  int steps = 0;
  bool closed = false;
  // Pairs of triangles of the rounded result that intersect other than in a shared edge or
  // vertex (0 for a valid solid); only the final rounding can add them.
  std::int64_t self_intersecting_pairs_after_rounding = 0;
  double time_s = 0.0;
};

struct CsgOptions {
  // Check every operand (closed, free of self-intersections, bounding a positive volume) before
  // using it; off for operands built by construction (primitives), on for user geometry.
  bool check_operands = true;
  // Count the rounded result's self-intersections into the summary (an exact sweep).
  bool count_self_intersections = true;
  ProgressReporter* progress = nullptr;
};

// Evaluates the sequence. The base and every operand must be closed, manifold, outward oriented,
// self-intersection free (kInvalidArgument naming the operand otherwise, when checked). An empty
// result is a mesh with no triangles. kInternal when CGAL cannot make the result manifold.
Result<TriangleMesh> csg_sequence(const TriangleMesh& base, const std::vector<CsgStep>& steps,
                                  const CsgOptions& options = {}, CsgSummary* summary = nullptr);

}  // namespace hc::geometry
