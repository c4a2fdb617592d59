#include "rig_daemon/simulation/sim_scene.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace hc::devices::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kSub = 8;  // supersamples per axis on edge pixels (as render_dots)

// Smallest s > eps of |o + s d - c| = r (d unit), or +inf.
double hit_sphere(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& c,
                  double r) {
  const Eigen::Vector3d oc = o - c;
  const double b = oc.dot(d);
  const double disc = b * b - (oc.squaredNorm() - r * r);
  if (disc < 0.0) return kInf;
  const double q = std::sqrt(disc);
  const double s0 = -b - q;
  if (s0 > 1e-9) return s0;
  const double s1 = -b + q;
  return s1 > 1e-9 ? s1 : kInf;
}

// Finite cylinder of radius r around the segment p + a h, h in [0, len] (a unit), with a flat cap
// at h = len (the bottom end lies inside the tip sphere).
double hit_cylinder(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& p,
                    const Eigen::Vector3d& a, double r, double len) {
  double best = kInf;
  const Eigen::Vector3d op = o - p;
  const Eigen::Vector3d dp = d - a * d.dot(a);
  const Eigen::Vector3d wp = op - a * op.dot(a);
  const double A = dp.squaredNorm();
  if (A > 1e-18) {
    const double B = dp.dot(wp);
    const double C = wp.squaredNorm() - r * r;
    const double disc = B * B - A * C;
    if (disc >= 0.0) {
      const double q = std::sqrt(disc);
      for (double s : {(-B - q) / A, (-B + q) / A}) {
        if (s <= 1e-9 || s >= best) continue;
        const double h = (op + s * d).dot(a);
        if (h >= 0.0 && h <= len) best = s;
      }
    }
  }
  const double dn = d.dot(a);
  if (std::abs(dn) > 1e-12) {  // the top cap
    const double s = (len - op.dot(a)) / dn;
    if (s > 1e-9 && s < best) {
      const Eigen::Vector3d q = op + s * d;
      if ((q - a * q.dot(a)).squaredNorm() <= r * r) best = s;
    }
  }
  return best;
}

// floor / ceil of a pixel coordinate as an int, clamped to [lo, hi] first (a point projected far
// off the image would overflow the conversion).
int floor_clamped(double v, int lo, int hi) {
  return static_cast<int>(
      std::floor(std::clamp(v, static_cast<double>(lo), static_cast<double>(hi))));
}
int ceil_clamped(double v, int lo, int hi) {
  return static_cast<int>(
      std::ceil(std::clamp(v, static_cast<double>(lo), static_cast<double>(hi))));
}

std::uint8_t to_grey(double v) {
  return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
}

}  // namespace

// ---- options ---------------------------------------------------------------------------------

Status ProbeLook::read(ConfigNode node) {
  node.optional("visible", visible);
  node.optional("shaft_radius_m", shaft_radius_m, Bounds::positive());
  node.optional("shaft_length_m", shaft_length_m, Bounds::positive());
  node.optional("marker_distances_m", marker_distances_m);
  node.optional("marker_radius_m", marker_radius_m, Bounds::positive());
  node.optional("grey", grey);
  node.optional("marker_grey", marker_grey);
  if (node.status().ok()) {
    if (Status s = validate(); !s.ok()) node.error("probe", s.message());
  }
  return node.status();
}

Status ProbeLook::validate() const {
  if (!(shaft_radius_m > 0.0 && shaft_length_m > 0.0 && marker_radius_m > 0.0))
    return invalid_argument("probe: shaft_radius_m, shaft_length_m, marker_radius_m must be > 0");
  for (double d : marker_distances_m)
    if (!(d > 0.0 && d <= shaft_length_m))
      return invalid_argument("probe: marker_distances_m must be in (0, shaft_length_m]");
  if (!(std::abs(marker_distances_m[1] - marker_distances_m[0]) > 2.0 * marker_radius_m))
    return invalid_argument("probe: the two shaft markers must not touch");
  return {};
}

