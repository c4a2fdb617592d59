#include "fabrication/abstraction/calibration_part.h"

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>

#include "geometry/booleans.h"

namespace hc::abstraction {
namespace {

constexpr std::size_t kMaxEntries = 20;

TriangleMesh box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  TriangleMesh m;
  m.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i) {
    m.vertices.row(i) << ((i & 1) ? hi.x() : lo.x()), ((i & 2) ? hi.y() : lo.y()),
        ((i & 4) ? hi.z() : lo.z());
  }
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0,
      6, 2, 1, 3, 7, 1, 7, 5;
  return m;
}

// A closed prism around the axis from `base` along unit `axis` for `length`, radius r.
TriangleMesh cylinder(const Eigen::Vector3d& base, const Eigen::Vector3d& axis, double length,
                      double r, int n) {
  const Eigen::Vector3d u = axis.unitOrthogonal(), v = axis.cross(u);
  TriangleMesh m;
  m.vertices.resize(2 * n + 2, 3);
  for (int i = 0; i < n; ++i) {
    const double t = 2 * std::numbers::pi * i / n;
    const Eigen::Vector3d p = base + r * (std::cos(t) * u + std::sin(t) * v);
    m.vertices.row(i) = p.transpose();
    m.vertices.row(n + i) = (p + length * axis).transpose();
  }
  m.vertices.row(2 * n) = base.transpose();
  m.vertices.row(2 * n + 1) = (base + length * axis).transpose();
  m.triangles.resize(4 * n, 3);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.triangles.row(4 * i) << i, j, n + j;  // u, v, axis right-handed: outward side walls
    m.triangles.row(4 * i + 1) << i, n + j, n + i;
    m.triangles.row(4 * i + 2) << 2 * n, j, i;  // bottom cap faces -axis
    m.triangles.row(4 * i + 3) << 2 * n + 1, n + i, n + j;
  }
  return m;
}

void append(TriangleMesh* to, const TriangleMesh& m) {
  const auto nv = to->num_vertices(), nt = to->num_triangles();
  to->vertices.conservativeResize(nv + m.num_vertices(), 3);
  to->vertices.bottomRows(m.num_vertices()) = m.vertices;
  to->triangles.conservativeResize(nt + m.num_triangles(), 3);
  to->triangles.bottomRows(m.num_triangles()) = m.triangles.array() + static_cast<int>(nv);
}

}  // namespace

Status CalibrationPartOptions::validate() const {
  const auto check = [](const std::vector<double>& v, std::string_view what) -> Status {
    if (v.empty() || v.size() > kMaxEntries) {
      return invalid_argument(
          fmt::format("calibration part: 1 to {} {} needed, got {}", kMaxEntries, what, v.size()));
    }
    for (const double x : v) {
      if (!(x > 0) || !std::isfinite(x))
        return invalid_argument(fmt::format("calibration part: {} must be > 0", what));
    }
    return {};
  };
  HC_RETURN_IF_ERROR(check(depths, "depths"));
  HC_RETURN_IF_ERROR(check(diameters, "diameters"));
  if (segments < 8 || segments > 512)
    return invalid_argument("calibration part: segments must be in [8, 512]");
  return {};
}

Result<std::vector<double>> parse_range(std::string_view text, std::string_view what) {
  const auto number = [&](std::string_view s) -> Result<double> {
    double v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || p != s.data() + s.size() || !(v > 0) || !std::isfinite(v)) {
      return invalid_argument(fmt::format("{}: \"{}\" is not a positive number", what, s));
    }
    return v;
  };
  std::vector<double> out;
  if (text.find(':') != std::string_view::npos) {
    const auto c1 = text.find(':'), c2 = text.find(':', c1 + 1);
    if (c2 == std::string_view::npos)
      return invalid_argument(fmt::format("{}: expected A:B:STEP, got \"{}\"", what, text));
    HC_ASSIGN_OR_RETURN(double a, number(text.substr(0, c1)));
    HC_ASSIGN_OR_RETURN(double b, number(text.substr(c1 + 1, c2 - c1 - 1)));
    HC_ASSIGN_OR_RETURN(double step, number(text.substr(c2 + 1)));
    if (b < a) return invalid_argument(fmt::format("{}: {} > {}", what, a, b));
    const double count = std::floor((b - a) / step + 1e-9) + 1;
    if (count > kMaxEntries)
      return invalid_argument(fmt::format("{}: more than {} values", what, kMaxEntries));
    for (int i = 0; i < static_cast<int>(count); ++i) out.push_back(a + i * step);
  } else {
    std::size_t start = 0;
    while (start <= text.size()) {
      const auto comma = std::min(text.find(',', start), text.size());
      HC_ASSIGN_OR_RETURN(double v, number(text.substr(start, comma - start)));
      out.push_back(v);
      start = comma + 1;
    }
    if (out.size() > kMaxEntries)
      return invalid_argument(fmt::format("{}: more than {} values", what, kMaxEntries));
  }
  return out;
}

