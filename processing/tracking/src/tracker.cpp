#include "processing/tracking/tracker.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <unordered_map>

#include "processing/tracking/triangulation.h"

namespace hc::tracking {
namespace {

// A uniform grid over one image's detections for nearest-neighbour queries (a k-d tree would do
// too; detections are spread evenly and queries are within a few pixels, so a grid is simpler).
class PixelGrid {
 public:
  PixelGrid(const std::vector<Eigen::Vector2d>& points, double cell_px)
      : points_(&points), cell_(cell_px) {
    for (std::size_t i = 0; i < points.size(); ++i)
      cells_[key(points[i])].push_back(static_cast<int>(i));
  }
  // Nearest and second-nearest detection within `radius` (index -1 when none).
  void nearest2(const Eigen::Vector2d& p, double radius, int& i1, double& d1, int& i2,
                double& d2) const {
    i1 = i2 = -1;
    d1 = d2 = std::numeric_limits<double>::infinity();
    const long r = static_cast<long>(std::ceil(radius / cell_));
    const long cx = static_cast<long>(std::floor(p.x() / cell_));
    const long cy = static_cast<long>(std::floor(p.y() / cell_));
    for (long y = cy - r; y <= cy + r; ++y)
      for (long x = cx - r; x <= cx + r; ++x) {
        auto it = cells_.find(pack(x, y));
        if (it == cells_.end()) continue;
        for (int i : it->second) {
          const double d = ((*points_)[static_cast<std::size_t>(i)] - p).norm();
          if (d > radius) continue;
          if (d < d1) {
            i2 = i1;
            d2 = d1;
            i1 = i;
            d1 = d;
          } else if (d < d2) {
            i2 = i;
            d2 = d;
          }
        }
      }
  }