Status BoardSpec::read(ConfigNode node) {
  node.required("cols", cols, Bounds::between(2, 64));
  node.required("rows", rows, Bounds::between(2, 64));
  node.required("square_m", square_m, Bounds{0.0, 1.0, true, false});
  node.optional("margin_squares", margin_squares, Bounds::between(0.0, 10.0));
  node.optional("black", black);
  node.optional("white", white);
  return node.status();
}

Status BoardSpec::validate() const {
  if (cols < 2 || rows < 2 || cols > 64 || rows > 64)
    return invalid_argument("board: cols and rows must be in [2, 64]");
  if (!(square_m > 0.0 && square_m <= 1.0))
    return invalid_argument("board: square_m must be in (0, 1]");
  if (!(margin_squares >= 0.0 && margin_squares <= 10.0))
    return invalid_argument("board: margin_squares must be in [0, 10]");
  return {};
}

// ---- probe -----------------------------------------------------------------------------------

ProbeGeometry ProbeGeometry::at(const ArmPose& pose, double radius_m, const ProbeLook& look) {
  ProbeGeometry g;
  g.tip_m = Eigen::Vector3d(pose.x_m, pose.y_m, pose.z_m);
  g.axis = Eigen::Vector3d::UnitZ();
  g.radius_m = radius_m;
  g.shaft_radius_m = look.shaft_radius_m;
  g.shaft_length_m = look.shaft_length_m;
  g.marker_radius_m = look.marker_radius_m;
  const double lo = std::min(look.marker_distances_m[0], look.marker_distances_m[1]);
  const double hi = std::max(look.marker_distances_m[0], look.marker_distances_m[1]);
  g.markers_m = {g.tip_m + g.axis * lo, g.tip_m + g.axis * hi};
  return g;
}

double ProbeGeometry::ray_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double inflate_m,
                              int* part) const {
  double marker = kInf;
  for (const Eigen::Vector3d& m : markers_m)
    marker = std::min(marker, hit_sphere(o, d, m, marker_radius_m + inflate_m));
  const double sphere = hit_sphere(o, d, sphere_center_m(), radius_m + inflate_m);
  const double shaft =
      hit_cylinder(o, d, sphere_center_m(), axis, shaft_radius_m + inflate_m, shaft_length_m);
  // A shaft marker shows in front of the stretch of shaft right next to it (within a ball
  // diameter along the ray: the shaft that passes through it, see the header).
  if (std::isfinite(marker) && marker <= sphere && marker <= shaft + 2.0 * marker_radius_m) {
    if (part != nullptr) *part = kMarker;
    return marker;
  }
  const double best = std::min(sphere, shaft);
  if (part != nullptr) *part = std::isfinite(best) ? kBody : kNone;
  return best;
}

