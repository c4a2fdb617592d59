// Marker dot extraction from camera frames (thesis Sec. 4.4.2 and 5.6).
//
// Two detectors over one image view:
//  * detect_blobs — dotted grids (Sec. 5.6): a threshold (Otsu or local mean), 8-connected
//    components, area / roundness filters and an intensity-weighted centroid over a window around
//    each component (sub-pixel: the weight is the grey level above the local background, so the
//    anti-aliased edge pixels count by their coverage). Works on Mono8 or RGB8 (converted to grey).
//  * detect_color_dots — painted coloured dots (Sec. 4.4.2): per-colour boxes in CIE Lab (OpenCV's
//    8-bit Lab converted back to L in [0, 100], a and b in [-128, 127]), a morphological closing,
//    8-connected components, area / roundness filters, centroids weighted by the pixel's closeness
//    to the colour's box centre (plain mean of the component's pixels when weighting is off).
//
// Pixel coordinates follow OpenCV: (0, 0) is the centre of the top-left pixel, x right, y down.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/status.h"

namespace hc::markers {

enum class PixelFormat { kMono8, kRgb8 };

// A non-owning view of an 8-bit image: `height` rows of `stride_bytes` bytes starting at `data`,
// each row holding `width` pixels of 1 (Mono8) or 3 (RGB8, R G B order) bytes.
struct ImageView {
  int width = 0;
  int height = 0;
  std::ptrdiff_t stride_bytes = 0;
  PixelFormat format = PixelFormat::kMono8;
  const std::uint8_t* data = nullptr;

  int channels() const { return format == PixelFormat::kRgb8 ? 3 : 1; }
  // kInvalidArgument on a null pointer, non-positive size or a stride shorter than a row.
  Status validate() const;
};

// One detected dot.
struct Dot {
  Eigen::Vector2d center_px = Eigen::Vector2d::Zero();  // sub-pixel centroid
  double area_px = 0.0;                                 // pixels in the thresholded component
  double roundness = 0.0;  // min/max eigenvalue ratio of the component's pixel covariance,
                           // in (0, 1]; 1 for a disc
  Eigen::Vector3d mean_color =
      Eigen::Vector3d::Zero();  // mean R, G, B (0..255) of the component's
                                // pixels; grey level in all three for Mono8
  int color_class = -1;         // index into ColorDotOptions::colors; -1 for detect_blobs
};

enum class Polarity { kBright, kDark };  // dots brighter / darker than the background
enum class ThresholdMethod { kOtsu, kLocalMean };

struct BlobOptions {
  Polarity polarity = Polarity::kBright;  // the simulated cameras render bright dots on dark
  ThresholdMethod threshold = ThresholdMethod::kOtsu;
  int local_block_px = 31;     // kLocalMean: odd window size
  double local_offset = 10.0;  // kLocalMean: grey levels above the local mean to count as dot
  double min_area_px = 3.0;    // component area bounds (thresholded pixels)
  double max_area_px = 5000.0;
  double min_roundness = 0.3;  // eigenvalue ratio of the component's second moments
  int closing_radius_px = 0;   // 0: no morphological closing before the components
  // Centroid window margin around the component's bounding box (px) so anti-aliased edge pixels
  // below the threshold still contribute by their intensity.
  int centroid_margin_px = 2;
  bool drop_border_dots = true;  // components touching the image border are cut: drop them

  Status validate() const;
};

// Dots of a dotted grid. Sorted by y, then x. kInvalidArgument on a bad view or options.
Result<std::vector<Dot>> detect_blobs(const ImageView& image, const BlobOptions& options = {});

// One marker colour: an axis-aligned box in CIE Lab (L in [0, 100], a and b in [-128, 127]).
struct ColorClass {
  std::string name;
  Eigen::Vector3d lab_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d lab_max = Eigen::Vector3d::Zero();
};

struct ColorDotOptions {
  std::vector<ColorClass> colors;  // at least one
  int closing_radius_px = 1;       // elliptic structuring element of this radius (0: none)
  double min_area_px = 3.0;
  double max_area_px = 5000.0;
  double min_roundness = 0.3;
  bool weighted_centroid = true;  // weight pixels by closeness to the box centre in Lab
  bool drop_border_dots = true;

  Status validate() const;
};

// Coloured dots of every class (Dot::color_class says which). RGB8 input required (a Mono8 image
// has no colour: kInvalidArgument). Sorted by class, then y, then x.
Result<std::vector<Dot>> detect_color_dots(const ImageView& image, const ColorDotOptions& options);

// Converts one sRGB colour (0..255 per channel) to CIE Lab (D65) the way the detector does
// (OpenCV's COLOR_RGB2Lab on 8-bit input, rescaled to L in [0, 100], a, b in [-128, 127]). For
// building ColorClass boxes from sample colours.
Eigen::Vector3d rgb_to_lab(const Eigen::Vector3d& rgb);

}  // namespace hc::markers
