// hardcopy_plot: tick layout (Heckbert's nice numbers), chart validation, PNG/SVG output read back
// by Cairo's own PNG reader and checked as XML text, and the data files carrying the plotted numbers.
#include <cairo.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <string>

#include "common/file_io.h"
#include "plot/chart.h"
#include "test_data.h"

namespace hc::plot {
namespace {

// Decodes PNG bytes with Cairo's reader (a decoder independent of how we wrote them).
struct Png {
  cairo_surface_t* surface = nullptr;
  explicit Png(const std::string& bytes) : data(bytes) {
    surface = cairo_image_surface_create_from_png_stream(
        [](void* closure, unsigned char* out, unsigned int n) {
          auto* self = static_cast<Png*>(closure);
          if (self->pos + n > self->data.size()) return CAIRO_STATUS_READ_ERROR;
          std::copy_n(self->data.data() + self->pos, n, out);
          self->pos += n;
          return CAIRO_STATUS_SUCCESS;
        },
        this);
  }
  ~Png() { cairo_surface_destroy(surface); }
  bool ok() const { return cairo_surface_status(surface) == CAIRO_STATUS_SUCCESS; }
  int width() const { return cairo_image_surface_get_width(surface); }
  int height() const { return cairo_image_surface_get_height(surface); }
  // 0xAARRGGBB (premultiplied; our PNGs are opaque).
  std::uint32_t pixel(int x, int y) const {
    const unsigned char* p = cairo_image_surface_get_data(surface);
    const int stride = cairo_image_surface_get_stride(surface);
    return *reinterpret_cast<const std::uint32_t*>(p + y * stride + 4 * x);
  }
  std::string data;
  std::size_t pos = 0;
};

Chart two_curves() {
  Chart c;
  c.title = "force-displacement";
  c.x.label = "displacement (mm)";
  c.y.label = "force (N)";
  c.series.push_back({"measured", {0, 1.5, 3.1, 4.4}, {0, 2.0, 5.5, 10.0}});
  c.series.back().line = LineStyle::kNone;
  c.series.back().marker = MarkerStyle::kCircle;
  c.series.push_back({"simulated, \"fit\"", {0, 1.4, 3.0, 4.5}, {0, 2.1, 5.4, 10.2}});
  return c;
}

TEST(NiceTicks, HeckbertExamples) {
  // Heckbert (Graphics Gems 1990) with 6 ticks wanted: range nice(1) = 1, step nice(0.2) = 0.2.
  Ticks t = nice_ticks(0, 1);
  ASSERT_EQ(t.values.size(), 6u);
  EXPECT_DOUBLE_EQ(t.step, 0.2);
  EXPECT_EQ(t.decimals, 1);
  EXPECT_DOUBLE_EQ(t.values[3], 0.6000000000000001);  // 3 * 0.2 as a double, not a running sum
  EXPECT_EQ(format_tick(t.values[3], t.decimals), "0.6");
  // 0.13..9.7: range nice(9.57) = 10, step nice(2) = 2 -> 0, 2, ..., 10.
  t = nice_ticks(0.13, 9.7);
  ASSERT_EQ(t.values.size(), 6u);
  EXPECT_EQ(t.values.front(), 0);
  EXPECT_EQ(t.values.back(), 10);
  // -3.2..47: range nice(50.2) = 100, step nice(20) = 20 -> -20..60.
  t = nice_ticks(-3.2, 47);
  EXPECT_EQ(t.values.front(), -20);
  EXPECT_EQ(t.values.back(), 60);
  // A single value is widened around itself.
  t = nice_ticks(5, 5);
  EXPECT_LE(t.values.front(), 5);
  EXPECT_GE(t.values.back(), 5);
  EXPECT_GT(t.values.back(), t.values.front());
}

TEST(NiceTicks, CoverEveryRangeWithNiceSteps) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> mag(-9, 9), u(-1, 1);
  for (int i = 0; i < 2000; ++i) {
    const double scale = std::pow(10.0, mag(rng));
    double lo = u(rng) * scale, hi = u(rng) * scale;
    if (lo > hi) std::swap(lo, hi);
    if (hi - lo < 1e-6 * scale) continue;
    const Ticks t = nice_ticks(lo, hi);
    ASSERT_GE(t.values.size(), 3u) << lo << " " << hi;
    ASSERT_LE(t.values.size(), 12u) << lo << " " << hi;
    EXPECT_LE(t.values.front(), lo + 1e-9 * scale);
    EXPECT_GE(t.values.back(), hi - 1e-9 * scale);
    const double mantissa = t.step / std::pow(10.0, std::floor(std::log10(t.step) + 1e-12));
    EXPECT_TRUE(std::abs(mantissa - 1) < 1e-9 || std::abs(mantissa - 2) < 1e-9 ||
                std::abs(mantissa - 5) < 1e-9)
        << t.step;
    for (std::size_t k = 1; k < t.values.size(); ++k)
      EXPECT_NEAR(t.values[k] - t.values[k - 1], t.step, 1e-9 * t.step);
    // Adjacent labels differ (enough decimals).
    for (std::size_t k = 1; k < t.values.size(); ++k)
      EXPECT_NE(format_tick(t.values[k], t.decimals), format_tick(t.values[k - 1], t.decimals));
  }
}

TEST(FormatTick, NoNegativeZero) {
  EXPECT_EQ(format_tick(-0.0001, 2), "0.00");
  EXPECT_EQ(format_tick(-0.0, 0), "0");
  EXPECT_EQ(format_tick(-1.5, 1), "-1.5");
  EXPECT_EQ(format_tick(2500, 0), "2500");
}

TEST(Chart, ValidateNamesTheProblem) {
  Chart c = two_curves();
  EXPECT_TRUE(c.validate().ok());
  c.series[1].y.pop_back();
  Status s = c.validate();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("series 1"), std::string::npos) << s.message();
  c = two_curves();
  c.series[0].y[2] = std::nan("");
  EXPECT_NE(c.validate().message().find("point 2 is not finite"), std::string::npos);
  c = two_curves();
  c.bars.push_back({"a", 1.0});
  EXPECT_NE(c.validate().message().find("both series and bars"), std::string::npos);
  c = two_curves();
  c.x.min = 2;
  c.x.max = 1;
  EXPECT_NE(c.validate().message().find("must be below max"), std::string::npos);
  EXPECT_EQ(Chart{}.validate().code(), StatusCode::kInvalidArgument);
}