namespace {

// Rays through pixel positions, in the world frame (origin: the camera centre).
struct RayCaster {
  explicit RayCaster(const CameraModel& c) : cam(c), Rt(c.R.transpose()), origin(c.center_m()) {}
  // Un-normalised world direction of the ray through (u, v).
  Eigen::Vector3d dir(double u, double v) const {
    const Eigen::Vector2d n = cam.undistort_to_normalized(Eigen::Vector2d(u, v));
    return Rt * Eigen::Vector3d(n.x(), n.y(), 1.0);
  }
  // dir() through the pixel corners (x0 - 0.5 + i, v), i < count, into out[i] (resized to count).
  // Exact rays every kStride corners, linear in between: the undistortion map's second
  // derivative is ~6 k1 r / f^2 per px^2, so over 8 px the interpolation error is below 1e-4 px
  // for any realistic lens.
  void corner_dirs(int x0, double v, int count, std::vector<Eigen::Vector3d>& out) const {
    constexpr int kStride = 8;
    out.resize(static_cast<std::size_t>(count));
    Eigen::Vector3d prev = dir(x0 - 0.5, v);
    out[0] = prev;
    for (int i0 = 0; i0 < count - 1; i0 += kStride) {
      const int i1 = std::min(count - 1, i0 + kStride);
      const Eigen::Vector3d next = dir(x0 - 0.5 + i1, v);
      for (int i = i0 + 1; i <= i1; ++i)
        out[static_cast<std::size_t>(i)] =
            prev + (next - prev) * (static_cast<double>(i - i0) / (i1 - i0));
      prev = next;
    }
  }
  const CameraModel& cam;
  Eigen::Matrix3d Rt;
  Eigen::Vector3d origin;
};

// Row spans of the probe's projection (lo[y] > hi[y]: none): project discs along the probe (the
// sphere, shaft cross-sections every half shaft radius, the marker balls) and take the union of
// their bounding boxes, grown for distortion.
void probe_row_spans(const CameraModel& cam, const ProbeGeometry& probe, int width, int height,
                     std::vector<int>& lo, std::vector<int>& hi) {
  lo.assign(static_cast<std::size_t>(height), width);
  hi.assign(static_cast<std::size_t>(height), -1);
  const auto add_disc = [&](const Eigen::Vector3d& c, double r) {
    const double z = cam.depth_m(c);
    if (!(z > r + 1e-3)) return;
    const std::optional<Eigen::Vector2d> uv = cam.project(c);
    if (!uv) return;
    const double rp = 1.15 * std::max(cam.fx, cam.fy) * r / (z - r) + 2.0;
    const int y0 = floor_clamped(uv->y() - rp, 0, height);
    const int y1 = ceil_clamped(uv->y() + rp, -1, height - 1);
    const int x0 = floor_clamped(uv->x() - rp, 0, width);
    const int x1 = ceil_clamped(uv->x() + rp, -1, width - 1);
    if (x0 > x1) return;
    for (int y = y0; y <= y1; ++y) {
      lo[static_cast<std::size_t>(y)] = std::min(lo[static_cast<std::size_t>(y)], x0);
      hi[static_cast<std::size_t>(y)] = std::max(hi[static_cast<std::size_t>(y)], x1);
    }
  };
  const Eigen::Vector3d c = probe.sphere_center_m();
  add_disc(c, probe.radius_m);
  const double step = 0.5 * probe.shaft_radius_m;
  const int n = static_cast<int>(std::ceil(probe.shaft_length_m / step));
  for (int i = 0; i <= n; ++i)
    add_disc(c + probe.axis * std::min(probe.shaft_length_m, i * step), probe.shaft_radius_m);
  for (const Eigen::Vector3d& m : probe.markers_m) add_disc(m, probe.marker_radius_m);
}

// A pixel corner's ray, the probe part it hits and the hit's camera depth.
struct Corner {
  Eigen::Vector3d d;
  int part = 0;
  double depth = kInf;
};
struct CornerLine {             // corners at (x0 - 0.5 + i, y - 0.5)
  int y = -1, x0 = 0, x1 = -1;  // pixel range whose corners it holds: x0 .. x1 + 1
  std::vector<Corner> c;
};

// Rays cast at the probe, per corner line and per pixel (ProbeLayer::render).
class ProbeCaster {
 public:
  ProbeCaster(const CameraModel& cam, const ProbeGeometry& probe)
      : probe_(probe), rc_(cam), zc_(cam.R.row(2).transpose()) {}

  // Camera depth of the hit along d_raw (+inf: none) and the part hit.
  double cast(const Eigen::Vector3d& d_raw, int& part) const {
    const Eigen::Vector3d d = d_raw.normalized();
    const double s = probe_.ray_hit(rc_.origin, d, 0.0, &part);
    return std::isfinite(s) ? s * d.dot(zc_) : kInf;
  }

