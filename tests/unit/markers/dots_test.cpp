// Dot extraction: sub-pixel centroids of anti-aliased discs against their analytic centres (the
// exact centre of a rendered disc is known), coloured dots classified in CIE Lab, filters and bad
// input.
#include "processing/markers/dots.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "rig_daemon/simulation/sim_dots.h"

namespace hc::markers {
namespace {

struct Image {
  int width = 0, height = 0, channels = 1;
  std::vector<std::uint8_t> px;
  ImageView view() const {
    return {width, height, static_cast<std::ptrdiff_t>(width) * channels,
            channels == 3 ? PixelFormat::kRgb8 : PixelFormat::kMono8, px.data()};
  }
};

// Disc coverage of pixel (x, y) by 16 x 16 supersampling (exact to 1/256 of a pixel's area).
double coverage(double x, double y, double cx, double cy, double r) {
  constexpr int kSub = 16;
  int inside = 0;
  for (int sy = 0; sy < kSub; ++sy)
    for (int sx = 0; sx < kSub; ++sx) {
      const double ex = x - 0.5 + (sx + 0.5) / kSub - cx;
      const double ey = y - 0.5 + (sy + 0.5) / kSub - cy;
      inside += ex * ex + ey * ey <= r * r ? 1 : 0;
    }
  return static_cast<double>(inside) / (kSub * kSub);
}

// Draws discs of colour `fg` (per channel) on `bg`, anti-aliased, rounded to 8 bits.
void draw_disc(Image& im, double cx, double cy, double r, const std::vector<double>& bg,
               const std::vector<double>& fg) {
  for (int y = static_cast<int>(cy - r - 2); y <= static_cast<int>(cy + r + 2); ++y)
    for (int x = static_cast<int>(cx - r - 2); x <= static_cast<int>(cx + r + 2); ++x) {
      if (x < 0 || y < 0 || x >= im.width || y >= im.height) continue;
      const double c = coverage(x, y, cx, cy, r);
      if (c <= 0) continue;
      for (int k = 0; k < im.channels; ++k)
        im.px[static_cast<std::size_t>((y * im.width + x) * im.channels + k)] =
            static_cast<std::uint8_t>(std::lround(bg[k] + (fg[k] - bg[k]) * c));
    }
}

Image blank(int w, int h, int channels, const std::vector<double>& bg) {
  Image im{w, h, channels, {}};
  im.px.resize(static_cast<std::size_t>(w * h * channels));
  for (std::size_t i = 0; i < im.px.size(); ++i)
    im.px[i] = static_cast<std::uint8_t>(bg[i % static_cast<std::size_t>(channels)]);
  return im;
}

// Finds the detected dot nearest to (x, y).
const Dot* nearest(const std::vector<Dot>& dots, const Eigen::Vector2d& p) {
  const Dot* best = nullptr;
  for (const Dot& d : dots)
    if (!best || (d.center_px - p).norm() < (best->center_px - p).norm()) best = &d;
  return best;
}

// Sub-pixel accuracy on a grid of discs at random sub-pixel offsets, radii 2.5-6 px (a 0.6 mm dot
// at 1-2.5 m with f = 2000-5000 px), bright on dark as the simulator renders them. The reference
// is the analytic disc centre; the brief's bound is a bias < 0.05 px.
TEST(DetectBlobs, SubPixelCentroidsOfAntiAliasedDiscs) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> frac(0.0, 1.0), radius(2.5, 6.0);
  Image im = blank(640, 480, 1, {30});
  std::vector<Eigen::Vector3d> truth;
  for (int gy = 0; gy < 9; ++gy)
    for (int gx = 0; gx < 12; ++gx) {
      const Eigen::Vector3d c(30 + 50 * gx + frac(rng), 30 + 50 * gy + frac(rng), radius(rng));
      truth.push_back(c);
      draw_disc(im, c.x(), c.y(), c.z(), {30}, {220});
    }
  auto dots = detect_blobs(im.view());
  ASSERT_TRUE(dots.ok()) << dots.status().to_string();
  ASSERT_EQ(dots->size(), truth.size());
  Eigen::Vector2d bias = Eigen::Vector2d::Zero();
  double max_err = 0;
  for (const auto& t : truth) {
    const Dot* d = nearest(*dots, t.head<2>());
    const Eigen::Vector2d e = d->center_px - t.head<2>();
    bias += e;
    max_err = std::max(max_err, e.norm());
    EXPECT_NEAR(d->area_px, M_PI * t.z() * t.z(), 0.35 * M_PI * t.z() * t.z());
    EXPECT_GT(d->roundness, 0.6);  // pixelated small discs: 0.7-1
    EXPECT_EQ(d->color_class, -1);
  }
  bias /= static_cast<double>(truth.size());
  EXPECT_LT(bias.norm(), 0.05);
  EXPECT_LT(max_err, 0.05);  // 8-bit rounding of the edge pixels: a few thousandths of a px
}

// The same through the simulator's own renderer (rig_daemon render_dots, 8 x 8 supersampled
// edges) with a dark-on-bright style and the kDark polarity, plus Gaussian noise (sigma 2 grey
// levels): the bias stays < 0.05 px.
TEST(DetectBlobs, SimulatorRenderedDarkDotsWithNoise) {
  CameraModel cam;
  cam.width = 800;
  cam.height = 600;
  cam.fx = cam.fy = 2400;
  cam.cx = 399.5;
  cam.cy = 299.5;
  std::vector<Eigen::Vector3d> centres;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.3e-3, 0.3e-3);
  for (int gy = -5; gy <= 5; ++gy)
    for (int gx = -7; gx <= 7; ++gx)
      centres.emplace_back(gx * 3e-3 + jitter(rng), gy * 3e-3 + jitter(rng), 0.4);
  devices::Frame frame;
  frame.width = cam.width;
  frame.height = cam.height;
  frame.stride_bytes = cam.width;
  frame.pixels.assign(static_cast<std::size_t>(cam.width) * cam.height, 200);
  devices::sim::DotStyle style;
  style.background = 200;
  style.dot = 40;
  ASSERT_EQ(devices::sim::render_dots(cam, centres, 0.6e-3, style, frame), centres.size());
  std::normal_distribution<double> noise(0.0, 2.0);
  for (auto& p : frame.pixels)
    p = static_cast<std::uint8_t>(std::clamp(std::lround(p + noise(rng)), 0L, 255L));
  ImageView view{static_cast<int>(frame.width), static_cast<int>(frame.height),
                 static_cast<std::ptrdiff_t>(frame.stride_bytes), PixelFormat::kMono8,
                 frame.pixels.data()};
  BlobOptions opt;
  opt.polarity = Polarity::kDark;
  auto dots = detect_blobs(view, opt);
  ASSERT_TRUE(dots.ok()) << dots.status().to_string();
  ASSERT_EQ(dots->size(), centres.size());
  Eigen::Vector2d bias = Eigen::Vector2d::Zero();
  double sq = 0;
  for (const auto& c : centres) {
    const Eigen::Vector2d t = *cam.project(c);
    const Eigen::Vector2d e = nearest(*dots, t)->center_px - t;
    bias += e;
    sq += e.squaredNorm();
  }
  bias /= static_cast<double>(centres.size());
  EXPECT_LT(bias.norm(), 0.05);
  EXPECT_LT(std::sqrt(sq / static_cast<double>(centres.size())), 0.1);
}

