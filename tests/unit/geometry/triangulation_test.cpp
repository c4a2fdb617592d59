// hardcopy_geometry: the regular triangulation (checked by its defining local property, in exact
// arithmetic's sign with a tolerance) and the k-d tree (against brute force).
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "geometry/nearest_point.h"
#include "geometry/regular_triangulation.h"

namespace hc::geometry {
namespace {

struct Weighted {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> weights;
};

// n balls with centres uniform in the unit cube and radii up to r.
Weighted random_balls(std::size_t n, double r, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Weighted w;
  for (std::size_t i = 0; i < n; ++i) {
    w.points.emplace_back(u(rng), u(rng), u(rng));
    const double ri = r * u(rng);
    w.weights.push_back(ri * ri);
  }
  return w;
}

// The cells as sets of input indices (the infinite vertex -1), for comparing two triangulations
// whatever their cell order and corner spelling.
std::set<std::array<int, 4>> cell_sets(const Triangulation3& t) {
  std::set<std::array<int, 4>> out;
  for (auto c : t.cells) {
    std::sort(c.begin(), c.end());
    out.insert(c);
  }
  return out;
}

// Above the size where the insertion runs in parallel (regular_triangulation_3.cpp): every finite
// cell positively oriented; neighbours mutual; the triangulation regular, checked locally (for a
// triangulation of the convex hull, every facet being locally regular makes it regular: the
// opposite corner across each facet has power >= 0 to the cell's orthogonal sphere); the same
// output on a second run and for the input in reverse order (indices mapped back).
TEST(RegularTriangulation3, ParallelInsertionIsRegularAndDeterministic) {
  constexpr std::size_t kN = 30'000;
  const Weighted w = random_balls(kN, 0.01, 7);
  Triangulate3Options parallel;
  parallel.insertion = Insertion::kParallel;
  auto t = triangulate_3d(w.points, w.weights, parallel);
  ASSERT_TRUE(t.ok()) << t.status().message();
  const std::size_t cells = t->cells.size();
  // A Delaunay tetrahedralisation of uniform random points has about 6.77 n cells (Dwyer 1991);
  // small weights change that little.
  ASSERT_GT(cells, 5 * kN);
  std::size_t hidden = 0;
  for (const auto v : t->is_vertex) hidden += v == 0;
  for (std::size_t c = 0; c < cells; ++c) {
    for (std::size_t k = 0; k < 4; ++k) {
      const int nb = t->neighbours[c][k];
      ASSERT_GE(nb, 0);
      const auto& back = t->neighbours[static_cast<std::size_t>(nb)];
      ASSERT_NE(std::find(back.begin(), back.end(), static_cast<int>(c)), back.end());
    }
    if (!t->is_finite(static_cast<int>(c))) continue;
    const auto& v = t->cells[c];
    const Eigen::Vector3d& a = w.points[static_cast<std::size_t>(v[0])];
    const double orient = (w.points[static_cast<std::size_t>(v[1])] - a)
                              .dot((w.points[static_cast<std::size_t>(v[2])] - a)
                                       .cross(w.points[static_cast<std::size_t>(v[3])] - a));
    ASSERT_GT(orient, 0.0) << "cell " << c;
    // The orthogonal sphere: |o - p|^2 - w_p = squared_radius for its four corners (rounding:
    // relative to its size; flat cells at the hull have huge ones).
    const Eigen::Vector3d& o = t->centres[c];
    const double tol = 1e-9 * (1.0 + std::abs(t->squared_radii[c]));
    for (const int p : v) {
      EXPECT_NEAR((o - w.points[static_cast<std::size_t>(p)]).squaredNorm() -
                      w.weights[static_cast<std::size_t>(p)],
                  t->squared_radii[c], tol);
    }
    for (std::size_t k = 0; k < 4; ++k) {
      const auto& nbc = t->cells[static_cast<std::size_t>(t->neighbours[c][k])];
      for (const int q : nbc) {
        if (q < 0 || std::find(v.begin(), v.end(), q) != v.end()) continue;
        const double power = (o - w.points[static_cast<std::size_t>(q)]).squaredNorm() -
                             w.weights[static_cast<std::size_t>(q)] - t->squared_radii[c];
        EXPECT_GT(power, -tol) << "cell " << c << " corner " << q;
      }
    }
  }
  // A ball is hidden only when its neighbours' balls cover its power cell; at radii up to 0.01 and
  // a point spacing of 30000^(-1/3) = 0.032 that is rare.
  EXPECT_LT(hidden, kN / 10);

  auto again = triangulate_3d(w.points, w.weights, parallel);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->cells, t->cells);
  EXPECT_EQ(again->neighbours, t->neighbours);
  EXPECT_EQ(again->is_vertex, t->is_vertex);
  // A sequential insertion (what kAuto does on a busy machine) gives the same output.
  Triangulate3Options sequential_options;
  sequential_options.insertion = Insertion::kSequential;
  auto sequential = triangulate_3d(w.points, w.weights, sequential_options);
  ASSERT_TRUE(sequential.ok());
  EXPECT_EQ(sequential->cells, t->cells);
  EXPECT_EQ(sequential->neighbours, t->neighbours);
  EXPECT_EQ(sequential->is_vertex, t->is_vertex);

