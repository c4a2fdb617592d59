// The tracking building blocks on synthetic data with exact answers: epipolar multi-view matching
// of a regular grid (where two-view epipolar matching alone is ambiguous), tracking a moving grid
// through steps (including a jump back to rest), Horn's absolute orientation against a known rigid
// motion, ICP, and the displacement interpolation (exact for affine fields, which the biharmonic
// RBF's affine part reproduces).
#include "processing/tracking/tracker.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace hc::tracking {
namespace {

CameraModel look_at_camera(const std::string& name, const Eigen::Vector3d& centre,
                                  const Eigen::Vector3d& target) {
  CameraModel c;
  c.name = name;
  c.width = 1600;
  c.height = 1200;
  c.fx = c.fy = 7000;
  c.cx = 799.5;
  c.cy = 599.5;
  c.distortion = {-0.05, 0.02, 0.0005, -0.0003, 0.0};
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d(0, 0, 1)).normalized();
  const Eigen::Vector3d y = z.cross(x);
  c.R.row(0) = x;
  c.R.row(1) = y;
  c.R.row(2) = z;
  c.t_m = -c.R * centre;
  return c;
}

std::vector<CameraModel> rig7() {
  std::vector<CameraModel> cams;
  for (int i = 0; i < 7; ++i) {
    const double a = M_PI * i / 6.0;
    cams.push_back(look_at_camera("cam" + std::to_string(i),
                                  {0.3 * std::cos(a), -0.3 * std::sin(a), 0.3}, {0, 0, 0.05}));
  }
  return cams;
}

// 15 x 15 markers, 3 mm apart, on z = 0.05 (the thesis's dotted grid).
std::vector<Eigen::Vector3d> grid() {
  std::vector<Eigen::Vector3d> g;
  for (int j = -7; j <= 7; ++j)
    for (int i = -7; i <= 7; ++i) g.emplace_back(0.003 * i, 0.003 * j, 0.05);
  return g;
}

FrameDetections project_all(const std::vector<CameraModel>& cams,
                            const std::vector<Eigen::Vector3d>& pts, double noise_px,
                            std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, noise_px);
  FrameDetections d(cams.size());
  for (std::size_t c = 0; c < cams.size(); ++c) {
    for (const auto& p : pts) d[c].push_back(*cams[c].project(p) + Eigen::Vector2d(n(rng), n(rng)));
    std::shuffle(d[c].begin(), d[c].end(), rng);  // detection order carries no identity
  }
  return d;
}

std::size_t nearest(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& p) {
  std::size_t b = 0;
  for (std::size_t i = 1; i < pts.size(); ++i)
    if ((pts[i] - p).norm() < (pts[b] - p).norm()) b = i;
  return b;
}

TEST(MatchViews, RecoversEveryGridMarkerWithoutFalseMatches) {
  const auto cams = rig7();
  const auto pts = grid();
  std::mt19937 rng(1);
  const FrameDetections det = project_all(cams, pts, 0.05, rng);
  auto m = match_views(cams, det);
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  ASSERT_EQ(m->size(), pts.size());
  std::vector<int> hit(pts.size(), 0);
  for (const MatchedPoint& p : *m) {
    const std::size_t i = nearest(pts, p.point_m);
    EXPECT_LT((pts[i] - p.point_m).norm(), 2e-5);  // 0.05 px noise: micrometres
    EXPECT_EQ(p.views(), 7);
    ++hit[i];
  }
  for (int h : hit) EXPECT_EQ(h, 1);
  // Mismatched input is an error, not a guess.
  FrameDetections short_list(3);
  EXPECT_EQ(match_views(cams, short_list).status().code(), StatusCode::kInvalidArgument);
}

TEST(MarkerTracker, FollowsADeformingGridAndAJumpBackToRest) {
  const auto cams = rig7();
  const auto rest = grid();
  std::mt19937 rng(2);
  MarkerTracker tracker(cams, {});
  auto first = tracker.initialise(project_all(cams, rest, 0.05, rng));
  ASSERT_TRUE(first.ok());
  ASSERT_EQ(tracker.num_markers(), rest.size());
  std::vector<std::size_t> id(rest.size());  // tracked marker -> grid index
  for (std::size_t m = 0; m < rest.size(); ++m) id[m] = nearest(rest, first->points_m[m]);
  // A Gaussian dimple deepening by 0.4 mm per step (markers 3 mm apart), then released.
  const auto dimple = [&](double depth) {
    std::vector<Eigen::Vector3d> p = rest;
    for (auto& x : p) x.z() -= depth * std::exp(-(x.x() * x.x() + x.y() * x.y()) / (2 * 4e-5));
    return p;
  };
  for (int k = 1; k <= 8; ++k) {
    const double depth = k <= 6 ? 0.4e-3 * k : 0.0;  // steps 7, 8: back at rest
    const auto truth = dimple(depth);
    auto r = tracker.track(project_all(cams, truth, 0.05, rng));
    ASSERT_TRUE(r.ok());
    ASSERT_EQ(r->points_m.size(), rest.size());  // no spurious new markers
    for (std::size_t m = 0; m < rest.size(); ++m) {
      ASSERT_EQ(r->measured[m], 1) << "step " << k << " marker " << m;
      EXPECT_LT((r->points_m[m] - truth[id[m]]).norm(), 2e-5) << "step " << k;
    }
    EXPECT_EQ(r->matched_detections, r->detections);
  }
}

