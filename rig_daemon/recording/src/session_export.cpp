// export_channel / encode_png (see mcap_tools.h).
#include <png.h>

#include <algorithm>
#include <cstring>

#include <fmt/format.h>

#include "common/file_io.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_tools.h"
#include "rig_daemon/recording/session_conventions.h"

namespace hc::recording {
namespace {

std::string file_safe(std::string_view topic) {
  std::string out;
  for (char c : topic) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '.';
    out.push_back(ok ? c : '_');
  }
  while (!out.empty() && out.front() == '_') out.erase(out.begin());
  if (out.empty()) out = "channel";
  return out;
}

// RFC 4180 quoting when needed.
std::string csv_cell(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q.push_back('"');
    q.push_back(c);
  }
  q.push_back('"');
  return q;
}

std::string json_scalar_text(const Json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_null()) return "";
  return v.dump();
}

// Flattens objects ("a.b") and arrays ("a[2]") down to scalars.
void flatten(const Json& j, const std::string& prefix,
             std::vector<std::pair<std::string, std::string>>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      flatten(it.value(), prefix.empty() ? it.key() : prefix + "." + it.key(), out);
  } else if (j.is_array()) {
    for (std::size_t i = 0; i < j.size(); ++i) flatten(j[i], fmt::format("{}[{}]", prefix, i), out);
  } else {
    out.emplace_back(prefix.empty() ? "value" : prefix, json_scalar_text(j));
  }
}

}  // namespace

Json ExportReport::to_json() const {
  Json files_json = Json::array();
  for (const auto& f : files) files_json.push_back(f.string());
  return Json{{"topic", topic}, {"kind", kind}, {"messages", messages}, {"files", files_json}};
}

Result<std::string> encode_png(std::uint32_t width, std::uint32_t height, int channels,
                               int bit_depth, bool bgr, std::uint32_t step, ByteSpan pixels) {
  if (width == 0 || height == 0) return invalid_argument("encode_png: empty image");
  if (channels != 1 && channels != 3 && channels != 4)
    return invalid_argument(fmt::format("encode_png: {} channels (expected 1, 3 or 4)", channels));
  if (bit_depth != 8 && bit_depth != 16)
    return invalid_argument(fmt::format("encode_png: bit depth {} (expected 8 or 16)", bit_depth));
  const std::uint64_t row = static_cast<std::uint64_t>(width) *
                            static_cast<std::uint64_t>(channels) *
                            static_cast<std::uint64_t>(bit_depth / 8);
  if (step < row || static_cast<std::uint64_t>(step) * height > pixels.size())
    return invalid_argument(
        fmt::format("encode_png: {} bytes for {}x{} with step {} (row {} bytes)", pixels.size(),
                    width, height, step, row));
  // PNG stores 16-bit samples big-endian: swap while packing rows.
  std::vector<std::uint8_t> packed(static_cast<std::size_t>(row * height));
  for (std::uint32_t y = 0; y < height; ++y) {
    const std::uint8_t* src = pixels.data() + static_cast<std::size_t>(y) * step;
    std::uint8_t* dst = packed.data() + static_cast<std::size_t>(y * row);
    if (bit_depth == 8) {
      std::memcpy(dst, src, static_cast<std::size_t>(row));
    } else {
      for (std::size_t i = 0; i + 1 < row; i += 2) {
        dst[i] = src[i + 1];
        dst[i + 1] = src[i];
      }
    }
  }
  // libpng's low-level write API, with the error callback turned into a C++ exception-free path:
  // png_image_* (simplified API) cannot store 16-bit samples verbatim (it treats them as linear
  // light), so the classic API is used with setjmp confined to this block of trivial objects.
  struct Out {
    std::string bytes;
  } out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (png == nullptr) return internal_error("encode_png: png_create_write_struct failed");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    return internal_error("encode_png: png_create_info_struct failed");
  }
  std::vector<png_bytep> rows(height);
  for (std::uint32_t y = 0; y < height; ++y)
    rows[y] = packed.data() + static_cast<std::size_t>(y * row);
  if (setjmp(png_jmpbuf(png))) {  // NOLINT(cert-err52-cpp): libpng's documented error path
    png_destroy_write_struct(&png, &info);
    return internal_error("encode_png: libpng error");
  }
  png_set_write_fn(
      png, &out,
      [](png_structp p, png_bytep data, png_size_t n) {
        static_cast<Out*>(png_get_io_ptr(p))->bytes.append(reinterpret_cast<const char*>(data), n);
      },
      nullptr);
  const int color = channels == 1   ? PNG_COLOR_TYPE_GRAY
                    : channels == 3 ? PNG_COLOR_TYPE_RGB
                                    : PNG_COLOR_TYPE_RGB_ALPHA;
  png_set_IHDR(png, info, width, height, bit_depth, color, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 3);
  png_write_info(png, info);
  if (bgr && channels >= 3) png_set_bgr(png);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return std::move(out.bytes);
}

