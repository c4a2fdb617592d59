#include "plot/chart.h"

#include <fmt/format.h>
#include <numbers>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <limits>

#include "cairo_canvas.h"
#include "common/file_io.h"

namespace hc::plot {
namespace {

using detail::Align;

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return lo > hi; }
};

// Heckbert's nice number: 1, 2, 5 or 10 times a power of ten near x (rounded or the next above).
double nice_number(double x, bool round) {
  const double e = std::floor(std::log10(x));
  const double f = x / std::pow(10.0, e);
  double nf;
  if (round)
    nf = f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10;
  else
    nf = f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10;
  return nf * std::pow(10.0, e);
}

// The axis' drawn interval and its ticks.
struct AxisLayout {
  double lo = 0, hi = 1;
  Ticks ticks;
};

AxisLayout layout_axis(const Axis& axis, Range data) {
  if (axis.include_zero) data.add(0.0);
  if (data.empty()) data = Range{0.0, 1.0};
  const double lo = axis.min.value_or(data.lo);
  const double hi = axis.max.value_or(data.hi);
  AxisLayout l;
  l.ticks = nice_ticks(lo, hi);
  l.lo = axis.min ? *axis.min : l.ticks.values.front();
  l.hi = axis.max ? *axis.max : l.ticks.values.back();
  // Fixed ends keep only the ticks inside them.
  const double eps = 1e-9 * (l.hi - l.lo);
  std::erase_if(l.ticks.values, [&](double v) { return v < l.lo - eps || v > l.hi + eps; });
  return l;
}

void draw_marker(cairo_t* cr, MarkerStyle m, double x, double y, double r) {
  switch (m) {
    case MarkerStyle::kNone:
      return;
    case MarkerStyle::kCircle:
      cairo_new_sub_path(cr);
      cairo_arc(cr, x, y, r, 0, 2 * std::numbers::pi);
      cairo_fill(cr);
      return;
    case MarkerStyle::kSquare:
      cairo_rectangle(cr, x - r, y - r, 2 * r, 2 * r);
      cairo_fill(cr);
      return;
    case MarkerStyle::kTriangle:
      cairo_move_to(cr, x, y - 1.2 * r);
      cairo_line_to(cr, x + 1.1 * r, y + 0.8 * r);
      cairo_line_to(cr, x - 1.1 * r, y + 0.8 * r);
      cairo_close_path(cr);
      cairo_fill(cr);
      return;
    case MarkerStyle::kDiamond:
      cairo_move_to(cr, x, y - 1.3 * r);
      cairo_line_to(cr, x + 1.1 * r, y);
      cairo_line_to(cr, x, y + 1.3 * r);
      cairo_line_to(cr, x - 1.1 * r, y);
      cairo_close_path(cr);
      cairo_fill(cr);
      return;
    case MarkerStyle::kCross:
      cairo_move_to(cr, x - r, y - r);
      cairo_line_to(cr, x + r, y + r);
      cairo_move_to(cr, x + r, y - r);
      cairo_line_to(cr, x - r, y + r);
      cairo_save(cr);
      cairo_set_line_width(cr, 1.6);
      cairo_stroke(cr);
      cairo_restore(cr);
      return;
  }
}

void set_dash(cairo_t* cr, LineStyle s, double width) {
  const std::array<double, 2> dashed{4.0 * width, 2.5 * width};
  const std::array<double, 2> dotted{0.8 * width, 2.0 * width};
  if (s == LineStyle::kDashed)
    cairo_set_dash(cr, dashed.data(), 2, 0);
  else if (s == LineStyle::kDotted)
    cairo_set_dash(cr, dotted.data(), 2, 0);
  else
    cairo_set_dash(cr, nullptr, 0, 0);
}

Rgb series_color(const Series& s, std::size_t i) { return s.color.value_or(palette_color(i)); }