 private:
  static std::int64_t pack(long x, long y) {
    return (static_cast<std::int64_t>(x) << 32) ^ static_cast<std::int64_t>(y & 0xFFFFFFFF);
  }
  std::int64_t key(const Eigen::Vector2d& p) const {
    return pack(static_cast<long>(std::floor(p.x() / cell_)),
                static_cast<long>(std::floor(p.y() / cell_)));
  }
  const std::vector<Eigen::Vector2d>* points_;
  double cell_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Triangulates from the views a marker's detection vector names, dropping the worst view while
// the RMS is above max_rms and more than min_views remain. Returns false when it cannot.
bool triangulate_marker(const std::vector<CameraModel>& cams, const FrameDetections& det,
                        std::vector<int>& detection, int min_views, double max_rms,
                        Eigen::Vector3d& point, double& rms) {
  while (true) {
    std::vector<View> views;
    std::vector<std::size_t> cam_of;
    for (std::size_t c = 0; c < cams.size(); ++c)
      if (detection[c] >= 0) {
        views.push_back({&cams[c], det[c][static_cast<std::size_t>(detection[c])]});
        cam_of.push_back(c);
      }
    if (static_cast<int>(views.size()) < std::max(2, min_views)) return false;
    Result<Triangulation> t = triangulate(views);
    if (!t.ok()) return false;
    if (t->rms_px <= max_rms) {
      point = t->point_m;
      rms = t->rms_px;
      return true;
    }
    const auto worst = static_cast<std::size_t>(
        std::max_element(t->residual_px.begin(), t->residual_px.end()) - t->residual_px.begin());
    detection[cam_of[worst]] = -1;
  }
}

// A two-view hypothesis's point: the midpoint of the closest points of the two rays (rig-frame
// centres c, directions d with unit depth). Scoring a pair only needs a point to project into the
// other cameras, and this costs a few dozen flops where the DLT's eigen-solve was a third of
// `calib hand-eye`; every accepted marker is then triangulated from all its views. nullopt for
// (nearly) parallel rays or a point behind either camera.
std::optional<Eigen::Vector3d> ray_midpoint(const Eigen::Vector3d& ca, const Eigen::Vector3d& da,
                                            const Eigen::Vector3d& cb, const Eigen::Vector3d& db) {
  const Eigen::Vector3d w = ca - cb;
  const double a = da.squaredNorm(), b = da.dot(db), c = db.squaredNorm();
  const double d = da.dot(w), e = db.dot(w);
  const double den = a * c - b * b;
  if (!(den > 1e-12 * a * c)) return std::nullopt;
  const double s = (b * e - c * d) / den, u = (a * e - b * d) / den;
  if (!(s > 0) || !(u > 0)) return std::nullopt;
  return 0.5 * ((ca + s * da) + (cb + u * db));
}

}  // namespace

int MatchedPoint::views() const {
  return static_cast<int>(
      std::count_if(detection.begin(), detection.end(), [](int d) { return d >= 0; }));
}

Status MatchOptions::validate() const {
  if (!(epipolar_tolerance_px > 0) || !(support_tolerance_px > 0) || !(max_rms_px > 0))
    return invalid_argument("match tolerances must be positive");
  if (min_views < 2) return invalid_argument(fmt::format("min_views {} < 2", min_views));
  return {};
}

Status TrackOptions::validate() const {
  HC_RETURN_IF_ERROR(match.validate());
  if (!(search_radius_px > 0) || !(max_rms_px > 0))
    return invalid_argument("track radii must be positive");
  if (min_views < 2) return invalid_argument(fmt::format("min_views {} < 2", min_views));
  if (!(ambiguity_ratio > 0 && ambiguity_ratio <= 1))
    return invalid_argument("ambiguity_ratio must be in (0, 1]");
  return {};
}

Result<std::vector<MatchedPoint>> match_views(const std::vector<CameraModel>& cameras,
                                              const FrameDetections& detections,
                                              const MatchOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const std::size_t nc = cameras.size();
  if (detections.size() != nc)
    return invalid_argument(
        fmt::format("{} detection lists for {} cameras", detections.size(), nc));
  if (nc < 2) return invalid_argument("matching needs at least 2 cameras");
  // Undistorted normalised coordinates and a lookup grid per camera.
  std::vector<std::vector<Eigen::Vector2d>> xn(nc);
  std::vector<std::vector<Eigen::Vector3d>> ray(nc);  // rig frame, unit depth
  std::vector<Eigen::Vector3d> centre(nc);
  std::vector<PixelGrid> grids;
  grids.reserve(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    centre[c] = cameras[c].center_m();
    for (const auto& p : detections[c]) {
      xn[c].push_back(cameras[c].undistort_to_normalized(p));
      ray[c].push_back(cameras[c].R.transpose() * xn[c].back().homogeneous());
    }
    grids.emplace_back(detections[c], 16.0);
  }
  struct Hypothesis {
    std::vector<int> detection;
    int views = 0;
    double rms = 0;
  };
  std::vector<Hypothesis> hyps;
  for (std::size_t a = 0; a < nc; ++a)
    for (std::size_t b = a + 1; b < nc; ++b) {
      const Eigen::Matrix3d R_ba = cameras[b].R * cameras[a].R.transpose();
      const Eigen::Vector3d t_ba = cameras[b].t_m - R_ba * cameras[a].t_m;
      const Eigen::Matrix3d E = skew(t_ba) * R_ba;  // x_b^T E x_a = 0
      const double tol_n = options.epipolar_tolerance_px / cameras[b].fx;
      for (std::size_t i = 0; i < xn[a].size(); ++i) {
        const Eigen::Vector3d l = E * xn[a][i].homogeneous();
        const double ln = std::hypot(l.x(), l.y());
        if (ln == 0) continue;
        for (std::size_t j = 0; j < xn[b].size(); ++j) {
          if (std::abs(l.dot(xn[b][j].homogeneous())) / ln > tol_n) continue;
          const std::optional<Eigen::Vector3d> X =
              ray_midpoint(centre[a], ray[a][i], centre[b], ray[b][j]);
          if (!X) continue;
          Hypothesis h;
          h.detection.assign(nc, -1);
          double ss = 0;
          for (std::size_t c = 0; c < nc; ++c) {
            if (c == a || c == b) {
              const int k = static_cast<int>(c == a ? i : j);
              const double e = reprojection_error_px(
                  {&cameras[c], detections[c][static_cast<std::size_t>(k)]}, *X);
              h.detection[c] = k;
              ss += e * e;
              continue;
            }
            const auto p = cameras[c].project(*X);
            if (!p) continue;
            int i1, i2;
            double d1, d2;
            grids[c].nearest2(*p, options.support_tolerance_px, i1, d1, i2, d2);
            if (i1 < 0 || i2 >= 0) continue;  // none, or ambiguous
            h.detection[c] = i1;
            ss += d1 * d1;
          }
          h.views = static_cast<int>(
              std::count_if(h.detection.begin(), h.detection.end(), [](int d) { return d >= 0; }));
          if (h.views < options.min_views) continue;
          h.rms = std::sqrt(ss / h.views);
          hyps.push_back(std::move(h));
        }
      }
    }
  std::sort(hyps.begin(), hyps.end(), [](const Hypothesis& x, const Hypothesis& y) {
    return x.views != y.views ? x.views > y.views : x.rms < y.rms;
  });
  std::vector<std::vector<std::uint8_t>> used(nc);
  for (std::size_t c = 0; c < nc; ++c) used[c].assign(detections[c].size(), 0);
  std::vector<MatchedPoint> out;
  for (Hypothesis& h : hyps) {
    int free_views = 0;
    for (std::size_t c = 0; c < nc; ++c) {
      if (h.detection[c] >= 0 && used[c][static_cast<std::size_t>(h.detection[c])])
        h.detection[c] = -1;
      if (h.detection[c] >= 0) ++free_views;
    }
    if (free_views < options.min_views) continue;
    MatchedPoint m;
    m.detection = h.detection;
    if (!triangulate_marker(cameras, detections, m.detection, options.min_views, options.max_rms_px,
                            m.point_m, m.rms_px))
      continue;
    for (std::size_t c = 0; c < nc; ++c)
      if (m.detection[c] >= 0) used[c][static_cast<std::size_t>(m.detection[c])] = 1;
    out.push_back(std::move(m));
  }
  return out;
}

MarkerTracker::MarkerTracker(std::vector<CameraModel> cameras, TrackOptions options)
    : cameras_(std::move(cameras)), options_(options) {}

Result<StepResult> MarkerTracker::initialise(const FrameDetections& detections) {
  HC_RETURN_IF_ERROR(options_.validate());
  HC_ASSIGN_OR_RETURN(std::vector<MatchedPoint> pts,
                      match_views(cameras_, detections, options_.match));
  StepResult r;
  const std::size_t nc = cameras_.size();
  r.owner.resize(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    r.owner[c].assign(detections[c].size(), -1);
    r.detections += detections[c].size();
  }
  double ss = 0;
  std::size_t nv = 0;
  for (std::size_t m = 0; m < pts.size(); ++m) {
    r.points_m.push_back(pts[m].point_m);
    r.measured.push_back(1);
    r.views.push_back(pts[m].views());
    for (std::size_t c = 0; c < nc; ++c)
      if (pts[m].detection[c] >= 0) {
        r.owner[c][static_cast<std::size_t>(pts[m].detection[c])] = static_cast<int>(m);
        ++r.matched_detections;
      }
    ss += pts[m].rms_px * pts[m].rms_px * pts[m].views();
    nv += static_cast<std::size_t>(pts[m].views());
  }
  r.reprojection_rms_px = nv ? std::sqrt(ss / static_cast<double>(nv)) : 0.0;
  position_ = r.points_m;
  velocity_.assign(position_.size(), Eigen::Vector3d::Zero());
  birth_.assign(position_.size(), 0);
  rest_ = position_;
  unmeasured_run_.assign(position_.size(), 0);
  retired_.assign(position_.size(), 0);
  step_ = 0;
  initialised_ = true;
  return r;
}

namespace {

// One association attempt of the markers' predicted positions with a step's detections: each
// detection goes to the nearest unambiguous projected marker, then each marker seen in enough
// views is triangulated. Retired markers take part in nothing.
StepResult associate(const std::vector<CameraModel>& cameras, const TrackOptions& options,
                     const FrameDetections& detections, const std::vector<PixelGrid>& grids,
                     const std::vector<std::uint8_t>& retired,
                     const std::vector<Eigen::Vector3d>& predicted) {
  const std::size_t nc = cameras.size(), nm = predicted.size();
  StepResult r;
  r.points_m = predicted;
  r.measured.assign(nm, 0);
  r.views.assign(nm, 0);
  r.owner.resize(nc);
  std::vector<std::vector<double>> owner_dist(nc);
  std::vector<std::vector<int>> det(nm, std::vector<int>(nc, -1));
  for (std::size_t c = 0; c < nc; ++c) {
    r.owner[c].assign(detections[c].size(), -1);
    owner_dist[c].assign(detections[c].size(), std::numeric_limits<double>::infinity());
    r.detections += detections[c].size();
  }
  for (std::size_t m = 0; m < nm; ++m)
    for (std::size_t c = 0; c < nc; ++c) {
      if (retired[m]) break;
      const auto p = cameras[c].project(predicted[m]);
      if (!p) continue;
      int i1, i2;
      double d1, d2;
      grids[c].nearest2(*p, options.search_radius_px, i1, d1, i2, d2);
      if (i1 < 0) continue;
      if (i2 >= 0 && d1 > options.ambiguity_ratio * d2) continue;
      const auto k = static_cast<std::size_t>(i1);
      if (d1 < owner_dist[c][k]) {
        if (r.owner[c][k] >= 0) det[static_cast<std::size_t>(r.owner[c][k])][c] = -1;
        r.owner[c][k] = static_cast<int>(m);
        owner_dist[c][k] = d1;
        det[m][c] = i1;
      }
    }
  double ss = 0;
  std::size_t nv = 0;
  for (std::size_t m = 0; m < nm; ++m) {
    Eigen::Vector3d X;
    double rms = 0;
    if (triangulate_marker(cameras, detections, det[m], options.min_views, options.max_rms_px, X,
                           rms)) {
      r.points_m[m] = X;
      r.measured[m] = 1;
      int v = 0;
      for (std::size_t c = 0; c < nc; ++c) v += det[m][c] >= 0 ? 1 : 0;
      r.views[m] = v;
      ss += rms * rms * v;
      nv += static_cast<std::size_t>(v);
    }
  }
  // Detections owned by markers that ended up unmeasured (or lost a view) are released.
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t k = 0; k < r.owner[c].size(); ++k) {
      const int m = r.owner[c][k];
      if (m < 0) continue;
      if (!r.measured[static_cast<std::size_t>(m)] ||
          det[static_cast<std::size_t>(m)][c] != static_cast<int>(k)) {
        r.owner[c][k] = -1;
      } else {
        ++r.matched_detections;
      }
    }
  r.reprojection_rms_px = nv ? std::sqrt(ss / static_cast<double>(nv)) : 0.0;
  return r;
}

long measured_count(const StepResult& r) {
  return std::count(r.measured.begin(), r.measured.end(), std::uint8_t{1});
}

// Unmeasured markers move with the mean displacement (from `position`) of their 4 nearest
// measured ones.
void predict_unmeasured(const std::vector<Eigen::Vector3d>& position, StepResult* r) {
  const std::size_t nm = position.size();
  std::vector<std::size_t> measured_ids;
  for (std::size_t m = 0; m < nm; ++m)
    if (r->measured[m]) measured_ids.push_back(m);
  for (std::size_t m = 0; m < nm; ++m) {
    if (r->measured[m]) continue;
    std::vector<std::pair<double, std::size_t>> near;
    for (std::size_t q : measured_ids)
      near.emplace_back((position[q] - position[m]).squaredNorm(), q);
    const std::size_t k = std::min<std::size_t>(4, near.size());
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(k), near.end());
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < k; ++i) d += r->points_m[near[i].second] - position[near[i].second];
    r->points_m[m] =
        position[m] + (k ? Eigen::Vector3d(d / static_cast<double>(k)) : Eigen::Vector3d::Zero());
  }
}

}  // namespace

