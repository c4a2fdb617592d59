// hardcopy_geometry: corefinement booleans, alpha wrap and distance queries against analytic
// volumes and distances of boxes and spheres.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "geometry/alpha_wrap.h"
#include "geometry/booleans.h"
#include "geometry/mesh_distance.h"
#include "geometry/mesh_ops.h"
#include "synthetic_meshes.h"

namespace hc::geometry {
namespace {

using hc::testing::box;
using hc::testing::icosphere;
using hc::testing::signed_volume;

std::int64_t self_intersections(const TriangleMesh& m) {
  SelfIntersectionQuery query;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    query.triangles.push_back(static_cast<std::int32_t>(t));
  }
  query.is_polygon_mesh = true;
  auto count = count_self_intersecting_pairs(m, query);
  EXPECT_TRUE(count.ok()) << count.status().message();
  return count.ok() ? count->pairs : -1;
}

TEST(Booleans, OverlappingBoxesMatchTheirAnalyticVolumes) {
  // [0,2]^3 and [1,3]x[1,3]x[1,3]: volumes 8 and 8 overlapping in a unit cube (exact: the
  // corefinement's new vertices lie on the boxes' faces, so the rounded result is exact too).
  const TriangleMesh a = box({0, 0, 0}, {2, 2, 2});
  const TriangleMesh b = box({1, 1, 1}, {3, 3, 3});
  BooleanSummary summary;
  auto u = corefine_boolean(a, b, BooleanOperation::kUnion, &summary);
  ASSERT_TRUE(u.ok()) << u.status().message();
  EXPECT_NEAR(signed_volume(*u), 15.0, 1e-12);
  EXPECT_TRUE(summary.closed);
  EXPECT_EQ(summary.self_intersecting_pairs_after_rounding, 0);
  auto d = corefine_boolean(a, b, BooleanOperation::kDifference);
  ASSERT_TRUE(d.ok()) << d.status().message();
  EXPECT_NEAR(signed_volume(*d), 7.0, 1e-12);
  auto i = corefine_boolean(a, b, BooleanOperation::kIntersection);
  ASSERT_TRUE(i.ok()) << i.status().message();
  EXPECT_NEAR(signed_volume(*i), 1.0, 1e-12);
}

TEST(Booleans, CoplanarTouchingBoxesUniteIntoOneSolid) {
  // Two unit cubes sharing the face x = 1 (coplanar faces, shared edges): union volume 2, no
  // self-intersections; intersecting them gives nothing of volume.
  const TriangleMesh a = box({0, 0, 0}, {1, 1, 1});
  const TriangleMesh b = box({1, 0, 0}, {2, 1, 1});
  BooleanSummary summary;
  auto u = corefine_boolean(a, b, BooleanOperation::kUnion, &summary);
  ASSERT_TRUE(u.ok()) << u.status().message();
  EXPECT_NEAR(signed_volume(*u), 2.0, 1e-12);
  EXPECT_TRUE(summary.closed);
  EXPECT_EQ(self_intersections(*u), 0);
}

TEST(Booleans, SpheresOverlapAsTheLensFormulaSays) {
  // Two spheres of radius r whose centres are d apart overlap in a lens of volume
  // pi (4r + d)(2r - d)^2 / 12 (the sphere-sphere intersection formula). The icospheres are
  // inscribed, so compare with the same formula applied to the polyhedra's own volumes through
  // inclusion-exclusion: V(a u b) + V(a n b) = V(a) + V(b) exactly, and the lens within 2 %.
  const double r = 1.0;
  const double dist = 1.0;
  const TriangleMesh a = icosphere({0, 0, 0}, r, 4);
  const TriangleMesh b = icosphere({dist, 0.1, 0.05}, r, 4);
  auto u = corefine_boolean(a, b, BooleanOperation::kUnion);
  auto i = corefine_boolean(a, b, BooleanOperation::kIntersection);
  ASSERT_TRUE(u.ok() && i.ok());
  EXPECT_NEAR(signed_volume(*u) + signed_volume(*i), signed_volume(a) + signed_volume(b), 1e-9);
  const double d = std::sqrt(dist * dist + 0.1 * 0.1 + 0.05 * 0.05);
  const double lens = std::numbers::pi * (4 * r + d) * (2 * r - d) * (2 * r - d) / 12.0;
  EXPECT_NEAR(signed_volume(*i), lens, 0.02 * lens);
  EXPECT_EQ(self_intersections(*u), 0);
  EXPECT_EQ(self_intersections(*i), 0);
}

TEST(Booleans, RejectsOpenAndInvertedInputsByName) {
  TriangleMesh open = box({0, 0, 0}, {1, 1, 1});
  open.triangles.conservativeResize(11, 3);
  auto r = corefine_boolean(box({0, 0, 0}, {1, 1, 1}), open, BooleanOperation::kUnion);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("second mesh is not closed"), std::string::npos)
      << r.status().message();
  TriangleMesh inverted = box({0, 0, 0}, {1, 1, 1});
  for (Eigen::Index t = 0; t < inverted.num_triangles(); ++t) hc::testing::flip(&inverted, t);
  r = corefine_boolean(inverted, box({0, 0, 0}, {1, 1, 1}), BooleanOperation::kUnion);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("first mesh is inward oriented"), std::string::npos)
      << r.status().message();
  EXPECT_FALSE(parse_boolean_operation("xor").ok());
  EXPECT_EQ(*parse_boolean_operation("difference"), BooleanOperation::kDifference);
}

