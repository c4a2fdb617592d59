// Charts for the lab's figures (force–displacement curves, measured vs simulated, bar plots of
// errors): a Chart says what to show — series of (x, y) points drawn as lines and/or markers, or
// labelled bars — and render_chart() lays out the frame, ticks, labels and legend and has Cairo
// draw it into a PNG or an SVG. Every chart's numbers can also be written as data (CSV / JSON) so
// that what a figure shows can be checked against its source without looking at pixels.
//
// Numbers are drawn as given: the caller converts units for display (e.g. m → mm) and names them
// in the axis labels.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/json.h"
#include "common/status.h"

namespace hc::plot {

struct Rgb {
  double r = 0, g = 0, b = 0;  // 0..1
};
// The i-th colour (cycling) of the Okabe–Ito palette, distinguishable with the common forms of
// colour blindness (Okabe & Ito 2008, "Color Universal Design").
Rgb palette_color(std::size_t i);

enum class LineStyle { kSolid, kDashed, kDotted, kNone };
enum class MarkerStyle { kNone, kCircle, kSquare, kTriangle, kDiamond, kCross };

struct Series {
  std::string label;  // legend text; empty: not in the legend
  std::vector<double> x, y;
  std::optional<Rgb> color = std::nullopt;  // unset: palette_color(index of the series)
  LineStyle line = LineStyle::kSolid;
  MarkerStyle marker = MarkerStyle::kNone;
  double line_width_pt = 1.8;
};

struct Bar {
  std::string label;  // category under the bar
  double value = 0;
  std::optional<Rgb> color = std::nullopt;  // unset: palette_color(0)
};

struct Axis {
  std::string label;  // with its unit, e.g. "displacement (mm)"
  // Fixed ends; unset: from the data, widened to nice tick values.
  std::optional<double> min, max;
  bool include_zero = false;  // extend the data range to 0
};

enum class LegendPlacement { kNone, kTopLeft, kTopRight, kBottomLeft, kBottomRight };

struct Chart {
  std::string title;
  Axis x, y;
  std::vector<Series> series;  // line/marker chart
  std::vector<Bar> bars;       // a bar chart when non-empty (then `series` must be empty)
  LegendPlacement legend = LegendPlacement::kTopLeft;

  // kInvalidArgument naming the series/bar at fault: x and y of different sizes, a non-finite
  // number, both series and bars, nothing to draw, min >= max on an axis.
  Status validate() const;
};

// Tick positions for [lo, hi] at "nice" steps (1, 2 or 5 times a power of ten; Heckbert,
// "Nice numbers for graph labels", Graphics Gems, 1990), covering the range: the first tick <= lo,
// the last >= hi, about `target_count` of them. lo == hi is widened around the value.
struct Ticks {
  std::vector<double> values;
  double step = 1;
  int decimals = 0;  // digits after the point that print every tick exactly
};
Ticks nice_ticks(double lo, double hi, int target_count = 6);
// The tick label: `decimals` digits, "-0" printed as "0".
std::string format_tick(double value, int decimals);

enum class ImageFormat { kPng, kSvg };
// From a file name's extension (".png", ".svg", any case); nullopt otherwise.
std::optional<ImageFormat> image_format_of(const std::filesystem::path& path);
std::string_view extension(ImageFormat format);  // ".png" / ".svg"

struct RenderOptions {
  int width_px = 800;  // PNG pixels; SVG points (1 px = 1 pt)
  int height_px = 560;
  double font_size = 13;  // tick labels; titles and axis labels scale from it
};

// The chart as PNG bytes or SVG text. kInvalidArgument when validate() fails or the size is not
// 100..8000 pixels per side; kInternal when Cairo reports an error.
Result<std::string> render_chart(const Chart& chart, ImageFormat format,
                                 const RenderOptions& options = {});
// Renders and writes atomically (format from the extension; kInvalidArgument for another one).
Status write_chart(const Chart& chart, const std::filesystem::path& path,
                   const RenderOptions& options = {});

// The chart's data: {"title", "x_label", "y_label", "series": [{"label", "x": [...], "y": [...]}],
// "bars": [{"label", "value"}]}, numbers exactly as plotted.
Json chart_data_json(const Chart& chart);
// One row per point: "series,x,y" (bars: "bar,label,value"), values with 17 significant digits so
// they read back bit-exactly; labels quoted as CSV (RFC 4180).
std::string chart_data_csv(const Chart& chart);

}  // namespace hc::plot
