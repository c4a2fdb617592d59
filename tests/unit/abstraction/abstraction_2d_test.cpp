// 2-D scale-aware fabrication: sampling, power crust, offsets, booleans, abstraction (thesis
// Sec. 7.4-7.5 in the plane). Expected values are analytic areas of the generated shapes.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "fabrication/abstraction/abstraction.h"
#include "fabrication/abstraction/operations.h"
#include "fabrication/abstraction/sampling.h"
#include "shapes_2d.h"

namespace hc::abstraction {
namespace {

using testing::circle;
using testing::comb;
using testing::rectangle;
using testing::star;

TEST(AliasTable, DrawsInProportionToTheWeights) {
  const std::vector<double> w = {1, 2, 3, 4, 0};
  auto t = AliasTable::build(w);
  ASSERT_TRUE(t.ok()) << t.status().to_string();
  std::mt19937_64 rng(7);
  std::vector<int> count(w.size(), 0);
  constexpr int kDraws = 200'000;
  for (int i = 0; i < kDraws; ++i) ++count[t->draw(rng)];
  // Binomial standard deviation sqrt(n p (1 - p)) / n <= 0.0011; 5 sigma.
  for (std::size_t i = 0; i < w.size(); ++i)
    EXPECT_NEAR(count[i] / double(kDraws), w[i] / 10.0, 0.0055);
  EXPECT_EQ(count[4], 0);
  EXPECT_FALSE(AliasTable::build(std::vector<double>{0, 0}).ok());
  EXPECT_FALSE(AliasTable::build(std::vector<double>{1, -1}).ok());
}

TEST(PoissonSampling, SquareKeepsCornersAndTheDiskProperty) {
  SamplingOptions o;
  SamplingSummary s;
  auto samples = sample_polygon(rectangle(0, 0, 1, 1), o, {}, &s);
  ASSERT_TRUE(samples.ok()) << samples.status().to_string();
  EXPECT_EQ(s.corners, 4u);
  EXPECT_EQ(s.samples_by_kind[0], 4u);  // every corner is accepted (corners are far apart)
  for (std::size_t i = 0; i < samples->size(); ++i) {
    const auto& p = samples->points[i];
    const double to_edge =
        std::min({std::abs(p.x()), std::abs(p.y()), std::abs(1 - p.x()), std::abs(1 - p.y())});
    EXPECT_LT(to_edge, 1e-12);
    EXPECT_GE(samples->radii[i], s.r_min * (1 - 1e-12));
  }
  // Disk property: no two samples closer than eps times the smaller radius (small pool-level
  // slack from the skipped hash levels is not expected on a square).
  std::size_t violations = 0;
  for (std::size_t i = 0; i < samples->size(); ++i)
    for (std::size_t j = i + 1; j < samples->size(); ++j)
      if ((samples->points[i] - samples->points[j]).norm() <
          o.epsilon * std::min(samples->radii[i], samples->radii[j]) * 0.999)
        ++violations;
  EXPECT_EQ(violations, 0u);
  // Adaptive: denser near the corners (r small) than mid-edge (r ~ half the side).
  EXPECT_GT(s.samples, 60u);
  EXPECT_LT(s.samples, 5000u);
}

TEST(PowerCrust2d, ReconstructsAStarWithinTheSamplingTolerance) {
  // Star, 5 tips: the area of the decagon with alternating radii 1 and 0.4 is
  // 10 * 1/2 * 1 * 0.4 * sin(36 deg).
  const Polygon2 s = star(5, 1.0, 0.4);
  const double expected = 10 * 0.5 * 0.4 * std::sin(std::numbers::pi / 5);
  ShapeOptions o;
  OperationSummary sum;
  auto out = reconstruct_2d(s, o, &sum);
  ASSERT_TRUE(out.ok()) << out.status().to_string();
  EXPECT_EQ(out->loops.size(), 1u);
  EXPECT_NEAR(area(*out), expected, 0.002 * expected);
  // Every crust vertex lies within a few r_min of the outline (the samples are on it, the power
  // vertices between them).
  const double r_min = sum.sampling.r_min;
  for (const auto& p : out->loops[0]) {
    double best = 1e9;
    const auto& l = s.loops[0];
    for (std::size_t i = 0; i < l.size(); ++i) {
      const Eigen::Vector2d a = l[i], b = l[(i + 1) % l.size()];
      const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * (b - a) - p).norm());
    }
    EXPECT_LT(best, 5 * r_min);
  }
}