  void make_line(int y, int x0, int x1, CornerLine& line) {
    line.y = y;
    line.x0 = x0;
    line.x1 = x1;
    const int count = x1 - x0 + 2;
    line.c.resize(static_cast<std::size_t>(count));
    rc_.corner_dirs(x0, y - 0.5, count, dirs_);
    for (std::size_t i = 0; i < line.c.size(); ++i) line.c[i].d = dirs_[i];
    for (Corner& corner : line.c) corner.depth = cast(corner.d, corner.part);
  }

  // The pixel with corners q (top left, top right, bottom left, bottom right): uniform when they
  // and its centre agree on the part hit, else supersampled.
  ProbeLayer::Sample sample(const Corner* const (&q)[4]) const {
    ProbeLayer::Sample out;
    int centre_part = 0;
    const Eigen::Vector3d dc = 0.25 * (q[0]->d + q[1]->d + q[2]->d + q[3]->d);
    const double centre_depth = cast(dc, centre_part);
    const bool uniform = q[0]->part == centre_part && q[1]->part == centre_part &&
                         q[2]->part == centre_part && q[3]->part == centre_part;
    if (uniform) {
      if (centre_part == ProbeGeometry::kNone) return out;
      (centre_part == ProbeGeometry::kBody ? out.body : out.marker) = 1.0f;
      out.depth = static_cast<float>(centre_depth);
      return out;
    }
    bool marker_edge = centre_part == ProbeGeometry::kMarker;
    for (const Corner* k : q) marker_edge = marker_edge || k->part == ProbeGeometry::kMarker;
    const int sub = marker_edge ? kSub : kSub / 2;
    int body = 0, marker = 0;
    double depth = kInf;
    for (int sy = 0; sy < sub; ++sy) {
      const double fy = (sy + 0.5) / sub;
      const Eigen::Vector3d left = q[0]->d + fy * (q[2]->d - q[0]->d);
      const Eigen::Vector3d right = q[1]->d + fy * (q[3]->d - q[1]->d);
      for (int sx = 0; sx < sub; ++sx) {
        const double fx = (sx + 0.5) / sub;
        int part = 0;
        const double z = cast(left + fx * (right - left), part);
        if (part == ProbeGeometry::kBody) ++body;
        if (part == ProbeGeometry::kMarker) ++marker;
        depth = std::min(depth, z);
      }
    }
    out.body = static_cast<float>(body) / static_cast<float>(sub * sub);
    out.marker = static_cast<float>(marker) / static_cast<float>(sub * sub);
    out.depth = static_cast<float>(depth);
    return out;
  }

 private:
  const ProbeGeometry& probe_;
  const RayCaster rc_;
  const Eigen::Vector3d zc_;  // camera z axis in the world
  std::vector<Eigen::Vector3d> dirs_;
};

}  // namespace

// ---- probe layer -------------------------------------------------------------------------------

