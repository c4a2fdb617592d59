// foxglove.RawImage / CompressedImage protobuf encoding: byte-exact against an encoding derived by
// hand from the protobuf wire-format specification, round trips, malformed input. (The schemas'
// FileDescriptorSets are checked by protobufjs in interop_test.cpp, as Foxglove reads them.)
#include <gtest/gtest.h>

#include <algorithm>

#include "rig_daemon/recording/foxglove_image.h"

namespace hc::recording {
namespace {

TEST(FoxgloveImage, RawImageByteExact) {
  RawImage im;
  im.timestamp_ns = 1'500'000'000;  // seconds 1, nanos 500000000
  im.frame_id = "c";
  im.width = 2;
  im.height = 1;
  im.encoding = "mono8";
  im.step = 2;
  im.data = {7, 9};
  Bytes out;
  encode_raw_image(im, out);
  // https://protobuf.dev/programming-guides/encoding/: tag = field << 3 | wire type.
  const Bytes expected = {
      0x0A, 0x08,                               // 1 timestamp, LEN 8
      0x08, 0x01,                               //   seconds = 1 (varint)
      0x10, 0x80, 0xCA, 0xB5, 0xEE, 0x01,       //   nanos = 500000000 (varint)
      0x3A, 0x01, 'c',                          // 7 frame_id
      0x15, 0x02, 0x00, 0x00, 0x00,             // 2 width, fixed32
      0x1D, 0x01, 0x00, 0x00, 0x00,             // 3 height, fixed32
      0x22, 0x05, 'm',  'o',  'n',  'o',  '8',  // 4 encoding
      0x2D, 0x02, 0x00, 0x00, 0x00,             // 5 step, fixed32
      0x32, 0x02, 0x07, 0x09,                   // 6 data
  };
  EXPECT_EQ(out, expected);
  auto back = decode_raw_image(out);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(*back, im);
}

TEST(FoxgloveImage, RoundTripsAndNegativeTimestamps) {
  for (std::int64_t t : {0LL, 1LL, -1LL, -1'500'000'001LL, 9'000'000'000'000'000'000LL}) {
    RawImage im{t, "cam", 1600, 2, "mono16", 3200, Bytes(6400, 0xAB)};
    Bytes out;
    encode_raw_image(im, out);
    auto back = decode_raw_image(out);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    EXPECT_EQ(*back, im);
  }
  CompressedImage c{42, "cam1", {0xFF, 0xD8, 0xFF}, "jpeg"};
  Bytes out;
  encode_compressed_image(c, out);
  auto back = decode_compressed_image(out);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, c);
}

TEST(FoxgloveImage, MalformedInput) {
  RawImage im{5, "c", 4, 2, "mono8", 4, Bytes(8, 1)};
  Bytes good;
  encode_raw_image(im, good);
  // Truncated: inside the leading timestamp field, or anywhere from the data field's tag on
  // (the data length then runs past the end, or the pixels are missing: 8 < step * height).
  const std::size_t ts_end = 2 + good[1];
  for (std::size_t n = 1; n < ts_end; ++n)
    EXPECT_FALSE(decode_raw_image(ByteSpan(good).first(n)).ok()) << n;
  for (std::size_t n = good.size() - 10; n < good.size(); ++n)
    EXPECT_FALSE(decode_raw_image(ByteSpan(good).first(n)).ok()) << "prefix " << n;
  // Wrong wire type for width (varint instead of fixed32).
  Bytes wrong = {0x10, 0x05};
  auto w = decode_raw_image(wrong);
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("width"), std::string::npos) << w.status().message();
  // Over-long varint.
  Bytes longv = {0x08, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01};
  EXPECT_FALSE(decode_raw_image(longv).ok());
  // step < width * bytes per pixel.
  RawImage narrow{0, "", 4, 1, "rgb8", 4, Bytes(4)};
  Bytes n;
  encode_raw_image(narrow, n);
  EXPECT_FALSE(decode_raw_image(n).ok());
  // Unknown fields are skipped.
  Bytes extra = good;
  extra.insert(extra.end(), {0x48, 0x2A});  // field 9 varint 42
  EXPECT_TRUE(decode_raw_image(extra).ok());
  // Timestamp nanos out of range.
  Bytes badts = {0x0A, 0x06, 0x10, 0x80, 0x94, 0xEB, 0xDC, 0x03};  // nanos = 1e9
  EXPECT_FALSE(decode_compressed_image(badts).ok());
}

TEST(FoxgloveImage, SchemasNameTheirMessages) {
  // The descriptor sets carry both files; spot-check the names inside the serialized bytes.
  auto has = [](const Bytes& b, std::string_view s) {
    return std::search(b.begin(), b.end(), s.begin(), s.end()) != b.end();
  };
  EXPECT_TRUE(has(raw_image_schema(), "foxglove/RawImage.proto"));
  EXPECT_TRUE(has(raw_image_schema(), "google/protobuf/timestamp.proto"));
  EXPECT_TRUE(has(raw_image_schema(), ".google.protobuf.Timestamp"));
  EXPECT_TRUE(has(compressed_image_schema(), "CompressedImage"));
  EXPECT_EQ(bytes_per_pixel("mono8"), 1u);
  EXPECT_EQ(bytes_per_pixel("bgr8"), 3u);
  EXPECT_EQ(bytes_per_pixel("weird"), 0u);
}

}  // namespace
}  // namespace hc::recording