namespace {

// A JSON channel as one CSV file: log_time_ns, publish_time_ns, sequence, then every field.
Status export_json_csv(const McapReader& reader, const ReadOptions& ro,
                       const std::filesystem::path& file, ExportReport& rep) {
  // Pass 1: the columns, in order of first appearance.
  std::vector<std::string> columns;
  std::map<std::string, std::size_t> column_of;
  Status err;
  std::vector<std::pair<std::string, std::string>> flat;
  HC_RETURN_IF_ERROR(reader.read_messages(ro, [&](const MessageEvent& e) {
    auto j = parse_json_message(e.message.data);
    if (!j.ok()) {
      err = j.status().with_context(fmt::format("message at log_time {}", e.message.log_time));
      return false;
    }
    flat.clear();
    flatten(*j, "", flat);
    for (const auto& [k, v] : flat)
      if (column_of.emplace(k, columns.size()).second) columns.push_back(k);
    return true;
  }));
  HC_RETURN_IF_ERROR(err);
  // Pass 2: the rows.
  std::string csv = "log_time_ns,publish_time_ns,sequence";
  for (const auto& c : columns) csv.append(",").append(csv_cell(c));
  csv += "\n";
  std::vector<std::string> cells(columns.size());
  HC_RETURN_IF_ERROR(reader.read_messages(ro, [&](const MessageEvent& e) {
    auto j = parse_json_message(e.message.data);
    if (!j.ok()) return false;
    flat.clear();
    flatten(*j, "", flat);
    std::fill(cells.begin(), cells.end(), std::string());
    for (const auto& [k, v] : flat) cells[column_of.at(k)] = v;
    csv += fmt::format("{},{},{}", e.message.log_time, e.message.publish_time, e.message.sequence);
    for (const auto& c : cells) csv.append(",").append(csv_cell(c));
    csv += "\n";
    ++rep.messages;
    return true;
  }));
  HC_RETURN_IF_ERROR(write_file_atomic(file, csv));
  rep.files.push_back(file);
  return {};
}

// How encode_png stores the pixels of a RawImage encoding; channels 0: not one PNG export handles.
struct PngLayout {
  int channels = 0;
  int bit_depth = 8;
  bool bgr = false;
};

PngLayout png_layout(const std::string& enc) {
  PngLayout l;
  if (enc == "mono8" || enc == "8UC1")
    l.channels = 1;
  else if (enc == "mono16" || enc == "16UC1") {
    l.channels = 1;
    l.bit_depth = 16;
  } else if (enc == "rgb8" || enc == "8UC3")
    l.channels = 3;
  else if (enc == "bgr8") {
    l.channels = 3;
    l.bgr = true;
  } else if (enc == "rgba8")
    l.channels = 4;
  else if (enc == "bgra8") {
    l.channels = 4;
    l.bgr = true;
  }
  return l;
}

// One exported frame: its file's name and bytes, and what its line of the frames index ends with
// (timestamp_ns, width, height, encoding).
struct FrameFile {
  std::string name;
  std::string bytes;
  std::string line_tail;
};

// A foxglove.RawImage as "<base>_<index>.png".
Result<FrameFile> raw_frame_file(const MessageEvent& e, const std::string& base,
                                 std::uint64_t index) {
  auto im = decode_raw_image(e.message.data);
  if (!im.ok())
    return im.status().with_context(fmt::format("frame at log_time {}", e.message.log_time));
  const std::string& enc = im->encoding;
  const PngLayout layout = png_layout(enc);
  if (layout.channels == 0)
    return unsupported(
        fmt::format("frame at log_time {}: PNG export of encoding '{}' is not "
                    "supported",
                    e.message.log_time, enc));
  HC_ASSIGN_OR_RETURN(std::string png,
                      encode_png(im->width, im->height, layout.channels, layout.bit_depth,
                                 layout.bgr, im->step, im->data));
  FrameFile f;
  f.bytes = std::move(png);
  f.name = fmt::format("{}_{:06d}.png", base, index);
  f.line_tail = fmt::format("{},{},{},{}", im->timestamp_ns, im->width, im->height, enc);
  return f;
}

// A foxglove.CompressedImage as "<base>_<index>.<format>", its bytes unchanged.
Result<FrameFile> compressed_frame_file(const MessageEvent& e, const std::string& base,
                                        std::uint64_t index) {
  auto im = decode_compressed_image(e.message.data);
  if (!im.ok())
    return im.status().with_context(fmt::format("frame at log_time {}", e.message.log_time));
  const std::string ext = im->format.empty() ? "bin" : file_safe(im->format);
  FrameFile f;
  f.name = fmt::format("{}_{:06d}.{}", base, index, ext);
  f.bytes.assign(im->data.begin(), im->data.end());
  f.line_tail = fmt::format("{},,,{}", im->timestamp_ns, csv_cell(im->format));
  return f;
}

// Moves the staged files (the index last) into out_dir, listing them in rep.files.
Status move_into_place(const std::filesystem::path& stage, const std::vector<std::string>& staged,
                       const std::filesystem::path& out_dir, ExportReport& rep) {
  std::error_code ec;
  for (const std::string& name : staged) {
    std::filesystem::rename(stage / name, out_dir / name, ec);
    if (ec) {
      const std::string why = ec.message();
      // Take back what was moved: the frames and their index are there together or not at all.
      for (const std::filesystem::path& f : rep.files) std::filesystem::remove(f, ec);
      return io_error(
          fmt::format("{}: cannot move {} into place: {}", out_dir.string(), name, why));
    }
    rep.files.push_back(out_dir / name);
  }
  return {};
}

// An image channel as one file per frame plus "<base>_frames.csv", their index.
Status export_frames(const McapReader& reader, const ReadOptions& ro, bool raw,
                     const std::filesystem::path& out_dir, const std::string& base,
                     ExportReport& rep) {
  // The frames go to a staging folder first and are moved into out_dir at the end, the index last:
  // an export that fails or is killed leaves no folder of frames without its index (the staging
  // folder of a killed run is removed by the next one).
  remove_stale_temporaries(out_dir);
  const std::filesystem::path stage = temp_path_for(out_dir / base);
  std::error_code ec;
  std::filesystem::create_directory(stage, ec);
  if (ec)
    return io_error(fmt::format("{}: cannot create directory: {}", stage.string(), ec.message()));
  struct RemoveStage {
    const std::filesystem::path& dir;
    ~RemoveStage() {
      std::error_code e;
      std::filesystem::remove_all(dir, e);
    }
  } remove_stage{stage};
  std::vector<std::string> staged;
  std::string index =
      "file,log_time_ns,publish_time_ns,sequence,timestamp_ns,width,height,encoding\n";
  Status err;
  HC_RETURN_IF_ERROR(reader.read_messages(ro, [&](const MessageEvent& e) {
    Result<FrameFile> frame =
        raw ? raw_frame_file(e, base, rep.messages) : compressed_frame_file(e, base, rep.messages);
    if (!frame.ok()) {
      err = frame.status();
      return false;
    }
    if (Status s = write_file_atomic(stage / frame->name, frame->bytes); !s.ok()) {
      err = s;
      return false;
    }
    staged.push_back(frame->name);
    index += fmt::format("{},{},{},{},{}\n", frame->name, e.message.log_time,
                         e.message.publish_time, e.message.sequence, frame->line_tail);
    ++rep.messages;
    return true;
  }));
  HC_RETURN_IF_ERROR(err);
  staged.push_back(base + "_frames.csv");
  HC_RETURN_IF_ERROR(write_file_atomic(stage / staged.back(), index));
  return move_into_place(stage, staged, out_dir, rep);
}

}  // namespace