TEST(DetectBlobs, LocalThresholdUnderAGradientAndRgbInput) {
  // Background ramps from 20 to 140 across the image: a global threshold would swallow the right
  // half; the local mean keeps every dot.
  Image im{400, 200, 3, {}};
  im.px.resize(400 * 200 * 3);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 400; ++x)
      for (int k = 0; k < 3; ++k)
        im.px[static_cast<std::size_t>((y * 400 + x) * 3 + k)] =
            static_cast<std::uint8_t>(20 + 120 * x / 399);
  std::vector<Eigen::Vector2d> truth;
  for (int i = 0; i < 7; ++i) {
    const double cx = 30.3 + 55 * i, cy = 100.6;
    const double bg = 20 + 120 * std::floor(cx) / 399;
    draw_disc(im, cx, cy, 4.0, {bg, bg, bg}, {bg + 90, bg + 90, bg + 90});
    truth.emplace_back(cx, cy);
  }
  BlobOptions opt;
  opt.threshold = ThresholdMethod::kLocalMean;
  opt.local_offset = 20;
  auto dots = detect_blobs(im.view(), opt);
  ASSERT_TRUE(dots.ok()) << dots.status().to_string();
  ASSERT_EQ(dots->size(), truth.size());
  for (const auto& t : truth) EXPECT_LT((nearest(*dots, t)->center_px - t).norm(), 0.15);
}

