// Camera frames as Foxglove's well-known image messages, protobuf-encoded, so Foxglove (and any
// protobuf reader) shows them: foxglove.RawImage and foxglove.CompressedImage
// (https://docs.foxglove.dev/docs/visualization/message-schemas/raw-image, /compressed-image).
//
// The protobuf wire format of these two small messages is hand-encoded (no libprotobuf dependency
// for five fields), and the schema each channel needs — a serialized
// google.protobuf.FileDescriptorSet holding foxglove/RawImage.proto (or CompressedImage.proto) and
// google/protobuf/timestamp.proto — is built by hand from the same field list.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "common/status.h"
#include "rig_daemon/recording/mcap_records.h"

namespace hc::recording {

inline constexpr std::string_view kRawImageSchemaName = "foxglove.RawImage";
inline constexpr std::string_view kCompressedImageSchemaName = "foxglove.CompressedImage";

// foxglove.RawImage. Field numbers: timestamp 1, frame_id 7, width 2, height 3, encoding 4,
// step 5, data 6.
struct RawImage {
  std::int64_t timestamp_ns = 0;  // device timestamp (ns); stored as google.protobuf.Timestamp
  std::string frame_id;           // coordinate frame, e.g. "camera0"
  std::uint32_t width = 0;        // pixels
  std::uint32_t height = 0;       // pixels
  std::string encoding;           // "mono8", "mono16", "rgb8", "bgr8", ... (Foxglove's names)
  std::uint32_t step = 0;         // bytes per row
  Bytes data;                     // step * height bytes
  bool operator==(const RawImage&) const = default;
};

// foxglove.CompressedImage. Field numbers: timestamp 1, frame_id 4, data 2, format 3.
struct CompressedImage {
  std::int64_t timestamp_ns = 0;
  std::string frame_id;
  Bytes data;          // the encoded image
  std::string format;  // "jpeg", "png", "webp", "avif"
  bool operator==(const CompressedImage&) const = default;
};

// Serialized FileDescriptorSet for Schema.data of the "protobuf" schema named k*SchemaName.
const Bytes& raw_image_schema();
const Bytes& compressed_image_schema();

// Appends the protobuf encoding to `out` (cleared first). The *_view variant of RawImage takes the
// pixels without copying them into a RawImage first (the recorder's hot path).
void encode_raw_image(const RawImage& image, Bytes& out);
void encode_raw_image_view(std::int64_t timestamp_ns, std::string_view frame_id,
                           std::uint32_t width, std::uint32_t height, std::string_view encoding,
                           std::uint32_t step, ByteSpan pixels, Bytes& out);
void encode_compressed_image(const CompressedImage& image, Bytes& out);

// Decoders: unknown fields are skipped, wrong wire types / truncated varints / lengths past the end
// are invalid_argument errors naming the field and byte position. decode_raw_image also checks
// data.size() >= step * height and step >= width * bytes-per-pixel for the encodings it knows.
Result<RawImage> decode_raw_image(ByteSpan data);
Result<CompressedImage> decode_compressed_image(ByteSpan data);

// Bytes per pixel for a Foxglove image encoding ("mono8" 1, "mono16" 2, "rgb8"/"bgr8" 3,
// "rgba8"/"bgra8" 4, "16UC1" 2, "32FC1" 4, "uyvy"/"yuyv" 2), or 0 when unknown.
std::uint32_t bytes_per_pixel(std::string_view encoding);

}  // namespace hc::recording