Result<StepResult> MarkerTracker::track(const FrameDetections& detections) {
  if (!initialised_) return failed_precondition("MarkerTracker::track before initialise");
  const std::size_t nc = cameras_.size();
  if (detections.size() != nc)
    return invalid_argument(
        fmt::format("{} detection lists for {} cameras", detections.size(), nc));
  std::vector<PixelGrid> grids;
  grids.reserve(nc);
  for (std::size_t c = 0; c < nc; ++c) grids.emplace_back(detections[c], 16.0);
  const std::size_t nm = position_.size();
  const auto attempt = [&](const std::vector<Eigen::Vector3d>& predicted) {
    return associate(cameras_, options_, detections, grids, retired_, predicted);
  };
  std::vector<Eigen::Vector3d> pred(nm);
  for (std::size_t m = 0; m < nm; ++m) pred[m] = position_[m] + velocity_[m];
  StepResult best = attempt(pred);
  // A jump the constant-velocity prediction misses (the probe retracted, a new location): try
  // the last positions as they are.
  const auto active = static_cast<double>(std::count(retired_.begin(), retired_.end(), 0));
  if (static_cast<double>(measured_count(best)) < 0.95 * active) {
    StepResult still = attempt(position_);
    if (measured_count(still) > measured_count(best)) best = std::move(still);
  }
  // ... or the probe let go: the markers are back where they were first seen.
  if (static_cast<double>(measured_count(best)) < 0.95 * active) {
    StepResult back = attempt(rest_);
    if (measured_count(back) > measured_count(best)) best = std::move(back);
  }
  // While moving the unmeasured markers with their neighbours lets more markers be found (a
  // dimple released in one step: the rim is found first, then the markers inside it), associate
  // again from these predictions.
  predict_unmeasured(position_, &best);
  for (int pass = 0; pass < 8 && measured_count(best) < static_cast<long>(active); ++pass) {
    StepResult again = attempt(best.points_m);
    if (measured_count(again) <= measured_count(best)) break;
    best = std::move(again);
    predict_unmeasured(position_, &best);
  }
  for (std::size_t m = 0; m < nm; ++m) {
    velocity_[m] = best.points_m[m] - position_[m];
    position_[m] = best.points_m[m];
    unmeasured_run_[m] = best.measured[m] ? 0 : unmeasured_run_[m] + 1;
    if (birth_[m] > 0 && unmeasured_run_[m] >= options_.retire_after_steps) retired_[m] = 1;
  }
  ++step_;
  if (options_.detect_new_markers) add_new_markers(detections, &best);
  return best;
}