TEST(DetectBlobs, AreaRoundnessAndBorderFilters) {
  Image im = blank(300, 200, 1, {10});
  draw_disc(im, 50.2, 50.7, 4.0, {10}, {250});   // kept
  draw_disc(im, 150.0, 50.0, 0.6, {10}, {250});  // too small (area ~1 px)
  draw_disc(im, 1.0, 100.0, 4.0, {10}, {250});   // touches the border
  for (int y = 140; y < 143; ++y)                // a 60 x 3 line: not round
    for (int x = 100; x < 160; ++x) im.px[static_cast<std::size_t>(y * 300 + x)] = 250;
  auto dots = detect_blobs(im.view());
  ASSERT_TRUE(dots.ok());
  ASSERT_EQ(dots->size(), 1u);
  EXPECT_LT(((*dots)[0].center_px - Eigen::Vector2d(50.2, 50.7)).norm(), 0.05);
  BlobOptions keep_border;
  keep_border.drop_border_dots = false;
  EXPECT_EQ(detect_blobs(im.view(), keep_border)->size(), 2u);
}

TEST(DetectBlobs, RejectsBadViewsAndOptions) {
  std::vector<std::uint8_t> px(100, 0);
  EXPECT_FALSE(detect_blobs({10, 10, 10, PixelFormat::kMono8, nullptr}).ok());
  EXPECT_FALSE(detect_blobs({0, 10, 10, PixelFormat::kMono8, px.data()}).ok());
  EXPECT_FALSE(detect_blobs({10, 10, 9, PixelFormat::kMono8, px.data()}).ok());
  EXPECT_FALSE(detect_blobs({10, 3, 10, PixelFormat::kRgb8, px.data()}).ok());  // stride < 30
  BlobOptions bad;
  bad.threshold = ThresholdMethod::kLocalMean;
  bad.local_block_px = 10;
  EXPECT_EQ(detect_blobs({10, 10, 10, PixelFormat::kMono8, px.data()}, bad).status().code(),
            StatusCode::kInvalidArgument);
  BlobOptions bad_area;
  bad_area.min_area_px = 10;
  bad_area.max_area_px = 5;
  EXPECT_FALSE(detect_blobs({10, 10, 10, PixelFormat::kMono8, px.data()}, bad_area).ok());
  // A uniform image has no dots (and must not fail).
  auto none = detect_blobs({10, 10, 10, PixelFormat::kMono8, px.data()});
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
}