TEST(Offset2d, CircleRadiusChangesByTheDistance) {
  // 256-gon of radius 1: area within 0.01 % of pi; offsets by +-0.1 give circles of 1.1 / 0.9.
  const Polygon2 c = circle(0, 0, 1.0, 256);
  ShapeOptions o;
  for (const double d : {0.1, -0.1}) {
    auto out = offset_2d(c, d, o);
    ASSERT_TRUE(out.ok()) << out.status().to_string();
    const double r = 1.0 + d;
    EXPECT_NEAR(area(*out), std::numbers::pi * r * r, 0.005 * std::numbers::pi * r * r) << d;
  }
}

TEST(Boolean2d, OverlappingSquaresMatchTheAnalyticAreas) {
  // [0,2]^2 and [1,3]x[0.5,2.5]: overlap 1 x 1.5 = 1.5; union 4 + 4 - 1.5; difference 4 - 1.5.
  const Polygon2 a = rectangle(0, 0, 2, 2), b = rectangle(1, 0.5, 3, 2.5);
  ShapeOptions o;
  const std::pair<BooleanOp, double> cases[] = {
      {BooleanOp::kUnion, 6.5}, {BooleanOp::kDifference, 2.5}, {BooleanOp::kIntersection, 1.5}};
  for (const auto& [op, expected] : cases) {
    OperationSummary sum;
    auto out = boolean_2d(a, b, op, o, &sum);
    ASSERT_TRUE(out.ok()) << to_string(op) << ": " << out.status().to_string();
    EXPECT_NEAR(area(*out), expected, 0.005 * expected) << to_string(op);
    EXPECT_EQ(sum.intersection_points, 2u);
  }
  // Touching squares (a shared edge): their union is the 4 x 2 rectangle.
  auto touching = boolean_2d(a, rectangle(2, 0, 4, 2), BooleanOp::kUnion, o);
  ASSERT_TRUE(touching.ok()) << touching.status().to_string();
  EXPECT_EQ(touching->loops.size(), 1u);
  EXPECT_NEAR(area(*touching), 8.0, 0.005 * 8.0);
}

TEST(Abstraction2d, CombClosesExactlyTheNarrowDeepSlots) {
  // Feature size F = 1. Slots of widths 0.5, 1, 2 (x F) with depth / width 0.25, 1, 4, tau 0.5:
  // only the 0.5-wide slots with ratio 1 and 4 are narrow and deep.
  const double f = 1.0;
  std::vector<testing::Slot> slots;
  double closed_area = 0.0;
  for (const double w : {0.5, 1.0, 2.0}) {
    for (const double ratio : {0.25, 1.0, 4.0}) {
      slots.push_back({w * f, ratio * w * f});
      if (w < 1.0 && ratio > 0.5) closed_area += w * ratio * w;
    }
  }
  const Polygon2 shape = comb(slots, 2.0, 10.0);
  AbstractionOptions o;
  o.feature_size = f;
  auto out = abstract_2d(shape, o);
  ASSERT_TRUE(out.ok()) << out.status().to_string();
  EXPECT_EQ(out->summary.intrusions_closed, 2u);
  // The closed slots are filled up to the rolling ball's lid (a dip of
  // rho - sqrt(rho^2 - w^2 / 4) = 0.06 at most); the rest stays within the sampling tolerance.
  const double tolerance = 0.06 * 0.5 * 2 + 0.003 * area(shape);
  EXPECT_NEAR(area(out->shape), area(shape) + closed_area, tolerance);
}

TEST(Abstraction2d, RejectsNonPositiveFeatureSize) {
  AbstractionOptions o;
  o.feature_size = 0.0;
  const auto out = abstract_2d(rectangle(0, 0, 1, 1), o);
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("feature size"), std::string::npos);
}

}  // namespace
}  // namespace hc::abstraction
