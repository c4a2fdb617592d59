// McapWriter: writes one MCAP session file, append-only and chunked.
//
// File produced: magic, Header, then for every chunk the Chunk record followed by one MessageIndex
// per channel in it; Schema / Channel records are written into the chunk in which they are first
// used (so a recovered prefix is self-describing); Metadata and Attachment records go between
// chunks. close() writes DataEnd (with the data-section CRC), the summary section (every Schema and
// Channel repeated, Statistics, ChunkIndex, AttachmentIndex and MetadataIndex records), one
// SummaryOffset per group, the Footer (with the summary CRC) and the closing magic.
//
// Crash safety: nothing is buffered across chunk boundaries. When a chunk closes (its uncompressed
// size reaches Options::chunk_size, flush() is called, or a Metadata / Attachment record is
// written) the chunk and its message indexes go to the OS with write(2) before the next message
// is accepted, and with Options::sync_on_chunk also fdatasync(2)ed. A process killed at any point
// therefore loses at most the open chunk; `recover()` (mcap_tools.h) turns the cut file into a
// valid one.
//
// Timestamps (convention for Hardcopy sessions, agreed with the recorder): log_time = host
// CLOCK_MONOTONIC ns when the sample / frame arrived; publish_time = the device's own timestamp in
// ns when it has one (else log_time); Message.sequence = the device's counter (frame id, RDT
// sequence, ...) when it has one, else a per-channel counter.
//
// Not thread-safe: one thread owns a writer (the recorder's writer thread). With
// Options::compression_threads > 0 chunks are compressed on background threads while the next one
// fills; the file order and bytes are identical to single-threaded writing.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "common/status.h"
#include "rig_daemon/recording/mcap_records.h"

namespace hc::recording {

class McapWriter {
 public:
  struct Options {
    std::string profile;               // Header.profile; "" for Hardcopy sessions
    std::string library = "hardcopy";  // Header.library (add the version)
    Compression compression = Compression::kZstd;
    int compression_level = 1;  // zstd 1..19 (1: fastest), lz4 0..12 (0: fast)
    // A chunk is closed when its uncompressed records reach this many bytes (a single message
    // larger than this gets a chunk of its own). Smaller chunks lose less in a crash.
    std::uint64_t chunk_size = 4u << 20;
    bool chunk_crc = true;         // Chunk.uncompressed_crc (0 when false)
    bool data_section_crc = true;  // DataEnd.data_section_crc (0 when false)
    bool sync_on_chunk = false;    // fdatasync after every chunk (survives power loss too)
    // 0: compress on the calling thread. N > 0: up to N chunks are compressed concurrently on
    // background threads; write_message() blocks only when N chunks are already in flight.
    int compression_threads = 0;
    // Refuse to overwrite an existing file.
    bool exclusive = false;

    Status validate() const;  // chunk_size > 0, levels in range, threads 0..16
  };

  // What close() reports.
  struct Summary {
    std::uint64_t message_count = 0;
    std::uint64_t chunk_count = 0;
    std::uint64_t uncompressed_bytes = 0;  // sum of uncompressed chunk records
    std::uint64_t compressed_bytes = 0;    // sum of Chunk.records as stored
    std::uint64_t file_size = 0;
    std::uint64_t message_start_time = 0;
    std::uint64_t message_end_time = 0;
    Statistics statistics;  // as written into the summary
  };

  // Creates (truncates unless Options::exclusive) `path` and writes magic + Header. Fails with
  // an io_error naming the path, or invalid_argument from Options::validate().
  static Result<std::unique_ptr<McapWriter>> open(const std::filesystem::path& path,
                                                  const Options& options);

  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;
  // Closes the file if close() was not called (errors are logged, not reported).
  ~McapWriter();

  // Registers a schema; returns its id (1, 2, ...). `encoding`: "jsonschema", "protobuf", ...
  Result<std::uint16_t> add_schema(std::string_view name, std::string_view encoding, ByteSpan data);
  // Registers a channel; returns its id (0, 1, ...). `schema_id` 0 means schemaless; otherwise it
  // must come from add_schema(). Topics must be unique.
  Result<std::uint16_t> add_channel(std::string_view topic, std::string_view message_encoding,
                                    std::uint16_t schema_id, const StringMap& metadata = {});

  // Registers a schema / channel with the id it already has (recover, re-recording a replay):
  // fails on an id or topic already registered, schema id 0, or a channel's unknown schema id.
  // Mixing with the id-assigning overloads above is fine: those hand out max id + 1.
  Status add_schema(const Schema& schema);
  Status add_channel(const Channel& channel);

  // Appends one message to the open chunk (closing it first if it is full). `channel_id` must come
  // from add_channel(). log_time may go backwards between calls (chunk time ranges and message
  // indexes stay correct); readers in log-time order sort.
  Status write_message(std::uint16_t channel_id, std::uint64_t log_time_ns,
                       std::uint64_t publish_time_ns, ByteSpan data, std::uint32_t sequence);
  // As above with sequence = a per-channel counter starting at 0.
  Status write_message(std::uint16_t channel_id, std::uint64_t log_time_ns,
                       std::uint64_t publish_time_ns, ByteSpan data);

  // Writes a Metadata record (closes the open chunk first, so it lands between chunks) and indexes
  // it in the summary. Names Hardcopy uses: see kMetadata* in session_conventions.h.
  Status write_metadata(std::string_view name, const StringMap& metadata);
  // Writes an Attachment record (e.g. a calibration YAML file) with its CRC, indexed in the
  // summary.
  Status write_attachment(std::string_view name, std::string_view media_type,
                          std::uint64_t log_time_ns, std::uint64_t create_time_ns, ByteSpan data);

  // Closes the open chunk (if any) and hands everything to the OS (fdatasync with sync_on_chunk).
  Status flush();

  // Finishes the file (DataEnd, summary, summary offsets, footer, magic) and closes it. After
  // close() every other call fails with failed_precondition.
  Result<Summary> close();

  // Bytes handed to the OS so far (file offset of the next record).
  std::uint64_t bytes_written() const;
  const std::filesystem::path& path() const;

  class Impl;

 private:
  explicit McapWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hc::recording
