// McapReader: reads an MCAP file, indexed (through the summary section) or linearly (streaming over
// the data section, for files without a summary or cut off by a crash).
//
// Every CRC present is checked (chunk uncompressed CRC on each chunk decompressed, data-section CRC
// and summary CRC by verify(); see mcap_tools.h), every length is checked against the file size or
// the enclosing record before anything is allocated, and errors carry the byte offset:
// "S.mcap: offset 1234: Chunk: records length 99999 exceeds the 120 bytes left".
//
// Usage:
//   HC_ASSIGN_OR_RETURN(auto reader, McapReader::open("S.mcap"));
//   for (const auto& [id, ch] : reader.channels()) ...
//   HC_RETURN_IF_ERROR(reader.read_messages({.topics = {"/ft/wrench"}},
//       [&](const MessageEvent& m) { ...; return true; }));
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/status.h"
#include "rig_daemon/recording/mcap_records.h"

namespace hc::recording {

// Everything the summary section (or, without one, a linear scan) says about a file.
struct FileSummary {
  Header header;
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::optional<Statistics> statistics;  // present when the file has a Statistics record
  std::vector<ChunkIndex> chunk_indexes;
  std::vector<AttachmentIndex> attachment_indexes;
  std::vector<MetadataIndex> metadata_indexes;
  bool from_summary_section = false;  // false: built by a linear scan
};

// One message delivered to a read_messages() callback. Views are valid only during the callback.
struct MessageEvent {
  const Channel* channel = nullptr;  // never null
  const Schema* schema = nullptr;    // null for schemaless channels
  MessageView message;               // data views the decompressed chunk
  std::uint64_t chunk_offset = 0;    // file offset of the enclosing Chunk (0: not in a chunk)
};

enum class ReadOrder : std::uint8_t {
  kFile,     // as stored (within a chunk: record order)
  kLogTime,  // by log_time across all chunks; ties keep file order (stable)
};

struct ReadOptions {
  std::vector<std::string> topics;                                     // empty: every channel
  std::uint64_t start_time = 0;                                        // log_time >= start_time
  std::uint64_t end_time = std::numeric_limits<std::uint64_t>::max();  // log_time < end_time
  ReadOrder order = ReadOrder::kLogTime;
  bool use_index = true;  // false: linear scan even when a summary exists
};

// Return false to stop reading early (read_messages then returns OK).
using MessageCallback = std::function<bool(const MessageEvent&)>;

class McapReader {
 public:
  struct Options {
    // No single decompressed chunk / record may exceed this (guards against hostile sizes).
    std::uint64_t max_record_size = 1ull << 32;
    // Check Chunk.uncompressed_crc whenever a chunk is decompressed.
    bool check_chunk_crc = true;
    // A file without its Footer / closing magic (cut off by a crash) is refused unless this is
    // set; then it is summarised by a linear scan of its complete records.
    bool allow_truncated = false;
  };

  // Opens `path`, checks both magics, reads the Header and, when the Footer points at one, the
  // summary section (schemas, channels, statistics, indexes). A file with no summary (or a
  // truncated file, with Options::allow_truncated) is summarised by a linear scan instead.
  static Result<McapReader> open(const std::filesystem::path& path, const Options& options);
  static Result<McapReader> open(const std::filesystem::path& path);
  // Reads from memory (tests, fuzzing). The bytes are copied.
  static Result<McapReader> from_bytes(ByteSpan bytes, const Options& options);

  McapReader(McapReader&&) noexcept;
  McapReader& operator=(McapReader&&) noexcept;
  ~McapReader();

  const FileSummary& summary() const;
  const Header& header() const { return summary().header; }
  const std::map<std::uint16_t, Schema>& schemas() const { return summary().schemas; }
  const std::map<std::uint16_t, Channel>& channels() const { return summary().channels; }
  // Channel with this topic, or null.
  const Channel* find_channel(std::string_view topic) const;
  std::uint64_t file_size() const;

  // Messages matching `filter`, in the requested order. Indexed when a summary with chunk indexes
  // exists and filter.use_index; otherwise one linear pass (kLogTime then sorts per pass in memory,
  // so prefer kFile for huge linear reads). Errors (bad CRC, malformed record) stop the read.
  Status read_messages(const ReadOptions& filter, const MessageCallback& callback) const;

  // Per-channel message counts: from Statistics when present, else by reading the message indexes
  // (or linearly scanning when there are none).
  Result<std::map<std::uint16_t, std::uint64_t>> message_counts() const;

  // The MessageIndex records stored after a chunk (located through its ChunkIndex), without
  // decompressing the chunk.
  Result<std::vector<MessageIndex>> read_message_indexes(const ChunkIndex& index) const;

  // Every Metadata record (through the metadata indexes, or linearly without a summary).
  Result<std::vector<Metadata>> read_metadata() const;
  // The Attachment at an index entry; its CRC is checked.
  Result<Attachment> read_attachment(const AttachmentIndex& index) const;

  class Impl;

 private:
  explicit McapReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// ---- Linear (streaming) reading of the records of a file, for verify / recover / tools ----

// One top-level record met by a linear scan, with its file offset.
struct LinearRecord {
  std::uint64_t offset = 0;  // file offset of the opcode
  std::uint8_t opcode = 0;
  ByteSpan content;  // valid during the callback only
};

struct LinearScanResult {
  std::uint64_t end_offset = 0;       // offset just past the last complete record read
  bool reached_footer = false;        // a Footer and closing magic were found
  bool truncated = false;             // the file ended inside a record (or before the Footer)
  std::uint8_t truncated_opcode = 0;  // opcode of the record cut off (0: none / only a prefix)
  std::string stop_reason;  // why the scan stopped early, with the offset ("" when complete)
};

// Reads the file from the start (after the magic) record by record, calling `on_record` for each
// complete top-level record until the Footer. A record cut off by the end of the file ends the scan
// with truncated = true (not an error). Malformed prefixes (opcode/length that cannot be right)
// also end the scan, with the reason. The callback returns a non-OK Status to abort the scan (that
// Status is returned). Memory use is bounded by the largest record.
Result<LinearScanResult> scan_records(const std::filesystem::path& path,
                                      const std::function<Status(const LinearRecord&)>& on_record,
                                      std::uint64_t max_record_size = 1ull << 32);

}  // namespace hc::recording