// sRGB -> Lab reference values (D65) from the CIE formulas, as tabulated e.g. by
// colormine.org / Bruce Lindbloom's calculator: red (255,0,0) -> (53.24, 80.09, 67.20),
// green (0,255,0) -> (87.73, -86.18, 83.18), blue (0,0,255) -> (32.30, 79.19, -107.86).
// OpenCV's 8-bit conversion quantises L to 100/255 and a, b to 1 (and clips a, b to
// [-128, 127]): tolerance 1.5.
TEST(RgbToLab, MatchesCieReferenceValues) {
  const Eigen::Vector3d red = rgb_to_lab({255, 0, 0});
  EXPECT_NEAR(red[0], 53.24, 1.5);
  EXPECT_NEAR(red[1], 80.09, 1.5);
  EXPECT_NEAR(red[2], 67.20, 1.5);
  const Eigen::Vector3d green = rgb_to_lab({0, 255, 0});
  EXPECT_NEAR(green[0], 87.73, 1.5);
  EXPECT_NEAR(green[1], -86.18, 1.5);
  EXPECT_NEAR(green[2], 83.18, 1.5);
  const Eigen::Vector3d blue = rgb_to_lab({0, 0, 255});
  EXPECT_NEAR(blue[0], 32.30, 1.5);
  EXPECT_NEAR(blue[1], 79.19, 1.5);
  EXPECT_NEAR(blue[2], -107.86, 21.0);  // OpenCV clips b to -128..127 after its own scaling
}

// Thesis Sec. 4.4.2: per-colour thresholds in Lab, closing, 8-connected components, centroids.
TEST(DetectColorDots, ClassifiesPaintedDotsAndLocatesThem) {
  const std::vector<double> skin{200, 170, 150};
  Image im = blank(400, 300, 3, skin);
  struct Truth {
    Eigen::Vector2d c;
    int cls;
  };
  std::vector<Truth> truth;
  const std::vector<std::vector<double>> paint{{220, 30, 30}, {30, 160, 40}, {30, 40, 200}};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> frac(0.0, 1.0);
  for (int i = 0; i < 15; ++i) {
    const int cls = i % 3;
    const Eigen::Vector2d c(40 + 70 * (i % 5) + frac(rng), 50 + 90 * (i / 5) + frac(rng));
    draw_disc(im, c.x(), c.y(), 5.0, skin, paint[static_cast<std::size_t>(cls)]);
    truth.push_back({c, cls});
  }
  // A one-pixel crack through a red dot: the closing must join the halves into one marker.
  for (int y = 40; y < 61; ++y) {
    const std::size_t i = static_cast<std::size_t>((y * 400 + 40) * 3);
    im.px[i] = 200;
    im.px[i + 1] = 170;
    im.px[i + 2] = 150;
  }
  ColorDotOptions opt;
  const char* const names[] = {"red", "green", "blue"};
  for (std::size_t k = 0; k < paint.size(); ++k) {
    const Eigen::Vector3d lab = rgb_to_lab({paint[k][0], paint[k][1], paint[k][2]});
    opt.colors.push_back(
        {names[k], lab - Eigen::Vector3d(25, 25, 25), lab + Eigen::Vector3d(25, 25, 25)});
  }
  opt.closing_radius_px = 1;
  auto dots = detect_color_dots(im.view(), opt);
  ASSERT_TRUE(dots.ok()) << dots.status().to_string();
  ASSERT_EQ(dots->size(), truth.size());
  for (const Truth& t : truth) {
    const Dot* d = nearest(*dots, t.c);
    EXPECT_EQ(d->color_class, t.cls);
    // Thresholding keeps the pixels mostly covered by paint: a symmetric set around the centre,
    // so the centroid error is a fraction of a pixel (0.2 px bound; the crack adds a little).
    EXPECT_LT((d->center_px - t.c).norm(), 0.2) << "class " << t.cls;
  }
  // Without the closing the cracked dot falls apart into two half discs (roundness ~0.28 each,
  // below the default filter; counted here with the filter off).
  opt.closing_radius_px = 0;
  opt.min_roundness = 0;
  auto open = detect_color_dots(im.view(), opt);
  ASSERT_TRUE(open.ok());
  EXPECT_EQ(open->size(), truth.size() + 1);
  // Mono8 has no colour.
  Image grey = blank(10, 10, 1, {0});
  EXPECT_EQ(detect_color_dots(grey.view(), opt).status().code(), StatusCode::kInvalidArgument);
  ColorDotOptions empty;
  EXPECT_FALSE(detect_color_dots(im.view(), empty).ok());
}

}  // namespace
}  // namespace hc::markers
