// libFuzzer target for the dot detectors: the first bytes choose the image size, pixel format and
// options, the rest are pixels. Detection must return dots inside the image (finite centroids,
// positive areas) or a Status; never crash or read outside the view.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "processing/markers/dots.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 4) return 0;
  const int width = 1 + data[0] % 64;
  const int height = 1 + data[1] % 64;
  const bool rgb = (data[2] & 1) != 0;
  const int channels = rgb ? 3 : 1;
  const std::ptrdiff_t stride = width * channels + (data[2] >> 5);
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(stride * height), 0);
  for (std::size_t i = 0; i < pixels.size() && 4 + i < size; ++i) pixels[i] = data[4 + i];
  hc::markers::ImageView view{
      width, height, stride,
      rgb ? hc::markers::PixelFormat::kRgb8 : hc::markers::PixelFormat::kMono8, pixels.data()};
  hc::markers::BlobOptions bo;
  bo.polarity = (data[3] & 1) ? hc::markers::Polarity::kDark : hc::markers::Polarity::kBright;
  bo.threshold = (data[3] & 2) ? hc::markers::ThresholdMethod::kLocalMean
                               : hc::markers::ThresholdMethod::kOtsu;
  bo.local_block_px = 3 + 2 * ((data[3] >> 2) & 7);
  bo.closing_radius_px = (data[3] >> 5) & 3;
  bo.min_area_px = 1;
  bo.min_roundness = 0;
  bo.drop_border_dots = (data[3] & 0x80) != 0;
  const auto check = [&](const hc::Result<std::vector<hc::markers::Dot>>& r) {
    if (!r.ok()) return;
    for (const hc::markers::Dot& d : *r) {
      if (!d.center_px.allFinite() || !(d.area_px > 0)) __builtin_trap();
      // The weighted centroid stays within the component's window (margin 2 px).
      if (d.center_px.x() < -3 || d.center_px.y() < -3 || d.center_px.x() > width + 2 ||
          d.center_px.y() > height + 2)
        __builtin_trap();
    }
  };
  check(hc::markers::detect_blobs(view, bo));
  if (rgb) {
    hc::markers::ColorDotOptions co;
    co.colors.push_back({"red", {20, 30, 10}, {70, 90, 80}});
    co.colors.push_back({"any", {0, -128, -128}, {100, 127, 127}});
    co.closing_radius_px = bo.closing_radius_px;
    co.min_area_px = 1;
    co.min_roundness = 0;
    check(hc::markers::detect_color_dots(view, co));
  }
  return 0;
}