void ProbeLayer::render(const CameraModel& cam, const ProbeGeometry& probe, const ProbeLook& look,
                        int width, int height) {
  grey_ = look.grey;
  marker_grey_ = look.marker_grey;
  rows_.clear();
  samples_.clear();
  row_index_.clear();
  std::vector<int> lo, hi;
  probe_row_spans(cam, probe, width, height, lo, hi);

  first_row_ = -1;
  for (int y = 0; y < height; ++y) {
    if (hi[static_cast<std::size_t>(y)] < lo[static_cast<std::size_t>(y)]) continue;
    if (first_row_ < 0) first_row_ = y;
    Row r;
    r.y = y;
    r.x0 = lo[static_cast<std::size_t>(y)];
    r.x1 = hi[static_cast<std::size_t>(y)];
    r.offset = samples_.size();
    samples_.resize(samples_.size() + static_cast<std::size_t>(r.x1 - r.x0 + 1));
    rows_.push_back(r);
  }
  if (rows_.empty()) return;
  row_index_.assign(static_cast<std::size_t>(rows_.back().y - first_row_ + 1), -1);
  for (std::size_t i = 0; i < rows_.size(); ++i)
    row_index_[static_cast<std::size_t>(rows_[i].y - first_row_)] = static_cast<int>(i);

  // Cast: pixel corners (shared between neighbours, and between rows) and centres; a pixel whose
  // five samples agree on the part hit is uniform, others are supersampled (8 x 8 when a shaft
  // marker is involved, whose centroid matters; 4 x 4 for the body's edges) with rays
  // interpolated bilinearly between the corner rays (distortion is linear across a pixel to far
  // below 1e-3 px).
  ProbeCaster caster(cam, probe);
  const auto span_of = [&](int y, int& x0, int& x1) {
    if (y < first_row_ || y > rows_.back().y) return false;
    const int ri = row_index_[static_cast<std::size_t>(y - first_row_)];
    if (ri < 0) return false;
    x0 = rows_[static_cast<std::size_t>(ri)].x0;
    x1 = rows_[static_cast<std::size_t>(ri)].x1;
    return true;
  };
  CornerLine top, bottom;
  for (const Row& r : rows_) {
    // The line above this row: the previous row's bottom line if it covers this span.
    if (bottom.y == r.y && bottom.x0 <= r.x0 && bottom.x1 >= r.x1) {
      std::swap(top, bottom);
    } else {
      int px0 = r.x0, px1 = r.x1;
      if (int a = 0, b = -1; span_of(r.y - 1, a, b)) px0 = std::min(px0, a), px1 = std::max(px1, b);
      caster.make_line(r.y, px0, px1, top);
    }
    int nx0 = r.x0, nx1 = r.x1;  // the line below: shared with the next row
    if (int a = 0, b = -1; span_of(r.y + 1, a, b)) nx0 = std::min(nx0, a), nx1 = std::max(nx1, b);
    caster.make_line(r.y + 1, nx0, nx1, bottom);
    for (int x = r.x0; x <= r.x1; ++x) {
      const std::size_t it = static_cast<std::size_t>(x - top.x0);
      const std::size_t ib = static_cast<std::size_t>(x - bottom.x0);
      const Corner* const q[4] = {&top.c[it], &top.c[it + 1], &bottom.c[ib], &bottom.c[ib + 1]};
      samples_[r.offset + static_cast<std::size_t>(x - r.x0)] = caster.sample(q);
    }
  }
}

ProbeLayer::Sample ProbeLayer::at(int x, int y) const {
  if (rows_.empty() || y < first_row_ || y > rows_.back().y) return {};
  const int ri = row_index_[static_cast<std::size_t>(y - first_row_)];
  if (ri < 0) return {};
  const Row& r = rows_[static_cast<std::size_t>(ri)];
  if (x < r.x0 || x > r.x1) return {};
  return samples_[r.offset + static_cast<std::size_t>(x - r.x0)];
}

void ProbeLayer::composite(Frame& frame) const {
  for (const Row& r : rows_) {
    std::uint8_t* row = frame.pixels.data() + static_cast<std::size_t>(r.y) * frame.stride_bytes;
    for (int x = r.x0; x <= r.x1; ++x) {
      const Sample& s = samples_[r.offset + static_cast<std::size_t>(x - r.x0)];
      const double c = s.body + s.marker;
      if (c <= 0.0) continue;
      row[x] = to_grey(s.body * grey_ + s.marker * marker_grey_ + (1.0 - c) * row[x]);
    }
  }
}

// ---- board -------------------------------------------------------------------------------------