// The plot rectangle and the data → page transform.
struct Frame {
  double left = 0, top = 0, right = 0, bottom = 0;
  AxisLayout x, y;
  double px(double v) const { return left + (v - x.lo) / (x.hi - x.lo) * (right - left); }
  double py(double v) const { return bottom - (v - y.lo) / (y.hi - y.lo) * (bottom - top); }
};

void draw_frame(cairo_t* cr, const Chart& chart, const Frame& f, double font, bool categorical_x) {
  // Grid.
  cairo_set_line_width(cr, 1.0);
  detail::set_color(cr, Rgb{0.88, 0.88, 0.88});
  for (double v : f.y.ticks.values) {
    cairo_move_to(cr, f.left, std::round(f.py(v)) + 0.5);
    cairo_line_to(cr, f.right, std::round(f.py(v)) + 0.5);
  }
  if (!categorical_x)
    for (double v : f.x.ticks.values) {
      cairo_move_to(cr, std::round(f.px(v)) + 0.5, f.top);
      cairo_line_to(cr, std::round(f.px(v)) + 0.5, f.bottom);
    }
  cairo_stroke(cr);
  // Box and tick labels.
  detail::set_color(cr, Rgb{0.15, 0.15, 0.15});
  cairo_rectangle(cr, f.left + 0.5, f.top + 0.5, f.right - f.left, f.bottom - f.top);
  cairo_stroke(cr);
  detail::set_font(cr, font);
  for (double v : f.y.ticks.values)
    detail::draw_text(cr, format_tick(v, f.y.ticks.decimals), f.left - 0.5 * font, f.py(v),
                      Align::kEnd, Align::kCentre);
  if (!categorical_x)
    for (double v : f.x.ticks.values)
      detail::draw_text(cr, format_tick(v, f.x.ticks.decimals), f.px(v), f.bottom + 0.45 * font,
                        Align::kCentre, Align::kStart);
  // Axis labels and title.
  detail::set_font(cr, 1.08 * font);
  detail::draw_text(cr, chart.x.label, 0.5 * (f.left + f.right), f.bottom + 2.1 * font,
                    Align::kCentre, Align::kStart);
  detail::draw_text(cr, chart.y.label, 0.9 * font, 0.5 * (f.top + f.bottom), Align::kCentre,
                    Align::kStart, -std::numbers::pi / 2);
  detail::set_font(cr, 1.25 * font, true);
  detail::draw_text(cr, chart.title, 0.5 * (f.left + f.right), 0.7 * font, Align::kCentre,
                    Align::kStart);
}

void draw_series(cairo_t* cr, const Chart& chart, const Frame& f) {
  cairo_save(cr);
  cairo_rectangle(cr, f.left, f.top, f.right - f.left, f.bottom - f.top);
  cairo_clip(cr);
  for (std::size_t i = 0; i < chart.series.size(); ++i) {
    const Series& s = chart.series[i];
    detail::set_color(cr, series_color(s, i));
    if (s.line != LineStyle::kNone && s.x.size() > 1) {
      cairo_set_line_width(cr, s.line_width_pt);
      cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
      set_dash(cr, s.line, s.line_width_pt);
      for (std::size_t k = 0; k < s.x.size(); ++k) {
        if (k == 0)
          cairo_move_to(cr, f.px(s.x[k]), f.py(s.y[k]));
        else
          cairo_line_to(cr, f.px(s.x[k]), f.py(s.y[k]));
      }
      cairo_stroke(cr);
      set_dash(cr, LineStyle::kSolid, 1);
    }
    for (std::size_t k = 0; k < s.x.size(); ++k)
      draw_marker(cr, s.marker, f.px(s.x[k]), f.py(s.y[k]), 3.2);
  }
  cairo_restore(cr);
}