  Weighted reversed;
  for (std::size_t i = kN; i-- > 0;) {
    reversed.points.push_back(w.points[i]);
    reversed.weights.push_back(w.weights[i]);
  }
  auto r = triangulate_3d(reversed.points, reversed.weights);
  ASSERT_TRUE(r.ok());
  for (auto& c : r->cells) {
    for (int& i : c) i = i < 0 ? -1 : static_cast<int>(kN) - 1 - i;
  }
  EXPECT_EQ(cell_sets(*r), cell_sets(*t));
}

// Large inputs without weights go through CGAL's Delaunay triangulation
// (regular_triangulation_3.cpp): the same cells, neighbours and order as the regular
// triangulation with all weights zero, and circumcentres equal to those power vertices up to
// rounding (both constructed in double, by different formulas).
TEST(RegularTriangulation3, LargeDelaunayMatchesZeroWeights) {
  constexpr std::size_t kN = 25'000;
  Weighted w = random_balls(kN, 0.0, 3);
  Triangulate3Options parallel;
  parallel.insertion = Insertion::kParallel;
  auto delaunay = triangulate_3d(w.points, {}, parallel);
  auto regular = triangulate_3d(w.points, w.weights, parallel);  // all zero
  ASSERT_TRUE(delaunay.ok() && regular.ok());
  ASSERT_GT(delaunay->cells.size(), 5 * kN);
  ASSERT_EQ(delaunay->cells, regular->cells);
  EXPECT_EQ(delaunay->neighbours, regular->neighbours);
  EXPECT_EQ(delaunay->is_vertex, regular->is_vertex);
  for (std::size_t c = 0; c < delaunay->cells.size(); ++c) {
    if (!delaunay->is_finite(static_cast<int>(c))) continue;
    const double r2 = regular->squared_radii[c];
    // Flat cells on the hull have huge circumspheres; relative to the cell's size.
    const double tol = 1e-9 * (1.0 + r2);
    ASSERT_NEAR(delaunay->squared_radii[c], r2, tol) << "cell " << c;
    ASSERT_LT((delaunay->centres[c] - regular->centres[c]).norm(), 1e-9 * (1.0 + std::sqrt(r2)))
        << "cell " << c;
  }
}

// centres_between: the power vertices of exactly the cells with corners of both labels, equal to
// those computed for every cell; NaN elsewhere. A label per point or none.
TEST(RegularTriangulation3, CentresOnlyBetweenLabelsAreTheSame) {
  const Weighted w = random_balls(3'000, 0.01, 11);
  std::vector<std::uint8_t> label(w.points.size());
  for (std::size_t i = 0; i < label.size(); ++i) label[i] = w.points[i].x() < 0.5 ? 1 : 0;
  auto all = triangulate_3d(w.points, w.weights);
  Triangulate3Options o;
  o.centres_between = label;
  auto some = triangulate_3d(w.points, w.weights, o);
  ASSERT_TRUE(all.ok() && some.ok());
  ASSERT_EQ(some->cells, all->cells);
  EXPECT_EQ(some->neighbours, all->neighbours);
  std::size_t mixed = 0;
  for (std::size_t c = 0; c < all->cells.size(); ++c) {
    if (!all->is_finite(static_cast<int>(c))) continue;
    std::set<std::uint8_t> labels;
    for (const int v : all->cells[c]) labels.insert(label[static_cast<std::size_t>(v)]);
    if (labels.size() == 2) {
      ++mixed;
      EXPECT_EQ(some->centres[c], all->centres[c]) << "cell " << c;
      EXPECT_EQ(some->squared_radii[c], all->squared_radii[c]) << "cell " << c;
    } else {
      EXPECT_TRUE(std::isnan(some->centres[c].x()) && std::isnan(some->squared_radii[c]));
    }
  }
  // A plane through 3,000 points crosses a few hundred of their ~20,000 cells.
  EXPECT_GT(mixed, 100U);
  EXPECT_LT(mixed, all->cells.size() / 2);
  label.pop_back();
  o.centres_between = label;
  EXPECT_EQ(triangulate_3d(w.points, w.weights, o).status().code(), StatusCode::kInvalidArgument);
}

// A Hilbert order is a permutation that visits near points one after another: on 10,000 uniform
// points its path is far shorter than the input order's (expected lengths ~0.66 n for a random
// order, ~ n^(2/3) times a small constant for a space-filling curve).
TEST(SpatialOrder, IsAPermutationWithAShortPath) {
  const Weighted w = random_balls(10'000, 0.0, 5);
  const std::vector<std::size_t> order = spatial_order(w.points);
  ASSERT_EQ(order.size(), w.points.size());
  std::vector<std::size_t> seen = order;
  std::sort(seen.begin(), seen.end());
  for (std::size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], i);
  double input = 0.0, hilbert = 0.0;
  for (std::size_t i = 1; i < order.size(); ++i) {
    input += (w.points[i] - w.points[i - 1]).norm();
    hilbert += (w.points[order[i]] - w.points[order[i - 1]]).norm();
  }
  EXPECT_LT(hilbert, 0.15 * input) << hilbert << " against " << input;
  EXPECT_EQ(spatial_order(w.points), order);
}

TEST(NearestPoint3, MatchesBruteForce) {
  const Weighted sites = random_balls(2'000, 0.0, 3);
  const Weighted queries = random_balls(500, 0.0, 4);
  auto tree = NearestPoint3::build(sites.points);
  ASSERT_TRUE(tree.ok()) << tree.status().message();
  auto q = tree->query(queries.points);
  ASSERT_TRUE(q.ok()) << q.status().message();
  for (std::size_t i = 0; i < queries.points.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& s : sites.points) best = std::min(best, (s - queries.points[i]).norm());
    EXPECT_DOUBLE_EQ(q->distance[i], best) << "query " << i;
    EXPECT_DOUBLE_EQ(
        (sites.points[static_cast<std::size_t>(q->index[i])] - queries.points[i]).norm(), best);
  }
}

TEST(NearestPoint3, EmptyAndNonFiniteInputAreErrors) {
  EXPECT_EQ(NearestPoint3::build({}).status().code(), StatusCode::kInvalidArgument);
  const std::vector<Eigen::Vector3d> bad{{0, 0, 0}, {std::nan(""), 0, 0}};
  EXPECT_EQ(NearestPoint3::build(bad).status().code(), StatusCode::kInvalidArgument);
  const std::vector<Eigen::Vector3d> one{{0, 0, 0}};
  auto tree = NearestPoint3::build(one);
  ASSERT_TRUE(tree.ok());
  const std::vector<Eigen::Vector3d> inf{{std::numeric_limits<double>::infinity(), 0, 0}};
  EXPECT_EQ(tree->query(inf).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace hc::geometry