std::vector<BoardPose> board_poses(const BoardSpec& spec, const BoardMotion& motion,
                                   const Eigen::Vector3d& center_m) {
  std::mt19937_64 rng(motion.seed * 0x9E3779B97F4A7C15ULL + 17);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double deg = std::numbers::pi / 180.0;
  std::vector<BoardPose> out;
  out.reserve(static_cast<std::size_t>(std::max(0, motion.poses)));
  for (int k = 0; k < motion.poses; ++k) {
    const double dx = (2.0 * u01(rng) - 1.0) * motion.offset_m[0];
    const double dy = (2.0 * u01(rng) - 1.0) * motion.offset_m[1];
    const double dz = motion.height_m[0] + u01(rng) * (motion.height_m[1] - motion.height_m[0]);
    const double azimuth = 2.0 * std::numbers::pi * u01(rng);
    double tilt = u01(rng) * motion.max_tilt_deg * deg;
    if (k % 4 == 3) tilt = (0.8 + 0.2 * u01(rng)) * motion.max_tilt_deg * deg;
    const double yaw = (2.0 * u01(rng) - 1.0) * motion.max_yaw_deg * deg;
    // The face's normal (towards the viewers): +z tilted towards `azimuth`.
    const Eigen::Vector3d n(std::sin(tilt) * std::cos(azimuth), std::sin(tilt) * std::sin(azimuth),
                            std::cos(tilt));
    // Board axes: z_board = -n (cameras look along +z_board); x_board starts along world +x
    // made orthogonal to n, then turns by `yaw` about n.
    const Eigen::Vector3d z = -n;
    Eigen::Vector3d x = Eigen::Vector3d::UnitX() - n * n.x();
    x.normalize();
    x = Eigen::AngleAxisd(yaw, n) * x;
    const Eigen::Vector3d y = z.cross(x);
    BoardPose p;
    p.R.col(0) = x;
    p.R.col(1) = y;
    p.R.col(2) = z;
    const Eigen::Vector3d grid_centre = center_m + Eigen::Vector3d(dx, dy, dz);
    p.t = grid_centre - p.R * spec.grid_center();
    out.push_back(p);
  }
  return out;
}

bool board_visible(const CameraModel& cam, const BoardSpec& spec, const BoardPose& pose,
                   double margin_px, double max_angle_deg) {
  // The face is seen from -z_board: the camera centre must be on that side.
  const Eigen::Vector3d to_cam = cam.center_m() - (pose.R * spec.grid_center() + pose.t);
  const Eigen::Vector3d front = -pose.R.col(2);
  const double cosang = front.dot(to_cam.normalized());
  if (!(cosang > std::cos(max_angle_deg * std::numbers::pi / 180.0))) return false;
  for (int j = 0; j < spec.rows; ++j)
    for (int i = 0; i < spec.cols; ++i) {
      const Eigen::Vector3d p = pose.R * spec.corner(i, j) + pose.t;
      const std::optional<Eigen::Vector2d> uv = cam.project(p);
      if (!uv) return false;
      if (uv->x() < margin_px || uv->y() < margin_px || uv->x() > cam.width - 1.0 - margin_px ||
          uv->y() > cam.height - 1.0 - margin_px)
        return false;
    }
  return true;
}

namespace {

// The plate (the squares and the margin around them), board frame.
struct Plate {
  double x0, x1, y0, y1;
};

Plate plate_of(const BoardSpec& spec) {
  const double s = spec.square_m;
  const double m = spec.margin_squares * s;
  return {-s - m, spec.cols * s + m, -s - m, spec.rows * s + m};
}

struct PixelBox {
  int x0 = 0, x1 = -1, y0 = 0, y1 = -1;  // inclusive; empty when x0 > x1 or y0 > y1
};

// Bounding box: the plate's outline sampled densely (distortion bends straight edges); the whole
// frame when part of the outline is behind the camera.
PixelBox plate_pixel_box(const CameraModel& cam, const BoardPose& pose, const Plate& plate, int w,
                         int h) {
  double u0 = kInf, u1 = -kInf, v0 = kInf, v1 = -kInf;
  bool behind = false;
  constexpr int kOutline = 32;
  for (int e = 0; e < 4; ++e)
    for (int k = 0; k <= kOutline; ++k) {
      const double f = static_cast<double>(k) / kOutline;
      double bx = 0.0, by = 0.0;
      switch (e) {
        case 0:
          bx = plate.x0 + f * (plate.x1 - plate.x0), by = plate.y0;
          break;
        case 1:
          bx = plate.x1, by = plate.y0 + f * (plate.y1 - plate.y0);
          break;
        case 2:
          bx = plate.x0 + f * (plate.x1 - plate.x0), by = plate.y1;
          break;
        default:
          bx = plate.x0, by = plate.y0 + f * (plate.y1 - plate.y0);
          break;
      }
      const std::optional<Eigen::Vector2d> uv =
          cam.project(pose.R * Eigen::Vector3d(bx, by, 0) + pose.t);
      if (!uv) {
        behind = true;
        continue;
      }
      u0 = std::min(u0, uv->x()), u1 = std::max(u1, uv->x());
      v0 = std::min(v0, uv->y()), v1 = std::max(v1, uv->y());
    }
  if (behind) return {0, w - 1, 0, h - 1};
  return {floor_clamped(u0 - 2.0, 0, w), ceil_clamped(u1 + 2.0, -1, w - 1),
          floor_clamped(v0 - 2.0, 0, h), ceil_clamped(v1 + 2.0, -1, h - 1)};
}

// Where rays through the image meet the board and what they see there (render_board).
class BoardHits {
 public:
  BoardHits(const CameraModel& cam, const BoardSpec& spec, const BoardPose& pose,
            const Plate& plate)
      : rc(cam),
        spec_(spec),
        plate_(plate),
        Rt_(pose.R.transpose()),
        o_b_(Rt_ * (rc.origin - pose.t)) {}