void draw_bars(cairo_t* cr, const Chart& chart, const Frame& f, double font) {
  const double slot = (f.right - f.left) / static_cast<double>(chart.bars.size());
  detail::set_font(cr, font);
  double widest = 0;
  for (const Bar& b : chart.bars) widest = std::max(widest, detail::text_width(cr, b.label));
  const bool slanted = widest > 0.95 * slot;
  for (std::size_t i = 0; i < chart.bars.size(); ++i) {
    const Bar& b = chart.bars[i];
    const double cx = f.left + (static_cast<double>(i) + 0.5) * slot;
    const double y0 = f.py(std::clamp(0.0, f.y.lo, f.y.hi));
    const double y1 = f.py(b.value);
    detail::set_color(cr, b.color.value_or(palette_color(0)));
    cairo_rectangle(cr, cx - 0.32 * slot, std::min(y0, y1), 0.64 * slot, std::abs(y1 - y0));
    cairo_fill(cr);
    detail::set_color(cr, Rgb{0.15, 0.15, 0.15});
    if (slanted)
      detail::draw_text(cr, b.label, cx, f.bottom + 0.45 * font, Align::kEnd, Align::kCentre,
                        -std::numbers::pi / 6);
    else
      detail::draw_text(cr, b.label, cx, f.bottom + 0.45 * font, Align::kCentre, Align::kStart);
  }
}

void draw_legend(cairo_t* cr, const Chart& chart, const Frame& f, double font) {
  if (chart.legend == LegendPlacement::kNone) return;
  std::vector<std::size_t> shown;
  for (std::size_t i = 0; i < chart.series.size(); ++i)
    if (!chart.series[i].label.empty()) shown.push_back(i);
  if (shown.empty()) return;
  detail::set_font(cr, font);
  double text_w = 0;
  for (std::size_t i : shown)
    text_w = std::max(text_w, detail::text_width(cr, chart.series[i].label));
  const double row = 1.45 * font, sample = 2.2 * font, pad = 0.6 * font;
  const double w = pad + sample + pad + text_w + pad;
  const double h = pad + row * static_cast<double>(shown.size()) + 0.3 * pad;
  const bool left =
      chart.legend == LegendPlacement::kTopLeft || chart.legend == LegendPlacement::kBottomLeft;
  const bool top =
      chart.legend == LegendPlacement::kTopLeft || chart.legend == LegendPlacement::kTopRight;
  const double x0 = left ? f.left + pad : f.right - pad - w;
  const double y0 = top ? f.top + pad : f.bottom - pad - h;
  cairo_rectangle(cr, x0, y0, w, h);
  detail::set_color(cr, Rgb{1, 1, 1}, 0.88);
  cairo_fill_preserve(cr);
  detail::set_color(cr, Rgb{0.7, 0.7, 0.7});
  cairo_set_line_width(cr, 1.0);
  cairo_stroke(cr);
  for (std::size_t r = 0; r < shown.size(); ++r) {
    const Series& s = chart.series[shown[r]];
    const double cy = y0 + pad + row * (static_cast<double>(r) + 0.5);
    detail::set_color(cr, series_color(s, shown[r]));
    if (s.line != LineStyle::kNone) {
      cairo_set_line_width(cr, s.line_width_pt);
      set_dash(cr, s.line, s.line_width_pt);
      cairo_move_to(cr, x0 + pad, cy);
      cairo_line_to(cr, x0 + pad + sample, cy);
      cairo_stroke(cr);
      set_dash(cr, LineStyle::kSolid, 1);
    }
    draw_marker(cr, s.marker, x0 + pad + 0.5 * sample, cy, 3.2);
    detail::set_color(cr, Rgb{0.1, 0.1, 0.1});
    detail::draw_text(cr, s.label, x0 + 2 * pad + sample, cy, Align::kStart, Align::kCentre);
  }
}

std::string csv_quote(std::string_view s) {
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q += '"';
    q += c;
  }
  return q + "\"";
}

}  // namespace

