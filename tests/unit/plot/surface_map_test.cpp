// Surface colour maps: the projection, the interpolated colours and the painter's order, read back
// from the PNG with Cairo's decoder; validation of malformed maps.
#include <cairo.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "plot/surface_map.h"

namespace hc::plot {
namespace {

struct Decoded {
  cairo_surface_t* s = nullptr;
  std::string data;
  std::size_t pos = 0;
  explicit Decoded(std::string bytes) : data(std::move(bytes)) {
    s = cairo_image_surface_create_from_png_stream(
        [](void* c, unsigned char* out, unsigned int n) {
          auto* d = static_cast<Decoded*>(c);
          if (d->pos + n > d->data.size()) return CAIRO_STATUS_READ_ERROR;
          std::copy_n(d->data.data() + d->pos, n, out);
          d->pos += n;
          return CAIRO_STATUS_SUCCESS;
        },
        this);
  }
  ~Decoded() { cairo_surface_destroy(s); }
  Rgb at(int x, int y) const {
    const unsigned char* p = cairo_image_surface_get_data(s) + y * cairo_image_surface_get_stride(s);
    const std::uint32_t v = reinterpret_cast<const std::uint32_t*>(p)[x];
    return {((v >> 16) & 255) / 255.0, ((v >> 8) & 255) / 255.0, (v & 255) / 255.0};
  }
  bool white(int x, int y) const {
    const Rgb c = at(x, y);
    return c.r > 0.99 && c.g > 0.99 && c.b > 0.99;
  }
};

void expect_near(const Rgb& a, const Rgb& b, double tol) {
  EXPECT_NEAR(a.r, b.r, tol);
  EXPECT_NEAR(a.g, b.g, tol);
  EXPECT_NEAR(a.b, b.b, tol);
}

SurfaceMap unit_square() {
  SurfaceMap m;
  m.title = "error";
  m.value_label = "error (mm)";
  m.axis_unit = "mm";
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  m.values = {0, 1, 1, 0};  // = x
  return m;
}

TEST(Viridis, EndsAndMiddleAreMatplotlibs) {
  // matplotlib viridis(0) = #440154, viridis(1) = #fde725; k/9 samples are exact table entries.
  expect_near(viridis(0), {0x44 / 255., 0x01 / 255., 0x54 / 255.}, 1e-12);
  expect_near(viridis(1), {0xfd / 255., 0xe7 / 255., 0x25 / 255.}, 1e-12);
  expect_near(viridis(4.0 / 9.0), {0x26 / 255., 0x82 / 255., 0x8e / 255.}, 1e-12);
  expect_near(viridis(-3), viridis(0), 0);
  expect_near(viridis(std::nan("")), viridis(0), 0);
}

TEST(SurfaceMap, ColoursFollowTheValuesAcrossTheProjectedSquare) {
  RenderOptions o;
  o.width_px = 600;
  o.height_px = 400;
  Result<std::string> png = render_surface_map(unit_square(), ImageFormat::kPng, o);
  ASSERT_TRUE(png.ok()) << png.status().to_string();
  Decoded img(*png);
  ASSERT_EQ(cairo_surface_status(img.s), CAIRO_STATUS_SUCCESS);
  // The middle row, left of the colour bar: the square's edges are its first/last coloured pixels.
  const int y = 200, bar_x = static_cast<int>(600 - 8.5 * o.font_size) - 4;
  int x0 = -1, x1 = -1;
  for (int x = 0; x < bar_x; ++x)
    if (!img.white(x, y)) {
      if (x0 < 0) x0 = x;
      x1 = x;
    }
  ASSERT_GT(x1 - x0, 100);
  // Values are linear in x (the projection keeps +x to the right for a view along -z), so the
  // colour at a quarter of the width is viridis(0.25) (within 8-bit rounding and edge blending).
  for (double t : {0.25, 0.5, 0.75}) {
    const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
    expect_near(img.at(x, y), viridis(t), 4.0 / 255);
  }
}

TEST(SurfaceMap, NearerTrianglesArePaintedLast) {
  SurfaceMap m = unit_square();
  // A second square above the first (z = 1, nearer a viewer looking down -z) with value 1.
  m.vertices.insert(m.vertices.end(), {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}});
  m.triangles.insert(m.triangles.begin(), {{4, 5, 6}, {4, 6, 7}});  // listed first on purpose
  m.values = {0, 0, 0, 0, 1, 1, 1, 1};
  Result<std::string> png = render_surface_map(m, ImageFormat::kPng);
  ASSERT_TRUE(png.ok());
  Decoded img(*png);
  int x0 = -1, x1 = -1;
  for (int x = 0; x < 600; ++x)
    if (!img.white(x, 280)) {
      if (x0 < 0) x0 = x;
      x1 = x;
    }
  expect_near(img.at((x0 + x1) / 2, 280), viridis(1), 2.0 / 255);
  // Seen from below (+z), the z = 0 square is nearer.
  m.view_direction = {0, 0, 1};
  Result<std::string> below = render_surface_map(m, ImageFormat::kPng);
  ASSERT_TRUE(below.ok());
  Decoded img2(*below);
  expect_near(img2.at((x0 + x1) / 2, 280), viridis(0), 2.0 / 255);
}

TEST(SurfaceMap, SvgRenders) {
  Result<std::string> svg = render_surface_map(unit_square(), ImageFormat::kSvg);
  ASSERT_TRUE(svg.ok());
  EXPECT_NE(svg->find("</svg>"), std::string::npos);
}

TEST(SurfaceMap, MalformedMapsAreRefused) {
  SurfaceMap m = unit_square();
  m.values.pop_back();
  EXPECT_NE(m.validate().message().find("3 values for 4 vertices"), std::string::npos);
  m = unit_square();
  m.triangles[1][2] = 9;
  EXPECT_NE(m.validate().message().find("triangle 1 names vertex 9"), std::string::npos);
  m = unit_square();
  m.view_direction = {0, 0, 0};
  EXPECT_EQ(m.validate().code(), StatusCode::kInvalidArgument);
  m = unit_square();
  m.vertices[2][0] = INFINITY;
  EXPECT_EQ(render_surface_map(m, ImageFormat::kPng).status().code(),
            StatusCode::kInvalidArgument);
  m = unit_square();
  m.triangles.clear();
  EXPECT_EQ(m.validate().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace hc::plot