  // Board coordinates of a ray's hit with the plane z_board = 0 (nan when parallel or behind).
  Eigen::Vector2d plane(const Eigen::Vector3d& d_w) const {
    const Eigen::Vector3d d = Rt_ * d_w;
    if (!(d.z() > 1e-12)) return {NAN, NAN};  // o_b.z < 0 (front side): rays must go +z
    const double t = -o_b_.z() / d.z();
    if (!(t > 0.0)) return {NAN, NAN};
    return {o_b_.x() + t * d.x(), o_b_.y() + t * d.y()};
  }

  // Colour class: -1 off the plate, 0 white (margin or white square), 1 black; `cell` identifies
  // the region so uniform pixels can be told apart from edge pixels.
  int classify(const Eigen::Vector2d& b, long& cell) const {
    if (!(b.x() >= plate_.x0 && b.x() < plate_.x1 && b.y() >= plate_.y0 && b.y() < plate_.y1)) {
      cell = -1;
      return -1;
    }
    const double s = spec_.square_m;
    const double a = std::floor(b.x() / s), c = std::floor(b.y() / s);
    if (a < -1 || c < -1 || a > spec_.cols - 1 || c > spec_.rows - 1) {
      cell = -2;  // the white margin
      return 0;
    }
    cell = static_cast<long>((a + 1) * 1000 + (c + 1));
    return (static_cast<long>(a + c) % 2 == 0) ? 1 : 0;
  }

  // Hits and cells of the pixel corners (x0 - 0.5 + i, v), i < pts.size() (rays as
  // RayCaster::corner_dirs).
  void corner_row(int x0, double v, std::vector<Eigen::Vector2d>& pts, std::vector<long>& cells) {
    const int count = static_cast<int>(pts.size());
    rc.corner_dirs(x0, v, count, dirs_);
    for (int i = 0; i < count; ++i) {
      pts[static_cast<std::size_t>(i)] = plane(dirs_[static_cast<std::size_t>(i)]);
      classify(pts[static_cast<std::size_t>(i)], cells[static_cast<std::size_t>(i)]);
    }
  }

  const RayCaster rc;