Rgb palette_color(std::size_t i) {
  // Okabe–Ito, without its black and yellow (too weak on white): blue, vermillion, bluish green,
  // reddish purple, orange, sky blue.
  static constexpr std::array<Rgb, 6> kColors{{{0.000, 0.447, 0.698},
                                               {0.835, 0.369, 0.000},
                                               {0.000, 0.620, 0.451},
                                               {0.800, 0.475, 0.655},
                                               {0.902, 0.624, 0.000},
                                               {0.337, 0.706, 0.914}}};
  return kColors[i % kColors.size()];
}

Status Chart::validate() const {
  if (!series.empty() && !bars.empty())
    return invalid_argument("chart '" + title + "': has both series and bars");
  if (series.empty() && bars.empty())
    return invalid_argument("chart '" + title + "': nothing to draw (no series, no bars)");
  for (std::size_t i = 0; i < series.size(); ++i) {
    const Series& s = series[i];
    const std::string where =
        "chart '" + title + "': series " + std::to_string(i) + " ('" + s.label + "')";
    if (s.x.size() != s.y.size())
      return invalid_argument(where + ": " + std::to_string(s.x.size()) + " x values but " +
                              std::to_string(s.y.size()) + " y values");
    for (std::size_t k = 0; k < s.x.size(); ++k)
      if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k]))
        return invalid_argument(where + ": point " + std::to_string(k) + " is not finite");
    if (!(s.line_width_pt > 0) || s.line_width_pt > 50)
      return invalid_argument(where + ": line width must be in (0, 50] pt");
  }
  for (std::size_t i = 0; i < bars.size(); ++i)
    if (!std::isfinite(bars[i].value))
      return invalid_argument("chart '" + title + "': bar " + std::to_string(i) + " ('" +
                              bars[i].label + "') is not finite");
  for (const Axis* a : {&x, &y}) {
    if ((a->min && !std::isfinite(*a->min)) || (a->max && !std::isfinite(*a->max)))
      return invalid_argument("chart '" + title + "': axis '" + a->label + "': non-finite end");
    if (a->min && a->max && !(*a->min < *a->max))
      return invalid_argument("chart '" + title + "': axis '" + a->label + "': min " +
                              format_tick(*a->min, 6) + " must be below max " +
                              format_tick(*a->max, 6));
  }
  return {};
}

Ticks nice_ticks(double lo, double hi, int target_count) {
  if (lo > hi) std::swap(lo, hi);
  if (!(hi > lo)) {
    const double pad = lo == 0 ? 1.0 : 0.1 * std::abs(lo);
    lo -= pad;
    hi += pad;
  }
  target_count = std::max(target_count, 2);
  const double range = nice_number(hi - lo, false);
  const double step = nice_number(range / (target_count - 1), true);
  Ticks t;
  t.step = step;
  t.decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  const double first = std::floor(lo / step + 1e-9) * step;
  const double last = std::ceil(hi / step - 1e-9) * step;
  const auto n = static_cast<long>(std::llround((last - first) / step));
  for (long k = 0; k <= n; ++k) {
    // Multiples of the step, not a running sum (0.1 + 0.2 != 0.3).
    const double v = std::round(first / step + static_cast<double>(k)) * step;
    t.values.push_back(v);
  }
  return t;
}

std::string format_tick(double value, int decimals) {
  std::string s = fmt::format("{:.{}f}", value, std::max(0, decimals));
  if (s.front() == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);
  return s;
}

std::optional<ImageFormat> image_format_of(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".png") return ImageFormat::kPng;
  if (ext == ".svg") return ImageFormat::kSvg;
  return std::nullopt;
}

std::string_view extension(ImageFormat format) {
  return format == ImageFormat::kPng ? ".png" : ".svg";
}