Result<ExportReport> export_channel(const std::filesystem::path& mcap, std::string_view topic,
                                    const std::filesystem::path& out_dir) {
  HC_ASSIGN_OR_RETURN(McapReader reader, McapReader::open(mcap));
  const Channel* channel = reader.find_channel(topic);
  if (channel == nullptr) {
    std::string known;
    for (const auto& [id, ch] : reader.channels()) known += (known.empty() ? "" : ", ") + ch.topic;
    return not_found(
        fmt::format("{}: no channel '{}' (channels: {})", mcap.string(), topic, known));
  }
  const Schema* schema = nullptr;
  if (auto s = reader.schemas().find(channel->schema_id); s != reader.schemas().end())
    schema = &s->second;
  ExportReport rep;
  rep.topic = std::string(topic);
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec)
    return io_error(fmt::format("{}: cannot create directory: {}", out_dir.string(), ec.message()));
  const std::string base = file_safe(topic);
  ReadOptions ro;
  ro.topics = {std::string(topic)};
  ro.order = ReadOrder::kFile;

  if (channel->message_encoding == kJsonEncoding) {
    rep.kind = "csv";
    HC_RETURN_IF_ERROR(export_json_csv(reader, ro, out_dir / (base + ".csv"), rep));
    return rep;
  }

  const bool raw = schema != nullptr && schema->name == kRawImageSchemaName &&
                   channel->message_encoding == kProtobufEncoding;
  const bool compressed = schema != nullptr && schema->name == kCompressedImageSchemaName &&
                          channel->message_encoding == kProtobufEncoding;
  if (!raw && !compressed)
    return unsupported(fmt::format(
        "{}: channel '{}' has encoding '{}' / schema '{}': export handles JSON time series and "
        "foxglove.RawImage / foxglove.CompressedImage frames",
        mcap.string(), topic, channel->message_encoding, schema ? schema->name : ""));
  rep.kind = raw ? "png" : "image";
  HC_RETURN_IF_ERROR(export_frames(reader, ro, raw, out_dir, base, rep));
  return rep;
}

}  // namespace hc::recording
