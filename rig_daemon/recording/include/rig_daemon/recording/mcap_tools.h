// Whole-file operations on MCAP sessions: verify (every CRC and index cross-checked), recover (a
// file cut off by a crash becomes a valid file holding every complete chunk), and the session
// info that `hardcopy session info` prints.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/mcap_writer.h"

namespace hc::recording {

// ---- verify ----
struct VerifyReport {
  bool ok = false;                    // true only when `problems` is empty
  std::vector<std::string> problems;  // each names the byte offset and what is wrong
  std::uint64_t chunks_checked = 0;
  std::uint64_t messages_checked = 0;
  std::uint64_t crcs_checked =
      0;  // non-zero CRCs verified (chunks, data section, summary, attachments)
  bool has_summary = false;
  Json to_json() const;
};

// Reads the whole file linearly and cross-checks it against its summary: magics, record framing,
// every chunk's uncompressed CRC and size, every inner record, DataEnd's data-section CRC, the
// Footer's summary CRC, every ChunkIndex against its Chunk (offset, length, times, sizes,
// compression, message-index offsets and length), every MessageIndex against the messages in its
// chunk, Statistics against the counted messages / schemas / channels / chunks / metadata /
// attachments, MetadataIndex / AttachmentIndex entries against the records, SummaryOffset groups,
// and that every message's channel and every channel's schema are defined.
// Returns an error Status only when the file cannot be read at all (missing, not MCAP); a readable
// file with problems gives a report with ok = false.
Result<VerifyReport> verify(const std::filesystem::path& path);

// ---- recover ----
struct RecoverReport {
  std::uint64_t chunks_kept = 0;
  std::uint64_t chunks_dropped = 0;  // incomplete or failing their CRC / decompression
  std::uint64_t messages_kept = 0;
  std::uint64_t messages_dropped = 0;  // in kept chunks but on a channel defined nowhere intact
  std::uint64_t metadata_kept = 0;
  std::uint64_t attachments_kept = 0;
  std::uint64_t definitions_found = 0;  // channel definitions found anywhere in the input
  std::uint64_t input_bytes_used = 0;   // offset where the usable input ended
  bool input_was_complete = false;      // the input had its Footer
  std::string stop_reason;              // why the scan of the input stopped ("" at the Footer)
  Json to_json() const;
};

// Linear scan of `input` (typically cut off by a crash); writes `output` as a complete file with a
// fresh summary holding every complete chunk whose CRC checks (re-chunked unchanged: messages keep
// their channel ids, sequences and times), every Schema / Channel / Metadata / Attachment found.
// Definitions come from wherever the input still holds them (a first pass reads the top level,
// every chunk that checks and the summary section), so a corrupt chunk loses only its own
// messages. `options` gives the output's compression and chunk size; chunks that would
// decompress to more than `max_chunk_bytes` are dropped. The output is written to a temporary name
// and renamed, so nothing half-written is left behind on failure. Fails (kInvalidArgument) when
// `input` is not MCAP (bad magic, or the record after it is not a Header), kNotFound when it
// cannot be read, and when output == input.
Result<RecoverReport> recover(const std::filesystem::path& input,
                              const std::filesystem::path& output,
                              const McapWriter::Options& options,
                              std::uint64_t max_chunk_bytes = std::uint64_t{1} << 34);

// ---- info ----
struct ChannelInfo {
  std::uint16_t id = 0;
  std::string topic;
  std::string message_encoding;
  std::string schema_name;  // "" when schemaless
  std::string schema_encoding;
  std::uint64_t message_count = 0;
  std::uint64_t first_log_time = 0;
  std::uint64_t last_log_time = 0;
  double rate_hz = 0;  // (count - 1) / (last - first), 0 with fewer than 2 messages
  StringMap metadata;
};

struct DeviceStats {
  std::string device;
  std::uint64_t received = 0;
  std::uint64_t lost = 0;
  std::uint64_t late = 0;
  std::uint64_t incomplete = 0;  // e.g. frames with missing packets
};

struct SessionInfo {
  std::string path;
  std::uint64_t file_size = 0;
  Header header;
  bool has_summary = false;
  std::uint64_t message_count = 0;
  std::uint64_t chunk_count = 0;
  std::uint64_t start_time = 0;  // ns, first log_time
  std::uint64_t end_time = 0;    // ns, last log_time
  double duration_s = 0;
  std::map<std::string, std::uint64_t> compression_chunks;  // "zstd" -> chunks
  std::uint64_t compressed_bytes = 0;
  std::uint64_t uncompressed_bytes = 0;
  std::vector<ChannelInfo> channels;
  std::vector<std::string> metadata_names;
  std::vector<std::string> attachment_names;
  std::vector<DeviceStats> device_stats;  // from the session's device-stats metadata (if any)
  // From the last "session" Metadata record rigd writes at the end (empty when absent).
  std::string session_state;  // e.g. "completed", "aborted"
  std::string session_reason;
  Json to_json() const;
};

// Everything `hardcopy session info` shows. Per-channel first/last times come from the chunk's
// message indexes (no decompression) when the file has them, else from reading the messages.
// Device stats: see session_conventions.h.
Result<SessionInfo> session_info(const std::filesystem::path& path);

// ---- export ----
struct ExportReport {
  std::string topic;
  std::string kind;  // "csv" (JSON time series), "png" (raw frames), "image" (compressed frames)
  std::uint64_t messages = 0;
  std::vector<std::filesystem::path> files;  // written, in order
  Json to_json() const;
};

// Writes one channel of a session into `out_dir` (created if missing); file names start with the
// topic made file-safe ("/ft/wrench" -> "ft_wrench"):
// * JSON channels: "<name>.csv" with columns log_time_ns, publish_time_ns, sequence, then every
//   field of the messages flattened ("force.x", "values[2]"), in order of first appearance; a
//   message without a field leaves its cell empty.
// * foxglove.RawImage: "<name>_<index 6 digits>.png" per frame (mono8/mono16/rgb8/bgr8/rgba8/bgra8
//   and 8UC1/16UC1/8UC3) plus "<name>_frames.csv" (file, log_time_ns, publish_time_ns, sequence,
//   device timestamp_ns, width, height, encoding).
// * foxglove.CompressedImage: the stored bytes as "<name>_<index>.<format>" plus the index CSV.
// Each file is written atomically; frames and their index are written into a staging folder and
// moved into out_dir together at the end (a failed or killed export leaves no frames without their
// index; a killed export's staging folder is removed by the next export into out_dir). Fails with
// not_found for an unknown topic and unsupported for another encoding.
Result<ExportReport> export_channel(const std::filesystem::path& mcap, std::string_view topic,
                                    const std::filesystem::path& out_dir);

// Encodes an 8- or 16-bit image as PNG bytes (libpng's simplified API). `channels` 1 (gray),
// 3 (RGB) or 4 (RGBA); `bgr` swaps to BGR(A) order; 16-bit samples are little-endian. `step` is
// bytes per row.
Result<std::string> encode_png(std::uint32_t width, std::uint32_t height, int channels,
                               int bit_depth, bool bgr, std::uint32_t step, ByteSpan pixels);

}  // namespace hc::recording