Result<std::string> render_chart(const Chart& chart, ImageFormat format,
                                 const RenderOptions& options) {
  HC_RETURN_IF_ERROR(chart.validate());
  if (!(options.font_size >= 4 && options.font_size <= 100))
    return invalid_argument("font size must be 4..100");
  HC_ASSIGN_OR_RETURN(std::unique_ptr<detail::Canvas> canvas,
                      detail::Canvas::create(format, options.width_px, options.height_px));
  cairo_t* cr = canvas->cr();
  const double font = options.font_size;
  const bool bars = !chart.bars.empty();

  Frame f;
  Range xr, yr;
  for (const Series& s : chart.series) {
    for (double v : s.x) xr.add(v);
    for (double v : s.y) yr.add(v);
  }
  for (const Bar& b : chart.bars) yr.add(b.value);
  Axis y_axis = chart.y;
  if (bars) y_axis.include_zero = true;
  f.x = bars ? AxisLayout{0, 1, {}} : layout_axis(chart.x, xr);
  f.y = layout_axis(y_axis, yr);

  // Margins from the widest tick label and the label/title heights.
  detail::set_font(cr, font);
  double tick_w = 0;
  for (double v : f.y.ticks.values)
    tick_w = std::max(tick_w, detail::text_width(cr, format_tick(v, f.y.ticks.decimals)));
  double bottom_extra = 0;
  if (bars) {
    double widest = 0;
    for (const Bar& b : chart.bars) widest = std::max(widest, detail::text_width(cr, b.label));
    const double slot = (options.width_px - tick_w - 3.5 * font) / chart.bars.size();
    if (widest > 0.95 * slot) bottom_extra = 0.5 * widest;
  }
  f.left = 2.4 * font + tick_w + 0.5 * font;
  f.right = options.width_px - 1.2 * font;
  f.top = (chart.title.empty() ? 1.0 : 2.6) * font;
  f.bottom = options.height_px - 3.6 * font - bottom_extra;
  if (f.right - f.left < 40 || f.bottom - f.top < 40)
    return invalid_argument("image too small for the chart's labels");

  draw_frame(cr, chart, f, font, bars);
  if (bars)
    draw_bars(cr, chart, f, font);
  else
    draw_series(cr, chart, f);
  draw_legend(cr, chart, f, font);
  return canvas->finish();
}

Status write_chart(const Chart& chart, const std::filesystem::path& path,
                   const RenderOptions& options) {
  const std::optional<ImageFormat> format = image_format_of(path);
  if (!format)
    return invalid_argument(path.string() + ": unknown image format (expected .png or .svg)");
  HC_ASSIGN_OR_RETURN(std::string bytes, render_chart(chart, *format, options));
  return write_file_atomic(path, bytes);
}

Json chart_data_json(const Chart& chart) {
  Json j{{"title", chart.title}, {"x_label", chart.x.label}, {"y_label", chart.y.label}};
  if (!chart.series.empty()) {
    Json series = Json::array();
    for (const Series& s : chart.series)
      series.push_back(Json{{"label", s.label}, {"x", s.x}, {"y", s.y}});
    j["series"] = std::move(series);
  }
  if (!chart.bars.empty()) {
    Json bars = Json::array();
    for (const Bar& b : chart.bars) bars.push_back(Json{{"label", b.label}, {"value", b.value}});
    j["bars"] = std::move(bars);
  }
  return j;
}

std::string chart_data_csv(const Chart& chart) {
  std::string out;
  if (!chart.bars.empty()) {
    out = "bar,value\n";
    for (const Bar& b : chart.bars) out += fmt::format("{},{:.17g}\n", csv_quote(b.label), b.value);
    return out;
  }
  out = fmt::format("series,{},{}\n", csv_quote(chart.x.label), csv_quote(chart.y.label));
  for (const Series& s : chart.series)
    for (std::size_t k = 0; k < s.x.size(); ++k)
      out += fmt::format("{},{:.17g},{:.17g}\n", csv_quote(s.label), s.x[k], s.y[k]);
  return out;
}

}  // namespace hc::plot
