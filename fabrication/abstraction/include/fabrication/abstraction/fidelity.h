// How far a result departs from its input: the two-sided Hausdorff distance, estimated on dense
// uniform samples of both surfaces (alias method, geometry::MeshDistance's AABB tree for the
// distances; in 2-D samples of both outlines against the other's segments), leaving out the
// regions an abstraction changed on purpose: points within `margin` of a closed ball.
#pragma once

#include "common/mesh.h"
#include "common/status.h"
#include "fabrication/abstraction/medial_balls.h"
#include "fabrication/abstraction/polygon.h"

namespace hc::abstraction {

struct HausdorffOptions {
  std::size_t samples = 20'000;  // per surface
  double margin = 0.0;           // points within this of an excluded ball are left out
  std::uint64_t seed = 3;
};

struct Hausdorff {
  double a_to_b = 0.0;  // largest distance from a sample of a to b
  double b_to_a = 0.0;
  double symmetric() const { return std::max(a_to_b, b_to_a); }
  std::size_t excluded = 0;  // samples left out
};

Result<Hausdorff> hausdorff_3d(const TriangleMesh& a, const TriangleMesh& b,
                               const Balls3& excluded = {}, const HausdorffOptions& options = {});
Result<Hausdorff> hausdorff_2d(const Polygon2& a, const Polygon2& b, const Balls2& excluded = {},
                               const HausdorffOptions& options = {});

}  // namespace hc::abstraction
