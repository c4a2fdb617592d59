// Engraving and embossing (abstraction.h, thesis Sec. 7.5): offsets of the abstraction's balls
// and a union with the input, all on unions of medial balls.
#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "common/clock.h"
#include "fabrication/abstraction/abstraction.h"

namespace hc::abstraction {
namespace {

// The balls with only the closed regions inside: `before` are the labels ahead of abstraction.
template <int D>
Balls<D> closed_region(const Balls<D>& after, const std::vector<std::uint8_t>& before) {
  Balls<D> c = after;
  for (std::size_t i = 0; i < c.size(); ++i) c.interior[i] = after.interior[i] && !before[i];
  return c;
}

template <int D>
std::size_t count_interior(const Balls<D>& b) {
  std::size_t n = 0;
  for (const auto l : b.interior) n += l;
  return n;
}

// Shared by 2-D and 3-D; Ops supplies balls / labelling / crust / union for its dimension.
template <int D, class Shape, class Ops>
Result<AbstractionResult<Shape, D>> engrave(const Shape& input, const EngraveOptions& options,
                                            const Ops& ops) {
  const auto t0 = std::chrono::steady_clock::now();
  HC_RETURN_IF_ERROR(options.validate());
  AbstractionResult<Shape, D> result;
  auto& sum = result.summary;
  HC_ASSIGN_OR_RETURN(Balls<D> balls, ops.balls(input, &sum));
  const std::vector<std::uint8_t> before = balls.interior;
  HC_ASSIGN_OR_RETURN(result.intrusions, ops.abstract(&balls, sum.sampling.r_min));
  for (std::size_t i = 0; i < balls.size(); ++i) {
    if (balls.interior[i] && !before[i])
      result.closed.push_back(balls.centres[i], balls.radii[i], true);
  }
  for (const auto& i : result.intrusions)
    (i.closed ? sum.intrusions_closed : sum.intrusions_kept)++;
  if (sum.intrusions_closed == 0) {
    // Nothing to engrave: the abstraction is the input's reconstruction.
    HC_ASSIGN_OR_RETURN(result.shape, ops.crust(balls, &sum.crust));
    sum.time_s = seconds_since(t0);
    return result;
  }
  const double d = options.depth;
  Shape other;
  if (!options.emboss) {
    // Engrave: (abstraction shrunk by d) united with the input.
    const Balls<D> shrunk = offset_balls(balls, -d);
    if (count_interior(shrunk) == 0) {
      return invalid_argument(fmt::format("engrave: the depth {} removes the whole shape", d));
    }
    CrustSummary cs;
    HC_ASSIGN_OR_RETURN(other, ops.crust(shrunk, &cs));
    OperationSummary us;
    HC_ASSIGN_OR_RETURN(result.shape, ops.unite(other, input, &us));
    sum.crust = us.crust;
  } else {
    // Emboss: the abstraction united with the closed regions grown by d.
    CrustSummary cs;
    HC_ASSIGN_OR_RETURN(Shape abstraction, ops.crust(balls, &cs));
    HC_ASSIGN_OR_RETURN(other, ops.crust(offset_balls(closed_region(balls, before), d), &cs));
    OperationSummary us;
    HC_ASSIGN_OR_RETURN(result.shape, ops.unite(abstraction, other, &us));
    sum.crust = us.crust;
  }
  sum.time_s = seconds_since(t0);
  return result;
}

struct Ops2 {
  const EngraveOptions& o;
  Result<Balls2> balls(const Polygon2& p, OperationSummary* s) const {
    return polygon_balls(p, o.abstraction.shape, s);
  }
  Result<std::vector<Intrusion>> abstract(Balls2* b, double) const {
    return abstract_balls_2d(o.abstraction, b);
  }
  Result<Polygon2> crust(const Balls2& b, CrustSummary* s) const { return power_crust_2d(b, s); }
  Result<Polygon2> unite(const Polygon2& a, const Polygon2& b, OperationSummary* s) const {
    return boolean_2d(a, b, BooleanOp::kUnion, o.abstraction.shape, s);
  }
};

struct Ops3 {
  const EngraveOptions& o;
  Result<Balls3> balls(const TriangleMesh& m, OperationSummary* s) const {
    return mesh_balls(m, o.abstraction.shape, s);
  }
  Result<std::vector<Intrusion>> abstract(Balls3* b, double r_min) const {
    return abstract_balls_3d(o.abstraction, b, r_min);
  }
  Result<TriangleMesh> crust(const Balls3& b, CrustSummary* s) const {
    return power_crust_3d(b, s);
  }
  Result<TriangleMesh> unite(const TriangleMesh& a, const TriangleMesh& b,
                             OperationSummary* s) const {
    return boolean_3d(a, b, BooleanOp::kUnion, o.abstraction.shape, s);
  }
};

}  // namespace

Status EngraveOptions::validate() const {
  HC_RETURN_IF_ERROR(abstraction.validate());
  if (!(depth > 0) || !std::isfinite(depth)) {
    return invalid_argument(fmt::format("engrave: the depth must be > 0, got {}", depth));
  }
  return {};
}

Result<AbstractionResult<Polygon2, 2>> engrave_2d(const Polygon2& polygon,
                                                  const EngraveOptions& options) {
  return engrave<2, Polygon2>(polygon, options, Ops2{options});
}

Result<AbstractionResult<TriangleMesh, 3>> engrave_3d(const TriangleMesh& mesh,
                                                      const EngraveOptions& options) {
  return engrave<3, TriangleMesh>(mesh, options, Ops3{options});
}

}  // namespace hc::abstraction