TEST(AlphaWrap, ClosesAnOpenBoxOnlyWhenAlphaExceedsItsOpening) {
  // A unit box missing its top. With alpha (the radius of the ball that carves the wrap) above
  // the 1 x 1 opening, the wrap closes over it: it encloses the box (volume > 1) and its vertices
  // lie on the offset surface, so it is inside the box grown by the offset on every side. With
  // alpha well below the opening, the ball enters the box and the wrap is a shell of thickness
  // about 2 x offset around the five walls: 5 x 2 x 0.01 = 0.1 plus its rims.
  TriangleMesh open = box({0, 0, 0}, {1, 1, 1});
  open.triangles.row(2) = open.triangles.row(11);
  open.triangles.row(3) = open.triangles.row(10);
  open.triangles.conservativeResize(10, 3);
  AlphaWrapOptions options;
  options.alpha = 1.5;
  options.offset = 0.01;
  auto wrap = alpha_wrap(open, options);
  ASSERT_TRUE(wrap.ok()) << wrap.status().message();
  EXPECT_GT(signed_volume(*wrap), 1.0);
  EXPECT_LT(signed_volume(*wrap), std::pow(1.0 + 2 * options.offset, 3));
  EXPECT_EQ(self_intersections(*wrap), 0);
  options.alpha = 0.1;
  wrap = alpha_wrap(open, options);
  ASSERT_TRUE(wrap.ok()) << wrap.status().message();
  EXPECT_GT(signed_volume(*wrap), 0.1);
  EXPECT_LT(signed_volume(*wrap), 0.2);
  options.alpha = 0.0;
  EXPECT_FALSE(alpha_wrap(open, options).ok());
}

TEST(MeshDistance, BoxDistancesAndInsideTestsAreExact) {
  auto query = MeshDistance::build(box({0, 0, 0}, {1, 1, 1}));
  ASSERT_TRUE(query.ok()) << query.status().message();
  EXPECT_TRUE(query->is_closed());
  EXPECT_NEAR(query->distance({0.5, 0.5, 2.0}), 1.0, 1e-12);   // above the top face
  EXPECT_NEAR(query->distance({2.0, 2.0, 0.5}), std::sqrt(2.0), 1e-12);  // off an edge
  EXPECT_NEAR(query->signed_distance({0.5, 0.5, 0.4}), -0.4, 1e-12);
  EXPECT_TRUE(query->inside({0.2, 0.3, 0.4}));
  EXPECT_FALSE(query->inside({1.2, 0.3, 0.4}));
  Eigen::Index t = -1;
  const Eigen::Vector3d q = query->closest_point({0.5, 0.5, -3.0}, &t);
  EXPECT_NEAR(q.z(), 0.0, 1e-12);
  EXPECT_TRUE(t == 0 || t == 1) << t;  // the bottom face's triangles
  EXPECT_FALSE(MeshDistance::build(TriangleMesh{}).ok());
}

}  // namespace
}  // namespace hc::geometry