Result<CalibrationPart> calibration_part(const CalibrationPartOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const double dmax = *std::max_element(options.diameters.begin(), options.diameters.end());
  const double dmin = *std::min_element(options.diameters.begin(), options.diameters.end());
  const double hmax = *std::max_element(options.depths.begin(), options.depths.end());
  const auto rows = static_cast<int>(options.depths.size());
  const auto cols = static_cast<int>(options.diameters.size());
  const double pitch = 2.0 * dmax;
  const double pit = std::max(0.5 * dmin, 0.02 * pitch);      // tally pit edge and depth
  const double label = (std::max(rows, cols) + 1) * 2 * pit;  // room for the longest tally
  // Grid (with its labels) centred on each face, kept hmax + margin away from the other faces so
  // that intrusions of different faces never meet.
  const double grid = label + std::max(rows, cols) * pitch;
  const double margin = hmax + pitch;
  CalibrationPart part;
  part.size = grid + 2 * margin;
  const double s = part.size;
  TriangleMesh cutters;
  // Local face frame: origin on the face, (e1, e2) in the face, n the inward normal.
  struct Face {
    Eigen::Vector3d origin, e1, e2, n;
    const char* name;
  };
  const Face faces[3] = {{{0, 0, s}, {1, 0, 0}, {0, 1, 0}, {0, 0, -1}, "top"},
                         {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}, "front"},
                         {{s, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, "right"}};
  const double over = 0.5 * pitch;  // cutters start this far outside the face
  for (const Face& f : faces) {
    const auto at = [&](double a, double b) { return f.origin + a * f.e1 + b * f.e2; };
    const double g0 = margin + label;  // first hole centre is at g0 + pitch / 2
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < cols; ++j) {
        const Eigen::Vector3d c = at(g0 + (j + 0.5) * pitch, g0 + (i + 0.5) * pitch);
        append(&cutters,
               cylinder(c - over * f.n, f.n, over + options.depths[static_cast<std::size_t>(i)],
                        0.5 * options.diameters[static_cast<std::size_t>(j)], options.segments));
      }
      for (int k = 0; k <= i; ++k) {  // row tally, right-aligned towards the grid
        const Eigen::Vector3d c = at(g0 - (k + 1) * 2 * pit, g0 + (i + 0.5) * pitch);
        const Eigen::Vector3d h = 0.5 * pit * (f.e1 + f.e2);
        const Eigen::Vector3d lo = (c - h - over * f.n).cwiseMin(c + h + pit * f.n);
        const Eigen::Vector3d hi = (c - h - over * f.n).cwiseMax(c + h + pit * f.n);
        append(&cutters, box(lo, hi));
      }
    }
    for (int j = 0; j < cols; ++j) {
      for (int k = 0; k <= j; ++k) {  // column tally, below the grid (towards the face's edge)
        const Eigen::Vector3d c = at(g0 + (j + 0.5) * pitch, g0 - (k + 1) * 2 * pit);
        const Eigen::Vector3d h = 0.5 * pit * (f.e1 + f.e2);
        const Eigen::Vector3d lo = (c - h - over * f.n).cwiseMin(c + h + pit * f.n);
        const Eigen::Vector3d hi = (c - h - over * f.n).cwiseMax(c + h + pit * f.n);
        append(&cutters, box(lo, hi));
      }
    }
  }
  for (int i = 0; i < rows; ++i)
    part.legend.push_back(fmt::format("row {} ({} pits): depth {}", i + 1, i + 1,
                                      options.depths[static_cast<std::size_t>(i)]));
  for (int j = 0; j < cols; ++j)
    part.legend.push_back(fmt::format("column {} ({} pits): diameter {}", j + 1, j + 1,
                                      options.diameters[static_cast<std::size_t>(j)]));
  HC_ASSIGN_OR_RETURN(part.mesh,
                      geometry::corefine_boolean(box({0, 0, 0}, {s, s, s}), cutters,
                                                 geometry::BooleanOperation::kDifference));
  return part;
}

}  // namespace hc::abstraction