TEST(MarkerTracker, HiddenMarkersAreNotMeasuredAndNewOnesAreFound) {
  const auto cams = rig7();
  auto pts = grid();
  std::mt19937 rng(3);
  const Eigen::Vector3d late(0.0015, 0.0015, 0.05);  // between grid markers
  MarkerTracker tracker(cams, {});
  ASSERT_TRUE(tracker.initialise(project_all(cams, pts, 0.05, rng)).ok());
  // Step 1: marker 112 (the centre) seen by one camera only; a new marker appears.
  FrameDetections d = project_all(cams, pts, 0.0, rng);
  for (std::size_t c = 1; c < cams.size(); ++c) {
    const Eigen::Vector2d p = *cams[c].project(pts[112]);
    std::erase_if(d[c], [&](const Eigen::Vector2d& q) { return (q - p).norm() < 1e-6; });
  }
  for (std::size_t c = 0; c < cams.size(); ++c) d[c].push_back(*cams[c].project(late));
  auto r = tracker.track(d);
  ASSERT_TRUE(r.ok());
  std::size_t unmeasured = 0;
  for (std::size_t m = 0; m < pts.size(); ++m) unmeasured += r->measured[m] ? 0 : 1;
  EXPECT_EQ(unmeasured, 1u);
  ASSERT_EQ(tracker.num_markers(), pts.size() + 1);
  EXPECT_LT((r->points_m.back() - late).norm(), 1e-6);
  EXPECT_EQ(tracker.birth_step().back(), 1);
}

TEST(AbsoluteOrientation, RecoversAKnownRigidMotion) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  Eigen::Matrix3Xd src(3, 30);
  for (int i = 0; i < 30; ++i) src.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.1, -0.2, 0.05);
  const Eigen::Matrix3Xd dst = T * src;
  auto est = absolute_orientation(src, dst);
  ASSERT_TRUE(est.ok());
  EXPECT_LT((est->matrix() - T.matrix()).norm(), 1e-12);
  Eigen::Matrix3Xd line(3, 5);
  for (int i = 0; i < 5; ++i) line.col(i) = Eigen::Vector3d(i, 2 * i, 0);
  EXPECT_EQ(absolute_orientation(line, line).status().code(), StatusCode::kFailedPrecondition);
}

TEST(Icp, AlignsAShiftedGridAndDropsFarPoints) {
  const auto target = grid();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.0004, -0.0003, 0.0002);
  std::vector<Eigen::Vector3d> source;
  for (const auto& p : target) source.push_back(T.inverse() * p);
  source.emplace_back(0.0, 0.0, 0.08);  // a probe marker: no node near it
  auto r = icp(source, target, Eigen::Isometry3d::Identity(), 1e-3);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_LT((r->T.matrix() - T.matrix()).norm(), 1e-9);
  EXPECT_EQ(r->match.back(), -1);
  for (std::size_t i = 0; i + 1 < source.size(); ++i) EXPECT_EQ(r->match[i], static_cast<int>(i));
  EXPECT_LT(r->rms_m, 1e-12);
}

TEST(InterpolateDisplacements, ReproducesAffineFieldsAndInterpolatesData) {
  std::vector<Eigen::Vector3d> pts = grid(), disp;
  Eigen::Matrix3d A;
  A << 0.01, -0.02, 0.0, 0.03, 0.0, 0.0, -0.01, 0.02, 0.0;
  const Eigen::Vector3d b(1e-4, -2e-4, 3e-4);
  for (const auto& p : pts) disp.push_back(A * p + b);
  // Query off the data (coplanar data: the affine part spans x and y only).
  std::vector<Eigen::Vector3d> q{{0.0011, -0.0042, 0.05}, {-0.017, 0.019, 0.05}};
  auto f = interpolate_displacements(pts, disp, q);
  for (std::size_t i = 0; i < q.size(); ++i) EXPECT_LT((f[i] - (A * q[i] + b)).norm(), 1e-12);
  // Arbitrary data is interpolated exactly at the data points.
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1e-3);
  for (auto& d : disp) d = Eigen::Vector3d(n(rng), n(rng), n(rng));
  auto g = interpolate_displacements(pts, disp, pts);
  for (std::size_t i = 0; i < pts.size(); ++i) EXPECT_LT((g[i] - disp[i]).norm(), 1e-10);
  // Fewer than 4 points: the mean.
  auto h = interpolate_displacements({pts[0], pts[1]}, {disp[0], disp[1]}, {pts[5]});
  EXPECT_LT((h[0] - 0.5 * (disp[0] + disp[1])).norm(), 1e-15);
}

}  // namespace
}  // namespace hc::tracking
