// libFuzzer target for the MCAP reader: arbitrary bytes are opened as an MCAP file (summary and
// linear paths, truncated files allowed), every message is read in file and log-time order,
// metadata / attachments / message indexes are read; the same bytes are also fed to every record
// decoder and to the Foxglove image decoders. The bytes also go through `session recover` (from a
// file): whatever it accepts, the file it writes must pass `verify`, and what it refuses leaves
// no file. Errors are the expected outcome; crashes, hangs, leaks, huge allocations and sanitizer
// reports are bugs.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/mcap_records.h"
#include "rig_daemon/recording/mcap_tools.h"
#include "rig_daemon/recording/session_conventions.h"

namespace rec = hc::recording;

namespace {

// recover() reads and writes files: one folder per fuzzing process, removed at exit.
const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    std::filesystem::path d =
        std::filesystem::temp_directory_path() / ("fuzz_mcap_reader." + std::to_string(::getpid()));
    std::error_code ec;
    std::filesystem::create_directories(d, ec);
    std::atexit([] {
      std::error_code e;
      std::filesystem::remove_all(scratch(), e);
    });
    return d;
  }();
  return dir;
}

void check_recover(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& dir = scratch();
  std::error_code ec;
  const std::filesystem::path in = dir / "in.mcap";
  const std::filesystem::path out = dir / "out.mcap";
  std::filesystem::remove(out, ec);
  {
    std::ofstream f(in, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  auto rep = rec::recover(in, out, {}, 1u << 24);
  if (!rep.ok()) {
    if (std::filesystem::exists(out)) __builtin_trap();  // refused, yet wrote something
    return;
  }
  auto v = rec::verify(out);
  if (!v.ok() || !v->ok) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const rec::ByteSpan bytes(data, size);
  rec::McapReader::Options opt;
  opt.allow_truncated = true;
  opt.max_record_size = 1u << 24;  // keeps hostile sizes below the fuzzer's RSS limit
  auto reader = rec::McapReader::from_bytes(bytes, opt);
  if (reader.ok()) {
    std::uint64_t sum = 0;
    for (rec::ReadOrder order : {rec::ReadOrder::kFile, rec::ReadOrder::kLogTime}) {
      for (bool use_index : {true, false}) {
        rec::ReadOptions ro;
        ro.order = order;
        ro.use_index = use_index;
        (void)reader->read_messages(ro, [&](const rec::MessageEvent& e) {
          sum += e.message.data.size() + e.message.log_time;
          if (e.schema != nullptr && e.schema->name == rec::kRawImageSchemaName)
            (void)rec::decode_raw_image(e.message.data);
          if (e.channel->message_encoding == rec::kJsonEncoding)
            (void)rec::parse_json_message(e.message.data);
          return true;
        });
      }
    }
    (void)reader->message_counts();
    (void)reader->read_metadata();
    for (const auto& ai : reader->summary().attachment_indexes) (void)reader->read_attachment(ai);
    for (const auto& ci : reader->summary().chunk_indexes) (void)reader->read_message_indexes(ci);
    (void)sum;
  }
  // Record decoders on the raw bytes.
  (void)rec::decode_header(bytes);
  (void)rec::decode_footer(bytes);
  (void)rec::decode_schema(bytes);
  (void)rec::decode_channel(bytes);
  (void)rec::decode_message(bytes);
  (void)rec::decode_chunk_view(bytes);
  (void)rec::decode_message_index(bytes);
  (void)rec::decode_chunk_index(bytes);
  (void)rec::decode_attachment(bytes);
  (void)rec::decode_attachment_index(bytes);
  (void)rec::decode_statistics(bytes);
  (void)rec::decode_metadata(bytes);
  (void)rec::decode_metadata_index(bytes);
  (void)rec::decode_summary_offset(bytes);
  (void)rec::decode_data_end(bytes);
  (void)rec::decode_raw_image(bytes);
  (void)rec::decode_compressed_image(bytes);
  check_recover(data, size);
  if (size > 1) {
    // Chunk payloads: the first byte picks the compression, the rest is the stream.
    const char* names[] = {"", "lz4", "zstd"};
    (void)rec::decompress(names[data[0] % 3], bytes.subspan(1), (size - 1) * 4, 1u << 20);
  }
  return 0;
}