void MarkerTracker::add_new_markers(const FrameDetections& detections, StepResult* best) {
  // Leftover detections, matched among themselves.
  const std::size_t nc = cameras_.size();
  FrameDetections left(nc);
  std::vector<std::vector<int>> index(nc);
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t k = 0; k < detections[c].size(); ++k)
      if (best->owner[c][k] < 0) {
        left[c].push_back(detections[c][k]);
        index[c].push_back(static_cast<int>(k));
      }
  Result<std::vector<MatchedPoint>> fresh = match_views(cameras_, left, options_.match);
  if (!fresh.ok()) return;
  for (const MatchedPoint& p : *fresh) {
    bool near = false;
    for (std::size_t m = 0; m < position_.size() && !near; ++m)
      near = !retired_[m] && (position_[m] - p.point_m).norm() < options_.new_marker_separation_m;
    if (near) continue;
    const int id = static_cast<int>(position_.size());
    position_.push_back(p.point_m);
    velocity_.push_back(Eigen::Vector3d::Zero());
    birth_.push_back(step_);
    rest_.push_back(p.point_m);
    unmeasured_run_.push_back(0);
    retired_.push_back(0);
    best->points_m.push_back(p.point_m);
    best->measured.push_back(1);
    best->views.push_back(p.views());
    for (std::size_t c = 0; c < nc; ++c)
      if (p.detection[c] >= 0) {
        best->owner[c]
                   [static_cast<std::size_t>(index[c][static_cast<std::size_t>(p.detection[c])])] =
            id;
        ++best->matched_detections;
      }
  }
}

