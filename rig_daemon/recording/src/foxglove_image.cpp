// foxglove.RawImage / foxglove.CompressedImage in protobuf wire format, and their schemas as
// serialized FileDescriptorSets. Hand-written (see foxglove_image.h): the wire format of a handful
// of scalar / string / bytes fields is a few lines, and avoids a libprotobuf dependency.
#include "rig_daemon/recording/foxglove_image.h"

#include <fmt/format.h>

namespace hc::recording {
namespace {

// ---- protobuf wire format (https://protobuf.dev/programming-guides/encoding/) ----
enum WireType : std::uint8_t { kVarint = 0, kI64 = 1, kLen = 2, kI32 = 5 };

void put_varint(Bytes& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<std::uint8_t>(v | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<std::uint8_t>(v));
}
void put_tag(Bytes& out, std::uint32_t field, WireType wt) {
  put_varint(out, (static_cast<std::uint64_t>(field) << 3) | wt);
}
void put_len(Bytes& out, std::uint32_t field, ByteSpan data) {
  put_tag(out, field, kLen);
  put_varint(out, data.size());
  out.insert(out.end(), data.begin(), data.end());
}
void put_str(Bytes& out, std::uint32_t field, std::string_view s) {
  put_len(out, field, ByteSpan(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()));
}
void put_fixed32(Bytes& out, std::uint32_t field, std::uint32_t v) {
  put_tag(out, field, kI32);
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_varint_field(Bytes& out, std::uint32_t field, std::uint64_t v) {
  put_tag(out, field, kVarint);
  put_varint(out, v);
}

// google.protobuf.Timestamp {int64 seconds = 1; int32 nanos = 2;} with 0 <= nanos < 1e9.
Bytes timestamp_message(std::int64_t ns) {
  constexpr std::int64_t kNsPerS = 1'000'000'000;
  std::int64_t s = ns / kNsPerS;
  std::int64_t n = ns % kNsPerS;
  if (n < 0) {
    n += kNsPerS;
    s -= 1;
  }
  Bytes b;
  if (s != 0) put_varint_field(b, 1, static_cast<std::uint64_t>(s));  // int64: two's complement
  if (n != 0) put_varint_field(b, 2, static_cast<std::uint64_t>(n));
  return b;
}

// One field as read by the decoder.
struct Field {
  std::uint32_t number = 0;
  WireType type = kVarint;
  std::uint64_t value = 0;  // varint / fixed
  ByteSpan bytes;           // len-delimited
  std::size_t at = 0;       // byte position of the tag
};

class ProtoReader {
 public:
  ProtoReader(ByteSpan data, const char* message) : data_(data), message_(message) {}
  bool done() const { return pos_ >= data_.size(); }

  Result<std::uint64_t> varint() {
    std::uint64_t v = 0;
    for (int shift = 0; shift < 70; shift += 7) {
      if (pos_ >= data_.size())
        return invalid_argument(fmt::format("{}: truncated varint at byte {}", message_, pos_));
      const std::uint8_t b = data_[pos_++];
      if (shift == 63 && (b & 0x7E) != 0)
        return invalid_argument(
            fmt::format("{}: varint overflows 64 bits at byte {}", message_, pos_ - 1));
      v |= static_cast<std::uint64_t>(b & 0x7F) << shift;
      if ((b & 0x80) == 0) return v;
    }
    return invalid_argument(
        fmt::format("{}: varint longer than 10 bytes at byte {}", message_, pos_));
  }

  Result<Field> next() {
    Field f;
    f.at = pos_;
    HC_ASSIGN_OR_RETURN(const std::uint64_t tag, varint());
    f.number = static_cast<std::uint32_t>(tag >> 3);
    const auto wt = static_cast<std::uint8_t>(tag & 7);
    if (f.number == 0 || (tag >> 3) > 0x1FFFFFFF)
      return invalid_argument(fmt::format("{}: invalid field number at byte {}", message_, f.at));
    switch (wt) {
      case kVarint: {
        f.type = kVarint;
        HC_ASSIGN_OR_RETURN(f.value, varint());
        return f;
      }
      case kI64:
      case kI32: {
        f.type = static_cast<WireType>(wt);
        const std::size_t n = wt == kI64 ? 8 : 4;
        if (data_.size() - pos_ < n)
          return invalid_argument(
              fmt::format("{}: field {} truncated at byte {}", message_, f.number, f.at));
        for (std::size_t i = 0; i < n; ++i)
          f.value |= static_cast<std::uint64_t>(data_[pos_ + i]) << (8 * i);
        pos_ += n;
        return f;
      }
      case kLen: {
        f.type = kLen;
        HC_ASSIGN_OR_RETURN(const std::uint64_t n, varint());
        if (n > data_.size() - pos_)
          return invalid_argument(
              fmt::format("{}: field {} length {} exceeds the {} bytes left (byte {})", message_,
                          f.number, n, data_.size() - pos_, f.at));
        f.bytes = data_.subspan(pos_, static_cast<std::size_t>(n));
        pos_ += static_cast<std::size_t>(n);
        return f;
      }
      default:
        return invalid_argument(fmt::format("{}: unsupported wire type {} for field {} at byte {}",
                                            message_, wt, f.number, f.at));
    }
  }

 private:
  ByteSpan data_;
  const char* message_;
  std::size_t pos_ = 0;
};

Status expect(const Field& f, WireType t, const char* message, const char* name) {
  if (f.type != t)
    return invalid_argument(fmt::format("{}: field {} ({}) has wire type {}, expected {} (byte {})",
                                        message, f.number, name, static_cast<int>(f.type),
                                        static_cast<int>(t), f.at));
  return {};
}

Result<std::int64_t> decode_timestamp(ByteSpan data) {
  ProtoReader r(data, "google.protobuf.Timestamp");
  std::int64_t s = 0;
  std::int64_t n = 0;
  while (!r.done()) {
    HC_ASSIGN_OR_RETURN(const Field f, r.next());
    if (f.number == 1) {
      HC_RETURN_IF_ERROR(expect(f, kVarint, "Timestamp", "seconds"));
      s = static_cast<std::int64_t>(f.value);
    } else if (f.number == 2) {
      HC_RETURN_IF_ERROR(expect(f, kVarint, "Timestamp", "nanos"));
      n = static_cast<std::int32_t>(static_cast<std::uint32_t>(f.value));
    }
  }
  if (n < 0 || n >= 1'000'000'000)
    return invalid_argument(fmt::format("google.protobuf.Timestamp: nanos {} outside [0, 1e9)", n));
  constexpr std::int64_t kLimit = 9'223'372'035;  // |seconds| that fit in int64 ns
  if (s > kLimit || s < -kLimit)
    return invalid_argument(
        fmt::format("google.protobuf.Timestamp: seconds {} overflow int64 ns", s));
  return s * 1'000'000'000 + n;
}

std::string to_string(ByteSpan b) { return std::string(b.begin(), b.end()); }

// ---- descriptors (google/protobuf/descriptor.proto field numbers) ----
// FieldDescriptorProto.Type values.
constexpr std::uint64_t kTypeInt64 = 3, kTypeInt32 = 5, kTypeFixed32 = 7, kTypeString = 9,
                        kTypeMessage = 11, kTypeBytes = 12;
constexpr std::uint64_t kLabelOptional = 1;

struct FieldDesc {
  const char* name;
  std::uint32_t number;
  std::uint64_t type;
  const char* type_name;  // for messages
  const char* json_name;
};

Bytes field_descriptor(const FieldDesc& f) {
  Bytes b;
  put_str(b, 1, f.name);             // name
  put_varint_field(b, 3, f.number);  // number
  put_varint_field(b, 4, kLabelOptional);
  put_varint_field(b, 5, f.type);
  if (f.type_name != nullptr) put_str(b, 6, f.type_name);
  put_str(b, 10, f.json_name);
  return b;
}

Bytes file_descriptor(const char* file, const char* package, const char* dependency,
                      const char* message, std::initializer_list<FieldDesc> fields) {
  Bytes msg;
  put_str(msg, 1, message);
  for (const auto& f : fields) put_len(msg, 2, field_descriptor(f));
  Bytes fd;
  put_str(fd, 1, file);
  put_str(fd, 2, package);
  if (dependency != nullptr) put_str(fd, 3, dependency);
  put_len(fd, 4, msg);
  put_str(fd, 12, "proto3");
  return fd;
}

Bytes timestamp_file() {
  return file_descriptor(
      "google/protobuf/timestamp.proto", "google.protobuf", nullptr, "Timestamp",
      {{"seconds", 1, kTypeInt64, nullptr, "seconds"}, {"nanos", 2, kTypeInt32, nullptr, "nanos"}});
}

Bytes descriptor_set(std::initializer_list<Bytes> files) {
  Bytes set;
  for (const auto& f : files) put_len(set, 1, f);
  return set;
}

}  // namespace

const Bytes& raw_image_schema() {
  static const Bytes schema = descriptor_set(
      {timestamp_file(),
       file_descriptor("foxglove/RawImage.proto", "foxglove", "google/protobuf/timestamp.proto",
                       "RawImage",
                       {{"timestamp", 1, kTypeMessage, ".google.protobuf.Timestamp", "timestamp"},
                        {"frame_id", 7, kTypeString, nullptr, "frameId"},
                        {"width", 2, kTypeFixed32, nullptr, "width"},
                        {"height", 3, kTypeFixed32, nullptr, "height"},
                        {"encoding", 4, kTypeString, nullptr, "encoding"},
                        {"step", 5, kTypeFixed32, nullptr, "step"},
                        {"data", 6, kTypeBytes, nullptr, "data"}})});
  return schema;
}

const Bytes& compressed_image_schema() {
  static const Bytes schema = descriptor_set(
      {timestamp_file(),
       file_descriptor("foxglove/CompressedImage.proto", "foxglove",
                       "google/protobuf/timestamp.proto", "CompressedImage",
                       {{"timestamp", 1, kTypeMessage, ".google.protobuf.Timestamp", "timestamp"},
                        {"frame_id", 4, kTypeString, nullptr, "frameId"},
                        {"data", 2, kTypeBytes, nullptr, "data"},
                        {"format", 3, kTypeString, nullptr, "format"}})});
  return schema;
}

std::uint32_t bytes_per_pixel(std::string_view e) {
  if (e == "mono8" || e == "8UC1" || e.starts_with("bayer_")) return 1;
  if (e == "mono16" || e == "16UC1" || e == "uyvy" || e == "yuyv" || e == "yuv422" ||
      e == "yuv422_yuy2")
    return 2;
  if (e == "rgb8" || e == "bgr8" || e == "8UC3") return 3;
  if (e == "rgba8" || e == "bgra8" || e == "32FC1") return 4;
  return 0;
}

void encode_raw_image_view(std::int64_t timestamp_ns, std::string_view frame_id,
                           std::uint32_t width, std::uint32_t height, std::string_view encoding,
                           std::uint32_t step, ByteSpan pixels, Bytes& out) {
  out.clear();
  out.reserve(pixels.size() + 64 + frame_id.size() + encoding.size());
  put_len(out, 1, timestamp_message(timestamp_ns));
  put_str(out, 7, frame_id);
  put_fixed32(out, 2, width);
  put_fixed32(out, 3, height);
  put_str(out, 4, encoding);
  put_fixed32(out, 5, step);
  put_len(out, 6, pixels);
}

void encode_raw_image(const RawImage& im, Bytes& out) {
  encode_raw_image_view(im.timestamp_ns, im.frame_id, im.width, im.height, im.encoding, im.step,
                        im.data, out);
}

void encode_compressed_image(const CompressedImage& im, Bytes& out) {
  out.clear();
  out.reserve(im.data.size() + 48 + im.frame_id.size());
  put_len(out, 1, timestamp_message(im.timestamp_ns));
  put_str(out, 4, im.frame_id);
  put_len(out, 2, im.data);
  put_str(out, 3, im.format);
}

Result<RawImage> decode_raw_image(ByteSpan data) {
  ProtoReader r(data, "foxglove.RawImage");
  RawImage im;
  const char* m = "foxglove.RawImage";
  while (!r.done()) {
    HC_ASSIGN_OR_RETURN(const Field f, r.next());
    switch (f.number) {
      case 1: {
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "timestamp"));
        HC_ASSIGN_OR_RETURN(im.timestamp_ns, decode_timestamp(f.bytes));
        break;
      }
      case 7:
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "frame_id"));
        im.frame_id = to_string(f.bytes);
        break;
      case 2:
        HC_RETURN_IF_ERROR(expect(f, kI32, m, "width"));
        im.width = static_cast<std::uint32_t>(f.value);
        break;
      case 3:
        HC_RETURN_IF_ERROR(expect(f, kI32, m, "height"));
        im.height = static_cast<std::uint32_t>(f.value);
        break;
      case 4:
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "encoding"));
        im.encoding = to_string(f.bytes);
        break;
      case 5:
        HC_RETURN_IF_ERROR(expect(f, kI32, m, "step"));
        im.step = static_cast<std::uint32_t>(f.value);
        break;
      case 6:
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "data"));
        im.data.assign(f.bytes.begin(), f.bytes.end());
        break;
      default:
        break;  // unknown fields are skipped
    }
  }
  const std::uint64_t need = static_cast<std::uint64_t>(im.step) * im.height;
  if (im.data.size() < need)
    return invalid_argument(
        fmt::format("foxglove.RawImage: {} data bytes, step {} x height {} needs {}",
                    im.data.size(), im.step, im.height, need));
  if (const std::uint32_t bpp = bytes_per_pixel(im.encoding);
      bpp != 0 && static_cast<std::uint64_t>(im.step) < static_cast<std::uint64_t>(im.width) * bpp)
    return invalid_argument(
        fmt::format("foxglove.RawImage: step {} < width {} x {} bytes per pixel ({})", im.step,
                    im.width, bpp, im.encoding));
  return im;
}

Result<CompressedImage> decode_compressed_image(ByteSpan data) {
  ProtoReader r(data, "foxglove.CompressedImage");
  CompressedImage im;
  const char* m = "foxglove.CompressedImage";
  while (!r.done()) {
    HC_ASSIGN_OR_RETURN(const Field f, r.next());
    switch (f.number) {
      case 1: {
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "timestamp"));
        HC_ASSIGN_OR_RETURN(im.timestamp_ns, decode_timestamp(f.bytes));
        break;
      }
      case 4:
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "frame_id"));
        im.frame_id = to_string(f.bytes);
        break;
      case 2:
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "data"));
        im.data.assign(f.bytes.begin(), f.bytes.end());
        break;
      case 3:
        HC_RETURN_IF_ERROR(expect(f, kLen, m, "format"));
        im.format = to_string(f.bytes);
        break;
      default:
        break;
    }
  }
  return im;
}

}  // namespace hc::recording
