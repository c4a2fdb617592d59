#include "rig_daemon/devices/types.h"

#include <algorithm>
#include <cmath>

namespace hc::devices {

std::string_view to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return "mono8";
    case PixelFormat::kMono16:
      return "mono16";
    case PixelFormat::kRgb8:
      return "rgb8";
    case PixelFormat::kBgr8:
      return "bgr8";
    case PixelFormat::kYuyv:
      return "yuyv";
    case PixelFormat::kMjpeg:
      return "mjpeg";
  }
  return "unknown";
}

std::optional<PixelFormat> pixel_format_from_string(std::string_view name) {
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kMono16, PixelFormat::kRgb8,
                        PixelFormat::kBgr8, PixelFormat::kYuyv, PixelFormat::kMjpeg})
    if (to_string(f) == name) return f;
  return std::nullopt;
}

std::string_view foxglove_encoding(PixelFormat format) {
  // foxglove.RawImage `encoding` spellings (foxglove/schemas RawImage.proto); JPEG goes in
  // foxglove.CompressedImage with format "jpeg".
  return format == PixelFormat::kMjpeg ? "jpeg" : to_string(format);
}

std::size_t bytes_per_pixel(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return 1;
    case PixelFormat::kMono16:
      return 2;
    case PixelFormat::kRgb8:
    case PixelFormat::kBgr8:
      return 3;
    case PixelFormat::kYuyv:
      return 2;
    case PixelFormat::kMjpeg:
      return 0;
  }
  return 0;
}

bool Frame::valid() const {
  if (format == PixelFormat::kMjpeg) return !pixels.empty();
  if (width == 0 || height == 0) return false;
  const std::size_t row = std::size_t{width} * bytes_per_pixel(format);
  if (stride_bytes < row) return false;
  return pixels.size() >= std::size_t{stride_bytes} * (height - 1) + row;
}

double FsrCalibration::to_newtons(double raw) const {
  if (!(full_scale > 0.0) || !(threshold < 1.0)) return 0.0;
  const double x = raw / full_scale;
  if (!(x > threshold)) return 0.0;
  return scale_n * std::pow((x - threshold) / (1.0 - threshold), exponent);
}

double FsrCalibration::to_raw(double force_n) const {
  if (!(force_n > 0.0) || !(scale_n > 0.0) || !(exponent > 0.0)) return threshold * full_scale;
  const double x = threshold + (1.0 - threshold) * std::pow(force_n / scale_n, 1.0 / exponent);
  return x * full_scale;
}

bool ArmLimits::contains(const ArmPose& p) const {
  const auto in = [](double v, double lo, double hi) { return v >= lo && v <= hi; };
  return in(p.x_m, min.x_m, max.x_m) && in(p.y_m, min.y_m, max.y_m) &&
         in(p.z_m, min.z_m, max.z_m) && in(p.yaw_rad, min.yaw_rad, max.yaw_rad);
}

}  // namespace hc::devices
