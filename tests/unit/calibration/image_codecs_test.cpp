// The lazily loaded image codecs (image_codecs.cpp dlopens libopencv_imgcodecs) against OpenCV
// linked the ordinary way (this test links it): the same pixels from a file and from its bytes,
// and empty images, not crashes, from what is no image.
#include "calibration/cameras/image_codecs.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>

#include "test_data.h"

namespace hc::calib {
namespace {

using hc::testing::shared_data;

std::vector<std::uint8_t> file_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void expect_same(const GreyImage& ours, const cv::Mat& theirs) {
  ASSERT_EQ(ours.width, theirs.cols);
  ASSERT_EQ(ours.height, theirs.rows);
  for (int r = 0; r < theirs.rows; ++r)
    ASSERT_TRUE(std::equal(theirs.ptr<std::uint8_t>(r), theirs.ptr<std::uint8_t>(r) + theirs.cols,
                           ours.pixels.begin() + static_cast<std::ptrdiff_t>(r) * ours.width))
        << "row " << r;
}

TEST(ImageCodecs, ReadAndDecodeMatchOpenCv) {
  // A JPEG of the OpenCV sample stereo set (MANIFEST.md) and a PNG written here.
  const auto jpeg = shared_data("calibration/opencv_stereo") / "left01.jpg";
  const cv::Mat reference = cv::imread(jpeg.string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(reference.empty());
  Result<GreyImage> read = read_grey_image(jpeg);
  ASSERT_TRUE(read.ok()) << read.status().to_string();
  expect_same(*read, reference);
  const std::vector<std::uint8_t> bytes = file_bytes(jpeg);
  Result<GreyImage> decoded = decode_grey_image(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.status().to_string();
  expect_same(*decoded, reference);

  cv::Mat gradient(37, 53, CV_8UC1);  // odd width: OpenCV pads nothing, we pack rows
  for (int r = 0; r < gradient.rows; ++r)
    for (int c = 0; c < gradient.cols; ++c) gradient.at<std::uint8_t>(r, c) = (r * 7 + c * 3) % 256;
  std::vector<std::uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", gradient, png));
  Result<GreyImage> lossless = decode_grey_image(png);
  ASSERT_TRUE(lossless.ok());
  expect_same(*lossless, gradient);
}

TEST(ImageCodecs, WhatIsNoImageGivesAnEmptyImage) {
  Result<GreyImage> missing = read_grey_image("/nonexistent/left01.jpg");
  ASSERT_TRUE(missing.ok());
  EXPECT_TRUE(missing->empty());
  const std::vector<std::uint8_t> garbage = {0x89, 'P', 'N', 'G', 1, 2, 3, 4, 5};
  Result<GreyImage> truncated = decode_grey_image(garbage);
  ASSERT_TRUE(truncated.ok());
  EXPECT_TRUE(truncated->empty());
  Result<GreyImage> nothing = decode_grey_image({});
  ASSERT_TRUE(nothing.ok());
  EXPECT_TRUE(nothing->empty());
}

}  // namespace
}  // namespace hc::calib