Result<Eigen::Isometry3d> absolute_orientation(const Eigen::Matrix3Xd& src,
                                               const Eigen::Matrix3Xd& dst) {
  if (src.cols() != dst.cols())
    return invalid_argument(fmt::format("{} source vs {} target points", src.cols(), dst.cols()));
  if (src.cols() < 3) return failed_precondition("absolute orientation needs >= 3 points");
  const Eigen::Vector3d mean = src.rowwise().mean();
  const Eigen::Matrix3d cov = (src.colwise() - mean) * (src.colwise() - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  if (es.eigenvalues()(1) <= 1e-12 * std::max(1e-30, es.eigenvalues()(2)))
    return failed_precondition("absolute orientation: points are collinear");
  const Eigen::Matrix4d T = Eigen::umeyama(src, dst, false);
  if (!T.allFinite()) return failed_precondition("absolute orientation: no finite solution");
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = T.topLeftCorner<3, 3>();
  out.translation() = T.topRightCorner<3, 1>();
  return out;
}

Result<IcpResult> icp(const std::vector<Eigen::Vector3d>& source,
                      const std::vector<Eigen::Vector3d>& target, const Eigen::Isometry3d& initial,
                      double max_distance_m, int max_iterations) {
  if (source.size() < 3 || target.size() < 3)
    return failed_precondition("ICP needs at least 3 source and 3 target points");
  if (!(max_distance_m > 0)) return invalid_argument("ICP max distance must be positive");
  // Target lookup: a uniform 3-D grid of cell max_distance.
  std::unordered_map<std::int64_t, std::vector<int>> grid;
  const auto cell = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / max_distance_m)),
                           static_cast<int>(std::floor(p.y() / max_distance_m)),
                           static_cast<int>(std::floor(p.z() / max_distance_m)));
  };
  const auto pack = [](const Eigen::Vector3i& c) {
    return (static_cast<std::int64_t>(c.x() & 0x1FFFFF) << 42) |
           (static_cast<std::int64_t>(c.y() & 0x1FFFFF) << 21) |
           static_cast<std::int64_t>(c.z() & 0x1FFFFF);
  };
  for (std::size_t i = 0; i < target.size(); ++i)
    grid[pack(cell(target[i]))].push_back(static_cast<int>(i));
  IcpResult r;
  r.T = initial;
  std::vector<int> prev;
  for (int it = 0; it < max_iterations; ++it) {
    r.iterations = it + 1;
    std::vector<int> match(source.size(), -1);
    std::vector<double> dist(source.size(), 0);
    std::vector<int> owner(target.size(), -1);
    std::vector<double> owner_d(target.size(), std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < source.size(); ++i) {
      const Eigen::Vector3d p = r.T * source[i];
      const Eigen::Vector3i c = cell(p);
      double best = max_distance_m;
      int bi = -1;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            auto f = grid.find(pack(c + Eigen::Vector3i(dx, dy, dz)));
            if (f == grid.end()) continue;
            for (int j : f->second) {
              const double d = (target[static_cast<std::size_t>(j)] - p).norm();
              if (d <= best) {
                best = d;
                bi = j;
              }
            }
          }
      if (bi < 0) continue;
      const auto j = static_cast<std::size_t>(bi);
      if (best < owner_d[j]) {
        if (owner[j] >= 0) match[static_cast<std::size_t>(owner[j])] = -1;
        owner[j] = static_cast<int>(i);
        owner_d[j] = best;
        match[i] = bi;
        dist[i] = best;
      }
    }
    std::vector<std::size_t> pairs;
    for (std::size_t i = 0; i < source.size(); ++i)
      if (match[i] >= 0) pairs.push_back(i);
    if (pairs.size() < 3) return failed_precondition("ICP: fewer than 3 pairs within the distance");
    Eigen::Matrix3Xd S(3, static_cast<Eigen::Index>(pairs.size()));
    Eigen::Matrix3Xd D(3, static_cast<Eigen::Index>(pairs.size()));
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      S.col(static_cast<Eigen::Index>(k)) = source[pairs[k]];
      D.col(static_cast<Eigen::Index>(k)) = target[static_cast<std::size_t>(match[pairs[k]])];
    }
    HC_ASSIGN_OR_RETURN(r.T, absolute_orientation(S, D));
    double ss = 0;
    for (std::size_t k = 0; k < pairs.size(); ++k)
      ss += (r.T * source[pairs[k]] - target[static_cast<std::size_t>(match[pairs[k]])])
                .squaredNorm();
    r.rms_m = std::sqrt(ss / static_cast<double>(pairs.size()));
    r.match = match;
    if (match == prev) break;
    prev = std::move(match);
  }
  return r;
}

