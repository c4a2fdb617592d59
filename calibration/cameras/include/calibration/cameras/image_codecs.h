// Image files and compressed frames (PNG, JPEG, TIFF, ... — whatever OpenCV's image codecs read)
// as 8-bit grey. The codecs are loaded on first use: libopencv_imgcodecs brings ~110 shared
// libraries (GDAL, GDCM, video codecs) whose loading and relocation took 0.14 s of every
// `hardcopy` command and every process linking this library (`hardcopy --version`: 0.19 s with
// it, 0.05 s without), though only board detection decodes images. So nothing links it;
// image_codecs.cpp dlopens it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "calibration/cameras/board.h"
#include "common/status.h"

namespace hc::calib {

struct GreyImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> pixels;  // row-major, width bytes per row

  bool empty() const { return width == 0 || height == 0; }
  ImageView view() const { return {width, height, width, 1, pixels.data()}; }
};

// The image in `file` as grey (cv::imread, IMREAD_GRAYSCALE); empty when OpenCV cannot read it
// (missing, not an image). invalid_argument when OpenCV throws on it; failed_precondition when
// the codecs cannot be loaded.
Result<GreyImage> read_grey_image(const std::filesystem::path& file);
// An image file's contents decoded to grey (cv::imdecode); empty when undecodable.
Result<GreyImage> decode_grey_image(std::span<const std::uint8_t> bytes);

}  // namespace hc::calib
