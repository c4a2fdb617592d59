#include "processing/markers/dots.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace hc::markers {
namespace {

// OpenCV may throw cv::Exception on inputs we did not foresee: turn it into a Status here.
template <typename F>
Status guard_opencv(const char* what, F&& f) {
  try {
    f();
  } catch (const cv::Exception& e) {
    return internal_error(fmt::format("{}: OpenCV: {}", what, e.what()));
  }
  return {};
}

cv::Mat wrap(const ImageView& image) {
  // The view is read-only; OpenCV's Mat has no const element type, so the cast only lets us build
  // a header. Nothing below writes through it.
  return cv::Mat(image.height, image.width, image.format == PixelFormat::kRgb8 ? CV_8UC3 : CV_8UC1,
                 const_cast<std::uint8_t*>(image.data),
                 static_cast<std::size_t>(image.stride_bytes));
}

Status check_area_roundness(double min_area, double max_area, double min_roundness) {
  if (!(min_area >= 0.0) || !(max_area >= min_area) || !std::isfinite(max_area))
    return invalid_argument(
        fmt::format("dot area bounds [{}, {}] px are not a valid range", min_area, max_area));
  if (!(min_roundness >= 0.0 && min_roundness <= 1.0))
    return invalid_argument(fmt::format("min_roundness {} is not in [0, 1]", min_roundness));
  return {};
}

// Second-moment roundness of a component: ratio of the covariance eigenvalues (1 for a disc).
double roundness_from_moments(double n, double sx, double sy, double sxx, double syy, double sxy) {
  if (n < 2.0) return 1.0;
  const double mx = sx / n, my = sy / n;
  // + 1/12: a pixel is a unit square, so even a single row of pixels has some spread in y.
  const double cxx = sxx / n - mx * mx + 1.0 / 12.0;
  const double cyy = syy / n - my * my + 1.0 / 12.0;
  const double cxy = sxy / n - mx * my;
  const double tr = cxx + cyy;
  const double det = cxx * cyy - cxy * cxy;
  const double disc = std::sqrt(std::max(0.0, tr * tr / 4.0 - det));
  const double l1 = tr / 2.0 + disc, l2 = tr / 2.0 - disc;
  return l1 > 0.0 ? std::clamp(l2 / l1, 0.0, 1.0) : 1.0;
}

struct ComponentStats {
  int x = 0, y = 0, w = 0, h = 0;
  int area = 0;
};

bool touches_border(const ComponentStats& c, int width, int height) {
  return c.x <= 0 || c.y <= 0 || c.x + c.w >= width || c.y + c.h >= height;
}

// Moments of one component's pixels in its bounding box; mean colour from the source image.
struct Moments {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  Eigen::Vector3d color_sum = Eigen::Vector3d::Zero();
};

Moments component_moments(const cv::Mat& labels, int label, const ComponentStats& c,
                          const cv::Mat& source) {
  Moments m;
  const int channels = source.channels();
  for (int y = c.y; y < c.y + c.h; ++y) {
    const int* lrow = labels.ptr<int>(y);
    const std::uint8_t* srow = source.ptr<std::uint8_t>(y);
    for (int x = c.x; x < c.x + c.w; ++x) {
      if (lrow[x] != label) continue;
      m.n += 1;
      m.sx += x;
      m.sy += y;
      m.sxx += static_cast<double>(x) * x;
      m.syy += static_cast<double>(y) * y;
      m.sxy += static_cast<double>(x) * y;
      if (channels == 3) {
        m.color_sum += Eigen::Vector3d(srow[3 * x], srow[3 * x + 1], srow[3 * x + 2]);
      } else {
        m.color_sum += Eigen::Vector3d::Constant(srow[x]);
      }
    }
  }
  return m;
}

// The steps both detectors share (thesis 4.4.2): morphological closing of the mask, 8-connected
// components, then the area, image-border and roundness filters. Calls
// fn(labels, label, stats, moments, roundness) for every component that passes.
template <typename Options, typename Fn>
void for_each_dot_component(cv::Mat& mask, const cv::Mat& src, const ImageView& image,
                            const Options& options, Fn&& fn) {
  if (options.closing_radius_px > 0) {
    const int k = 2 * options.closing_radius_px + 1;
    cv::morphologyEx(mask, mask, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  }
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  for (int l = 1; l < n; ++l) {
    const ComponentStats c{stats.at<int>(l, cv::CC_STAT_LEFT), stats.at<int>(l, cv::CC_STAT_TOP),
                           stats.at<int>(l, cv::CC_STAT_WIDTH),
                           stats.at<int>(l, cv::CC_STAT_HEIGHT),
                           stats.at<int>(l, cv::CC_STAT_AREA)};
    if (c.area < options.min_area_px || c.area > options.max_area_px) continue;
    if (options.drop_border_dots && touches_border(c, image.width, image.height)) continue;
    const Moments m = component_moments(labels, l, c, src);
    const double roundness = roundness_from_moments(m.n, m.sx, m.sy, m.sxx, m.syy, m.sxy);
    if (roundness < options.min_roundness) continue;
    fn(labels, l, c, m, roundness);
  }
}

}  // namespace

Status ImageView::validate() const {
  if (data == nullptr) return invalid_argument("image view has no pixel data");
  if (width <= 0 || height <= 0)
    return invalid_argument(fmt::format("image size {}x{} is not positive", width, height));
  if (stride_bytes < static_cast<std::ptrdiff_t>(width) * channels())
    return invalid_argument(fmt::format("image stride {} bytes is shorter than a row of {} px x {}",
                                        stride_bytes, width, channels()));
  return {};
}

Status BlobOptions::validate() const {
  if (threshold == ThresholdMethod::kLocalMean && (local_block_px < 3 || local_block_px % 2 == 0))
    return invalid_argument(
        fmt::format("local_block_px {} must be an odd number >= 3", local_block_px));
  if (!std::isfinite(local_offset)) return invalid_argument("local_offset is not finite");
  if (closing_radius_px < 0 || closing_radius_px > 50)
    return invalid_argument(
        fmt::format("closing_radius_px {} is not in [0, 50]", closing_radius_px));
  if (centroid_margin_px < 0 || centroid_margin_px > 50)
    return invalid_argument(
        fmt::format("centroid_margin_px {} is not in [0, 50]", centroid_margin_px));
  return check_area_roundness(min_area_px, max_area_px, min_roundness);
}

Status ColorDotOptions::validate() const {
  if (colors.empty()) return invalid_argument("no marker colours given");
  for (std::size_t i = 0; i < colors.size(); ++i) {
    const ColorClass& c = colors[i];
    if (!c.lab_min.allFinite() || !c.lab_max.allFinite() ||
        (c.lab_max.array() < c.lab_min.array()).any())
      return invalid_argument(
          fmt::format("colour {} ('{}'): Lab box is empty or not finite", i, c.name));
  }
  if (closing_radius_px < 0 || closing_radius_px > 50)
    return invalid_argument(
        fmt::format("closing_radius_px {} is not in [0, 50]", closing_radius_px));
  return check_area_roundness(min_area_px, max_area_px, min_roundness);
}

Result<std::vector<Dot>> detect_blobs(const ImageView& image, const BlobOptions& options) {
  HC_RETURN_IF_ERROR(image.validate());
  HC_RETURN_IF_ERROR(options.validate());
  std::vector<Dot> dots;
  const Status st = guard_opencv("detect_blobs", [&] {
    const cv::Mat src = wrap(image);
    cv::Mat grey;
    if (image.format == PixelFormat::kRgb8) {
      cv::cvtColor(src, grey, cv::COLOR_RGB2GRAY);
    } else {
      grey = src;
    }
    if (options.polarity == Polarity::kDark) {
      cv::Mat inverted;
      cv::bitwise_not(grey, inverted);
      grey = inverted;
    }
    cv::Mat mask;
    if (options.threshold == ThresholdMethod::kOtsu) {
      cv::threshold(grey, mask, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
    } else {
      cv::adaptiveThreshold(grey, mask, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY,
                            options.local_block_px, -options.local_offset);
    }
    for_each_dot_component(mask, src, image, options,
                           [&](const cv::Mat& labels, int l, const ComponentStats& c,
                               const Moments& m, double roundness) {
                             // Intensity-weighted centroid over the box plus a margin, weight =
                             // grey - background, where the background is the median of the
                             // window's outer ring (outside the dot by the margin). Pixels of other
                             // components are skipped. The weights are not clamped at zero:
                             // clamping would turn zero-mean noise into a pull towards the window
                             // centre.
                             const int m_px = options.centroid_margin_px;
                             const int x0 = std::max(0, c.x - m_px), y0 = std::max(0, c.y - m_px);
                             const int x1 = std::min(image.width - 1, c.x + c.w - 1 + m_px);
                             const int y1 = std::min(image.height - 1, c.y + c.h - 1 + m_px);
                             std::vector<std::uint8_t> ring;
                             ring.reserve(static_cast<std::size_t>(2 * (x1 - x0 + y1 - y0 + 2)));
                             for (int y = y0; y <= y1; ++y) {
                               const std::uint8_t* g = grey.ptr<std::uint8_t>(y);
                               const int* lr = labels.ptr<int>(y);
                               for (int x = x0; x <= x1; ++x) {
                                 const bool edge = (y == y0 || y == y1 || x == x0 || x == x1);
                                 if (edge && (lr[x] == 0)) ring.push_back(g[x]);
                               }
                             }
                             double background = 0.0;
                             if (!ring.empty()) {
                               auto mid =
                                   ring.begin() + static_cast<std::ptrdiff_t>(ring.size() / 2);
                               std::nth_element(ring.begin(), mid, ring.end());
                               background = *mid;
                             }
                             double sw = 0, swx = 0, swy = 0, sw_pos = 0;
                             for (int y = y0; y <= y1; ++y) {
                               const std::uint8_t* g = grey.ptr<std::uint8_t>(y);
                               const int* lr = labels.ptr<int>(y);
                               for (int x = x0; x <= x1; ++x) {
                                 if (lr[x] != 0 && lr[x] != l) continue;
                                 const double w = static_cast<double>(g[x]) - background;
                                 sw += w;
                                 sw_pos += std::max(0.0, w);
                                 swx += w * x;
                                 swy += w * y;
                               }
                             }
                             Dot d;
                             // A weak or inverted contrast (the negative weights cancel most of the
                             // positive ones) makes the weighted centroid meaningless: use the
                             // thresholded component's centroid then.
                             const Eigen::Vector2d weighted(swx / sw, swy / sw);
                             if (sw > 0.5 * sw_pos && sw > 0.0 && weighted.x() >= x0 &&
                                 weighted.x() <= x1 && weighted.y() >= y0 && weighted.y() <= y1) {
                               d.center_px = weighted;
                             } else {
                               d.center_px = Eigen::Vector2d(m.sx / m.n, m.sy / m.n);
                             }
                             d.area_px = c.area;
                             d.roundness = roundness;
                             d.mean_color = m.color_sum / m.n;
                             dots.push_back(d);
                           });
  });
  HC_RETURN_IF_ERROR(st);
  std::sort(dots.begin(), dots.end(), [](const Dot& a, const Dot& b) {
    return a.center_px.y() != b.center_px.y() ? a.center_px.y() < b.center_px.y()
                                              : a.center_px.x() < b.center_px.x();
  });
  return dots;
}

Eigen::Vector3d rgb_to_lab(const Eigen::Vector3d& rgb) {
  cv::Mat px(1, 1, CV_8UC3);
  for (int c = 0; c < 3; ++c)
    px.at<cv::Vec3b>(0, 0)[c] = cv::saturate_cast<std::uint8_t>(std::lround(rgb[c]));
  cv::Mat lab;
  cv::cvtColor(px, lab, cv::COLOR_RGB2Lab);
  const cv::Vec3b v = lab.at<cv::Vec3b>(0, 0);
  return {v[0] * 100.0 / 255.0, v[1] - 128.0, v[2] - 128.0};
}

Result<std::vector<Dot>> detect_color_dots(const ImageView& image, const ColorDotOptions& options) {
  HC_RETURN_IF_ERROR(image.validate());
  HC_RETURN_IF_ERROR(options.validate());
  if (image.format != PixelFormat::kRgb8)
    return invalid_argument("coloured dot detection needs an RGB8 image (got Mono8)");
  std::vector<Dot> dots;
  const Status st = guard_opencv("detect_color_dots", [&] {
    const cv::Mat src = wrap(image);
    cv::Mat lab;
    cv::cvtColor(src, lab, cv::COLOR_RGB2Lab);  // 8-bit: L*255/100, a+128, b+128
    const auto to_cv = [](const Eigen::Vector3d& v) {
      return cv::Scalar(std::clamp(v[0] * 255.0 / 100.0, 0.0, 255.0),
                        std::clamp(v[1] + 128.0, 0.0, 255.0), std::clamp(v[2] + 128.0, 0.0, 255.0));
    };
    for (std::size_t ci = 0; ci < options.colors.size(); ++ci) {
      const ColorClass& cc = options.colors[ci];
      cv::Mat mask;
      cv::inRange(lab, to_cv(cc.lab_min), to_cv(cc.lab_max), mask);
      const Eigen::Vector3d centre = 0.5 * (cc.lab_min + cc.lab_max);
      const Eigen::Vector3d half =
          (0.5 * (cc.lab_max - cc.lab_min)).cwiseMax(Eigen::Vector3d::Constant(1e-6));
      std::vector<Dot> class_dots;
      for_each_dot_component(
          mask, src, image, options,
          [&](const cv::Mat& labels, int l, const ComponentStats& c, const Moments& m,
              double roundness) {
            double sw = 0, swx = 0, swy = 0;
            for (int y = c.y; y < c.y + c.h; ++y) {
              const int* lr = labels.ptr<int>(y);
              const cv::Vec3b* lrow = lab.ptr<cv::Vec3b>(y);
              for (int x = c.x; x < c.x + c.w; ++x) {
                if (lr[x] != l) continue;
                double w = 1.0;
                if (options.weighted_centroid) {
                  const Eigen::Vector3d v(lrow[x][0] * 100.0 / 255.0, lrow[x][1] - 128.0,
                                          lrow[x][2] - 128.0);
                  const double dist = ((v - centre).cwiseAbs().cwiseQuotient(half)).maxCoeff();
                  // Pixels the closing added (outside the box) still count a little.
                  w = std::max(0.05, 1.0 - 0.5 * dist);
                }
                sw += w;
                swx += w * x;
                swy += w * y;
              }
            }
            Dot d;
            d.center_px = Eigen::Vector2d(swx / sw, swy / sw);
            d.area_px = c.area;
            d.roundness = roundness;
            d.mean_color = m.color_sum / m.n;
            d.color_class = static_cast<int>(ci);
            class_dots.push_back(d);
          });
      std::sort(class_dots.begin(), class_dots.end(), [](const Dot& a, const Dot& b) {
        return a.center_px.y() != b.center_px.y() ? a.center_px.y() < b.center_px.y()
                                                  : a.center_px.x() < b.center_px.x();
      });
      dots.insert(dots.end(), class_dots.begin(), class_dots.end());
    }
  });
  HC_RETURN_IF_ERROR(st);
  return dots;
}

}  // namespace hc::markers