std::vector<Eigen::Vector3d> interpolate_displacements(
    const std::vector<Eigen::Vector3d>& known_points,
    const std::vector<Eigen::Vector3d>& known_disp, const std::vector<Eigen::Vector3d>& query,
    double regularization_m) {
  const auto K = static_cast<Eigen::Index>(known_points.size());
  std::vector<Eigen::Vector3d> out(query.size(), Eigen::Vector3d::Zero());
  if (K == 0) return out;
  Eigen::Vector3d mean_d = Eigen::Vector3d::Zero();
  for (const auto& d : known_disp) mean_d += d;
  mean_d /= static_cast<double>(K);
  if (K < 4) {
    std::fill(out.begin(), out.end(), mean_d);
    return out;
  }
  // The affine part spans only the directions the known points extend in (markers on a flat top
  // face are coplanar: a z term would make the system singular).
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : known_points) centre += p;
  centre /= static_cast<double>(K);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : known_points) cov += (p - centre) * (p - centre).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  std::vector<Eigen::Vector3d> axes;
  for (int a = 2; a >= 0; --a)
    if (es.eigenvalues()(a) > 1e-6 * es.eigenvalues()(2)) axes.push_back(es.eigenvectors().col(a));
  const auto P = static_cast<Eigen::Index>(1 + axes.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(K + P, K + P);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(K + P, 3);
  double scale = std::sqrt(es.eigenvalues()(2) / static_cast<double>(K));  // spread, m
  if (!(scale > 0)) scale = 1;
  for (Eigen::Index i = 0; i < K; ++i) {
    for (Eigen::Index j = 0; j < K; ++j)
      A(i, j) =
          (known_points[static_cast<std::size_t>(i)] - known_points[static_cast<std::size_t>(j)])
              .norm() /
          scale;
    A(i, i) -= regularization_m / scale;  // |r| is conditionally negative definite: smoothing
                                          // moves the diagonal the other way
    A(i, K) = A(K, i) = 1;
    for (std::size_t a = 0; a < axes.size(); ++a) {
      const double v = axes[a].dot(known_points[static_cast<std::size_t>(i)] - centre) / scale;
      A(i, K + 1 + static_cast<Eigen::Index>(a)) = A(K + 1 + static_cast<Eigen::Index>(a), i) = v;
    }
    b.row(i) = known_disp[static_cast<std::size_t>(i)].transpose();
  }
  const Eigen::MatrixXd w = A.partialPivLu().solve(b);
  if (!w.allFinite()) {
    std::fill(out.begin(), out.end(), mean_d);
    return out;
  }
  for (std::size_t q = 0; q < query.size(); ++q) {
    Eigen::RowVector3d v = w.row(K);
    for (std::size_t a = 0; a < axes.size(); ++a)
      v += w.row(K + 1 + static_cast<Eigen::Index>(a)) * (axes[a].dot(query[q] - centre) / scale);
    for (Eigen::Index i = 0; i < K; ++i)
      v += w.row(i) * ((query[q] - known_points[static_cast<std::size_t>(i)]).norm() / scale);
    out[q] = v.transpose();
  }
  return out;
}

}  // namespace hc::tracking