TEST(Chart, PngDecodesAtTheAskedSizeAndShowsTheCurves) {
  Chart c = two_curves();
  RenderOptions o;
  o.width_px = 640;
  o.height_px = 400;
  Result<std::string> png = render_chart(c, ImageFormat::kPng, o);
  ASSERT_TRUE(png.ok()) << png.status().to_string();
  Png img(*png);
  ASSERT_TRUE(img.ok());
  EXPECT_EQ(img.width(), 640);
  EXPECT_EQ(img.height(), 400);
  // Both palette colours appear (the series were drawn), and the corners are white (the page).
  const auto has_color = [&](Rgb want_rgb) {
    const auto to8 = [](double v) { return static_cast<std::uint32_t>(std::lround(v * 255)); };
    const std::uint32_t want =
        0xff000000u | to8(want_rgb.r) << 16 | to8(want_rgb.g) << 8 | to8(want_rgb.b);
    for (int y = 0; y < img.height(); ++y)
      for (int x = 0; x < img.width(); ++x)
        if (img.pixel(x, y) == want) return true;
    return false;
  };
  EXPECT_TRUE(has_color(palette_color(0)));
  EXPECT_TRUE(has_color(palette_color(1)));
  EXPECT_EQ(img.pixel(0, 0), 0xffffffffu);
  EXPECT_EQ(img.pixel(639, 399), 0xffffffffu);
}

TEST(Chart, SvgIsOneDocumentOfTheAskedSize) {
  Result<std::string> svg = render_chart(two_curves(), ImageFormat::kSvg);
  ASSERT_TRUE(svg.ok()) << svg.status().to_string();
  EXPECT_EQ(svg->rfind("<?xml", 0), 0u);
  EXPECT_NE(svg->find("<svg"), std::string::npos);
  EXPECT_NE(svg->find("width=\"800pt\""), std::string::npos);
  EXPECT_NE(svg->find("height=\"560pt\""), std::string::npos);
  EXPECT_NE(svg->find("</svg>"), std::string::npos);
}

TEST(Chart, BarsRender) {
  Chart c;
  c.title = "RMS error per design";
  c.y.label = "RMS error (mm)";
  for (int i = 0; i < 20; ++i) c.bars.push_back({"design " + std::to_string(i), 0.01 * i});
  EXPECT_TRUE(render_chart(c, ImageFormat::kPng).ok());
  EXPECT_TRUE(render_chart(c, ImageFormat::kSvg).ok());
}

TEST(Chart, BadSizesAndFormatsAreRefusedAndNothingIsWritten) {
  RenderOptions o;
  o.width_px = 50;
  EXPECT_EQ(render_chart(two_curves(), ImageFormat::kPng, o).status().code(),
            StatusCode::kInvalidArgument);
  hc::testing::ScratchDir scratch;
  const std::filesystem::path dir = scratch.path();
  EXPECT_EQ(write_chart(two_curves(), dir / "c.jpg").code(), StatusCode::kInvalidArgument);
  Chart bad = two_curves();
  bad.series[0].x.push_back(1);
  EXPECT_FALSE(write_chart(bad, dir / "c.png").ok());
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  ASSERT_TRUE(write_chart(two_curves(), dir / "c.SVG").ok());
  EXPECT_TRUE(std::filesystem::exists(dir / "c.SVG"));
}

TEST(ChartData, CsvCarriesTheNumbersBitExactly) {
  Chart c = two_curves();
  c.series[1].x[1] = 0.1 + 0.2;  // not representable in short decimal form
  const std::string csv = chart_data_csv(c);
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "series,\"displacement (mm)\",\"force (N)\"");
  std::size_t si = 0, k = 0, rows = 0;
  while (std::getline(in, line)) {
    const std::size_t a = line.rfind(',', line.rfind(',') - 1);
    const std::size_t b = line.rfind(',');
    const std::string label = line.substr(0, a);
    const double x = std::stod(line.substr(a + 1, b - a - 1));
    const double y = std::stod(line.substr(b + 1));
    while (k >= c.series[si].x.size()) {
      ++si;
      k = 0;
    }
    EXPECT_EQ(x, c.series[si].x[k]);
    EXPECT_EQ(y, c.series[si].y[k]);
    if (si == 1) {
      EXPECT_EQ(label, "\"simulated, \"\"fit\"\"\"");  // RFC 4180 quoting
    }
    ++k;
    ++rows;
  }
  EXPECT_EQ(rows, 8u);
  const Json j = chart_data_json(c);
  EXPECT_EQ(j["series"][1]["x"][1].get<double>(), 0.1 + 0.2);
  EXPECT_EQ(j["series"][0]["label"], "measured");
}

}  // namespace
}  // namespace hc::plot