 private:
  const BoardSpec& spec_;
  const Plate plate_;
  const Eigen::Matrix3d Rt_;
  const Eigen::Vector3d o_b_;
  std::vector<Eigen::Vector3d> dirs_;
};

// Pixel (x, y) from its corners' hits q and cells (top left, top right, bottom left, bottom
// right) over its grey `pixel`; false when the board does not cover it.
bool shade_board_pixel(const BoardHits& hits, const BoardSpec& spec, int x, int y,
                       const Eigen::Vector2d* const (&q)[4], const long (&cells)[4],
                       std::uint8_t& pixel) {
  const double black = spec.black, white = spec.white;
  const bool finite = std::isfinite(q[0]->x()) && std::isfinite(q[1]->x()) &&
                      std::isfinite(q[2]->x()) && std::isfinite(q[3]->x());
  const long c0 = cells[0];
  if (finite && c0 == cells[1] && c0 == cells[2] && c0 == cells[3]) {
    if (c0 == -1) return false;  // off the plate
    long cell = 0;
    const int cls = hits.classify(0.25 * (*q[0] + *q[1] + *q[2] + *q[3]), cell);
    if (cls < 0) return false;
    pixel = to_grey(cls == 1 ? black : white);
    return true;
  }
  // Edge pixel: 8 x 8 samples (board coordinates interpolated bilinearly between the corner
  // hits, or cast per sample when a corner missed the plane).
  double sum = 0.0;
  int on_plate = 0;
  for (int sy = 0; sy < kSub; ++sy) {
    const double fy = (sy + 0.5) / kSub;
    for (int sx = 0; sx < kSub; ++sx) {
      const double fx = (sx + 0.5) / kSub;
      Eigen::Vector2d b;
      if (finite) {
        const Eigen::Vector2d l = *q[0] + fy * (*q[2] - *q[0]);
        const Eigen::Vector2d r = *q[1] + fy * (*q[3] - *q[1]);
        b = l + fx * (r - l);
      } else {
        b = hits.plane(hits.rc.dir(x - 0.5 + fx, y - 0.5 + fy));
      }
      long cell = 0;
      const int cls = hits.classify(b, cell);
      if (cls < 0) continue;
      ++on_plate;
      sum += cls == 1 ? black : white;
    }
  }
  if (on_plate == 0) return false;
  const double n = kSub * kSub;
  pixel = to_grey(sum / n + (n - on_plate) / n * pixel);
  return true;
}

}  // namespace

std::size_t render_board(const CameraModel& cam, const BoardSpec& spec, const BoardPose& pose,
                         Frame& frame) {
  const Eigen::Vector3d centre_w = pose.R * spec.grid_center() + pose.t;
  const Eigen::Vector3d front = -pose.R.col(2);
  if (!(front.dot(cam.center_m() - centre_w) > 0.0)) return 0;  // seen from behind
  const Plate plate = plate_of(spec);
  const PixelBox box = plate_pixel_box(cam, pose, plate, static_cast<int>(frame.width),
                                       static_cast<int>(frame.height));
  if (box.x0 > box.x1 || box.y0 > box.y1) return 0;

  BoardHits hits(cam, spec, pose, plate);
  std::size_t touched = 0;
  const std::size_t cw = static_cast<std::size_t>(box.x1 - box.x0 + 2);
  std::vector<Eigen::Vector2d> top(cw), bottom(cw);
  std::vector<long> top_cell(cw), bottom_cell(cw);
  hits.corner_row(box.x0, box.y0 - 0.5, top, top_cell);
  for (int y = box.y0; y <= box.y1; ++y) {
    hits.corner_row(box.x0, y + 0.5, bottom, bottom_cell);
    std::uint8_t* row = frame.pixels.data() + static_cast<std::size_t>(y) * frame.stride_bytes;
    for (int x = box.x0; x <= box.x1; ++x) {
      const std::size_t i = static_cast<std::size_t>(x - box.x0);
      const Eigen::Vector2d* const q[4] = {&top[i], &top[i + 1], &bottom[i], &bottom[i + 1]};
      const long cells[4] = {top_cell[i], top_cell[i + 1], bottom_cell[i], bottom_cell[i + 1]};
      if (shade_board_pixel(hits, spec, x, y, q, cells, row[x])) ++touched;
    }
    std::swap(top, bottom);
    std::swap(top_cell, bottom_cell);
  }
  return touched;
}

}  // namespace hc::devices::sim
