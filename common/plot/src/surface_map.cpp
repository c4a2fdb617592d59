#include "plot/surface_map.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "cairo_canvas.h"
#include "common/file_io.h"

namespace hc::plot {
namespace {

using detail::Align;
using Vec3 = std::array<double, 3>;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 normalized(const Vec3& a) {
  const double n = std::sqrt(dot(a, a));
  return {a[0] / n, a[1] / n, a[2] / n};
}

// An orthographic camera looking along `forward`; "up" is the world axis least aligned with it
// (y before x before z on ties, so a view along -z is the usual plan view, +y up).
struct View {
  Vec3 right, up, forward;
  explicit View(const Vec3& direction) {
    forward = normalized(direction);
    const std::array<Vec3, 3> axes{{{0, 1, 0}, {1, 0, 0}, {0, 0, 1}}};
    Vec3 world_up = axes[0];
    double best = 2;
    for (const Vec3& a : axes)
      if (std::abs(dot(a, forward)) < best - 1e-12) {
        best = std::abs(dot(a, forward));
        world_up = a;
      }
    right = normalized(cross(forward, world_up));
    up = cross(right, forward);
  }
};

void draw_colour_bar(cairo_t* cr, double x, double top, double bottom, double lo, double hi,
                     const std::string& label, double font) {
  const double w = 1.1 * font;
  cairo_pattern_t* g = cairo_pattern_create_linear(0, bottom, 0, top);
  for (int k = 0; k <= 16; ++k) {
    const Rgb c = viridis(k / 16.0);
    cairo_pattern_add_color_stop_rgb(g, k / 16.0, c.r, c.g, c.b);
  }
  cairo_rectangle(cr, x, top, w, bottom - top);
  cairo_set_source(cr, g);
  cairo_fill(cr);
  cairo_pattern_destroy(g);
  detail::set_color(cr, Rgb{0.15, 0.15, 0.15});
  cairo_set_line_width(cr, 1.0);
  cairo_rectangle(cr, x + 0.5, top + 0.5, w, bottom - top);
  cairo_stroke(cr);
  const Ticks t = nice_ticks(lo, hi, 6);
  detail::set_font(cr, font);
  for (double v : t.values) {
    if (v < lo - 1e-12 * (hi - lo) || v > hi + 1e-12 * (hi - lo)) continue;
    const double y = bottom - (v - lo) / (hi - lo) * (bottom - top);
    cairo_move_to(cr, x + w, y);
    cairo_line_to(cr, x + w + 0.35 * font, y);
    cairo_stroke(cr);
    detail::draw_text(cr, format_tick(v, t.decimals), x + w + 0.55 * font, y, Align::kStart,
                      Align::kCentre);
  }
  detail::set_font(cr, 1.08 * font);
  detail::draw_text(cr, label, x + w + 4.6 * font, 0.5 * (top + bottom), Align::kCentre,
                    Align::kStart, -std::numbers::pi / 2);
}

// A bar of a nice length with its value, bottom left of the map.
void draw_scale_bar(cairo_t* cr, double x, double y, double pixels_per_unit, double max_px,
                    const std::string& unit, double font) {
  const Ticks t = nice_ticks(0, max_px / pixels_per_unit, 4);
  const double len = t.step;
  const double px = len * pixels_per_unit;
  detail::set_color(cr, Rgb{0.15, 0.15, 0.15});
  cairo_set_line_width(cr, 2.0);
  cairo_move_to(cr, x, y);
  cairo_line_to(cr, x + px, y);
  cairo_stroke(cr);
  detail::set_font(cr, font);
  detail::draw_text(cr, format_tick(len, t.decimals) + (unit.empty() ? "" : " " + unit),
                    x + 0.5 * px, y + 0.35 * font, Align::kCentre, Align::kStart);
}

}  // namespace

Rgb viridis(double t) {
  // matplotlib's viridis sampled at k/9, k = 0..9 (its published colour table), interpolated
  // linearly in between.
  static constexpr std::array<Rgb, 10> kStops{{{0x44 / 255., 0x01 / 255., 0x54 / 255.},
                                               {0x48 / 255., 0x28 / 255., 0x78 / 255.},
                                               {0x3e / 255., 0x49 / 255., 0x89 / 255.},
                                               {0x31 / 255., 0x68 / 255., 0x8e / 255.},
                                               {0x26 / 255., 0x82 / 255., 0x8e / 255.},
                                               {0x1f / 255., 0x9e / 255., 0x89 / 255.},
                                               {0x35 / 255., 0xb7 / 255., 0x79 / 255.},
                                               {0x6e / 255., 0xce / 255., 0x58 / 255.},
                                               {0xb5 / 255., 0xde / 255., 0x2b / 255.},
                                               {0xfd / 255., 0xe7 / 255., 0x25 / 255.}}};
  if (!(t > 0)) return kStops.front();  // also NaN
  if (t >= 1) return kStops.back();
  const double s = t * (kStops.size() - 1);
  const auto i = static_cast<std::size_t>(s);
  const double f = s - static_cast<double>(i);
  const Rgb& a = kStops[i];
  const Rgb& b = kStops[i + 1];
  return {a.r + f * (b.r - a.r), a.g + f * (b.g - a.g), a.b + f * (b.b - a.b)};
}

Status SurfaceMap::validate() const {
  const std::string where = "surface map '" + title + "'";
  if (triangles.empty()) return invalid_argument(where + ": no triangles");
  if (values.size() != vertices.size())
    return invalid_argument(where + ": " + std::to_string(values.size()) + " values for " +
                            std::to_string(vertices.size()) + " vertices");
  for (std::size_t i = 0; i < vertices.size(); ++i)
    for (double c : vertices[i])
      if (!std::isfinite(c))
        return invalid_argument(where + ": vertex " + std::to_string(i) + " is not finite");
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
      return invalid_argument(where + ": value " + std::to_string(i) + " is not finite");
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (int v : triangles[t])
      if (v < 0 || static_cast<std::size_t>(v) >= vertices.size())
        return invalid_argument(where + ": triangle " + std::to_string(t) + " names vertex " +
                                std::to_string(v) + " (there are " +
                                std::to_string(vertices.size()) + ")");
  for (const auto& m : marks)
    for (double c : m)
      if (!std::isfinite(c)) return invalid_argument(where + ": a mark is not finite");
  if (!(dot(view_direction, view_direction) > 0) ||
      !std::isfinite(dot(view_direction, view_direction)))
    return invalid_argument(where + ": the view direction must be a non-zero finite vector");
  if ((value_min && !std::isfinite(*value_min)) || (value_max && !std::isfinite(*value_max)))
    return invalid_argument(where + ": non-finite colour scale end");
  return {};
}

Result<std::string> render_surface_map(const SurfaceMap& map, ImageFormat format,
                                       const RenderOptions& options) {
  HC_RETURN_IF_ERROR(map.validate());
  HC_ASSIGN_OR_RETURN(std::unique_ptr<detail::Canvas> canvas,
                      detail::Canvas::create(format, options.width_px, options.height_px));
  cairo_t* cr = canvas->cr();
  const double font = options.font_size;
  const View view(map.view_direction);

  // Projected coordinates and their box.
  std::vector<std::array<double, 2>> uv(map.vertices.size());
  double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300;
  for (std::size_t i = 0; i < map.vertices.size(); ++i) {
    uv[i] = {dot(map.vertices[i], view.right), dot(map.vertices[i], view.up)};
    u0 = std::min(u0, uv[i][0]);
    u1 = std::max(u1, uv[i][0]);
    v0 = std::min(v0, uv[i][1]);
    v1 = std::max(v1, uv[i][1]);
  }
  double lo = map.value_min.value_or(*std::min_element(map.values.begin(), map.values.end()));
  double hi = map.value_max.value_or(*std::max_element(map.values.begin(), map.values.end()));
  if (!(hi > lo)) hi = lo + (lo == 0 ? 1.0 : 0.1 * std::abs(lo));

  const double left = 1.5 * font, top = (map.title.empty() ? 1.0 : 2.8) * font;
  const double bar_x = options.width_px - 8.5 * font;
  const double right = bar_x - 2.0 * font, bottom = options.height_px - 3.2 * font;
  if (right - left < 40 || bottom - top < 40)
    return invalid_argument("image too small for the surface map");
  const double du = std::max(u1 - u0, 1e-300), dv = std::max(v1 - v0, 1e-300);
  const double scale = std::min((right - left) / du, (bottom - top) / dv);
  const double ox = left + 0.5 * ((right - left) - scale * du);
  const double oy = top + 0.5 * ((bottom - top) - scale * dv);
  const auto page = [&](const std::array<double, 2>& p) {
    return std::array<double, 2>{ox + (p[0] - u0) * scale, oy + (v1 - p[1]) * scale};
  };

  // Back to front: painter's order by the triangles' mean depth along the view.
  std::vector<std::size_t> order(map.triangles.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> depth(map.triangles.size());
  for (std::size_t t = 0; t < map.triangles.size(); ++t) {
    const auto& tri = map.triangles[t];
    depth[t] = dot(map.vertices[tri[0]], view.forward) + dot(map.vertices[tri[1]], view.forward) +
               dot(map.vertices[tri[2]], view.forward);
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return depth[a] > depth[b]; });
  // Cairo's mesh patches interpolate colours linearly between their corners, which between two
  // far-apart values is not the colour map (purple to yellow through brown instead of through
  // viridis' blues and greens). So each triangle is split into sub-triangles spanning at most
  // kMaxSpan of the colour range, whose corners carry the map's exact colours.
  constexpr double kMaxSpan = 1.0 / 48.0;
  constexpr int kMaxSplits = 64;
  cairo_pattern_t* mesh = cairo_pattern_create_mesh();
  const auto patch = [&](const std::array<std::array<double, 2>, 3>& p,
                         const std::array<double, 3>& v) {
    cairo_mesh_pattern_begin_patch(mesh);
    cairo_mesh_pattern_move_to(mesh, p[0][0], p[0][1]);
    cairo_mesh_pattern_line_to(mesh, p[1][0], p[1][1]);
    cairo_mesh_pattern_line_to(mesh, p[2][0], p[2][1]);
    for (unsigned k = 0; k < 3; ++k) {
      const Rgb c = viridis((v[k] - lo) / (hi - lo));
      cairo_mesh_pattern_set_corner_color_rgb(mesh, k, c.r, c.g, c.b);
    }
    cairo_mesh_pattern_end_patch(mesh);
  };
  for (std::size_t t : order) {
    const auto& tri = map.triangles[t];
    std::array<std::array<double, 2>, 3> p;
    std::array<double, 3> v;
    for (int k = 0; k < 3; ++k) {
      p[k] = page(uv[static_cast<std::size_t>(tri[k])]);
      v[k] = map.values[static_cast<std::size_t>(tri[k])];
    }
    const double span =
        (*std::max_element(v.begin(), v.end()) - *std::min_element(v.begin(), v.end())) / (hi - lo);
    const int n = std::clamp(static_cast<int>(std::ceil(span / kMaxSpan)), 1, kMaxSplits);
    // Barycentric grid: point (i, j) = p0 + i/n (p1 - p0) + j/n (p2 - p0), likewise the value.
    const auto at = [&](int i, int j) {
      const double a = static_cast<double>(i) / n, b = static_cast<double>(j) / n;
      return std::pair<std::array<double, 2>, double>{
          {p[0][0] + a * (p[1][0] - p[0][0]) + b * (p[2][0] - p[0][0]),
           p[0][1] + a * (p[1][1] - p[0][1]) + b * (p[2][1] - p[0][1])},
          v[0] + a * (v[1] - v[0]) + b * (v[2] - v[0])};
    };
    for (int i = 0; i < n; ++i)
      for (int j = 0; i + j < n; ++j) {
        const auto q0 = at(i, j), q1 = at(i + 1, j), q2 = at(i, j + 1);
        patch({q0.first, q1.first, q2.first}, {q0.second, q1.second, q2.second});
        if (i + j + 1 < n) {
          const auto q3 = at(i + 1, j + 1);
          patch({q1.first, q3.first, q2.first}, {q1.second, q3.second, q2.second});
        }
      }
  }
  cairo_set_source(cr, mesh);
  cairo_rectangle(cr, left, top, right - left, bottom - top);
  cairo_fill(cr);
  cairo_pattern_destroy(mesh);

  for (const Vec3& m : map.marks) {
    const auto p = page({dot(m, view.right), dot(m, view.up)});
    cairo_new_sub_path(cr);
    cairo_arc(cr, p[0], p[1], 4.0, 0, 2 * std::numbers::pi);
    detail::set_color(cr, Rgb{0, 0, 0});
    cairo_fill_preserve(cr);
    detail::set_color(cr, Rgb{1, 1, 1});
    cairo_set_line_width(cr, 1.5);
    cairo_stroke(cr);
  }

  draw_colour_bar(cr, bar_x, top, bottom, lo, hi, map.value_label, font);
  draw_scale_bar(cr, left, bottom + 1.2 * font, scale, 0.4 * (right - left), map.axis_unit, font);
  detail::set_color(cr, Rgb{0.1, 0.1, 0.1});
  detail::set_font(cr, 1.25 * font, true);
  detail::draw_text(cr, map.title, 0.5 * options.width_px, 0.7 * font, Align::kCentre,
                    Align::kStart);
  return canvas->finish();
}

Status write_surface_map(const SurfaceMap& map, const std::filesystem::path& path,
                         const RenderOptions& options) {
  const std::optional<ImageFormat> format = image_format_of(path);
  if (!format)
    return invalid_argument(path.string() + ": unknown image format (expected .png or .svg)");
  HC_ASSIGN_OR_RETURN(std::string bytes, render_surface_map(map, *format, options));
  return write_file_atomic(path, bytes);
}

}  // namespace hc::plot
