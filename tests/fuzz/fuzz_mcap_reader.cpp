// libFuzzer target for the MCAP reader: arbitrary bytes are opened as an MCAP file (summary and
// linear paths, truncated files allowed), every message is read in file and log-time order,
// metadata / attachments / message indexes are read; the same bytes are also fed to every record
// decoder and to the Foxglove image decoders. Errors are the expected outcome; crashes, hangs,
// leaks, huge allocations and sanitizer reports are bugs.
#include <cstddef>
#include <cstdint>

#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/mcap_records.h"
#include "rig_daemon/recording/session_conventions.h"

namespace rec = hc::recording;

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
  if (size > 1) {
    // Chunk payloads: the first byte picks the compression, the rest is the stream.
    const char* names[] = {"", "lz4", "zstd"};
    (void)rec::decompress(names[data[0] % 3], bytes.subspan(1), (size - 1) * 4, 1u << 20);
  }
  return 0;
}
