// MCAP records (https://mcap.dev/spec, format version "0"): the record structs, their byte-exact
// encoding and decoding, and the CRC-32 the format uses. Hand-written from the public specification
// because the project writes and reads its sessions with its own code (no libmcap dependency); the
// writer, reader, verify and recover are built on these functions.
//
// Layout reminders (all integers little-endian):
//   file    = magic, Header, data section (..., DataEnd), [summary section], [summary offsets],
//             Footer, magic
//   record  = opcode u8, content length u64, content
//   String  = u32 byte length + UTF-8;  Bytes (u32) = u32 length + bytes;
//   Map<K,V>= u32 byte length + entries;  Array<T> = u32 byte length + entries
//   Time    = u64 nanoseconds (our sessions: host CLOCK_MONOTONIC for log_time, see mcap_writer.h)
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/status.h"

namespace hc::recording {

using Bytes = std::vector<std::uint8_t>;
using ByteSpan = std::span<const std::uint8_t>;
using StringMap = std::map<std::string, std::string>;

// A text payload (JSON) as message bytes.
inline Bytes to_bytes(std::string_view s) { return Bytes(s.begin(), s.end()); }

// "\x89MCAP0\r\n": at the start and at the end of every MCAP file.
inline constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
// Opcode (1) + content length (8).
inline constexpr std::size_t kRecordPrefixSize = 9;
// Footer content: summary_start u64, summary_offset_start u64, summary_crc u32.
inline constexpr std::size_t kFooterContentSize = 20;
// Footer record + closing magic: the last 37 bytes of a complete file.
inline constexpr std::size_t kFooterAndMagicSize = kRecordPrefixSize + kFooterContentSize + 8;

enum class Opcode : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};
// The byte an opcode is written as.
constexpr std::uint8_t opcode_byte(Opcode o) { return static_cast<std::uint8_t>(o); }

// "Header", "Chunk", ... or "Unknown(0x42)" (the spec lets readers skip unknown opcodes).
std::string opcode_name(std::uint8_t opcode);

struct Header {
  std::string profile;  // "" for our sessions (no ROS profile)
  std::string library;  // e.g. "hardcopy 0.4.0"
  bool operator==(const Header&) const = default;
};

struct Footer {
  std::uint64_t summary_start = 0;         // 0: no summary section
  std::uint64_t summary_offset_start = 0;  // 0: no summary offset section
  std::uint32_t summary_crc = 0;           // 0: not computed
  bool operator==(const Footer&) const = default;
};

// Schema id 0 is reserved ("no schema"); valid ids start at 1.
struct Schema {
  std::uint16_t id = 0;
  std::string name;      // e.g. "foxglove.RawImage", "hardcopy.ForceTorque"
  std::string encoding;  // "protobuf", "jsonschema", ...
  Bytes data;            // the schema itself (FileDescriptorSet, JSON Schema text, ...)
  bool operator==(const Schema&) const = default;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;   // 0: schemaless
  std::string topic;             // e.g. "/camera/0/image", "/ft/wrench"
  std::string message_encoding;  // "json", "protobuf", ...
  StringMap metadata;
  bool operator==(const Channel&) const = default;
};

struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;      // ns
  std::uint64_t publish_time = 0;  // ns
  Bytes data;
  bool operator==(const Message&) const = default;
};

// A Chunk record; `records` holds the (possibly compressed) inner records.
struct Chunk {
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;  // CRC of the uncompressed records; 0: not computed
  std::string compression;             // "", "lz4" (LZ4 frame format) or "zstd"
  Bytes records;
  bool operator==(const Chunk&) const = default;
};

// Follows each chunk, one per channel with messages in the chunk: (log_time, offset of the Message
// record inside the *uncompressed* chunk records).
struct MessageIndex {
  std::uint16_t channel_id = 0;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> records;
  bool operator==(const MessageIndex&) const = default;
};

struct ChunkIndex {
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t chunk_start_offset = 0;  // file offset of the Chunk record's opcode
  std::uint64_t chunk_length = 0;        // whole Chunk record, prefix included
  std::map<std::uint16_t, std::uint64_t> message_index_offsets;  // channel -> file offset
  std::uint64_t message_index_length = 0;  // all MessageIndex records after the chunk
  std::string compression;
  std::uint64_t compressed_size = 0;    // size of Chunk.records
  std::uint64_t uncompressed_size = 0;  // == Chunk.uncompressed_size
  bool operator==(const ChunkIndex&) const = default;
};

struct Attachment {
  std::uint64_t log_time = 0;
  std::uint64_t create_time = 0;
  std::string name;
  std::string media_type;
  Bytes data;             // u64-length-prefixed on disk
  std::uint32_t crc = 0;  // CRC of every preceding field of the record content; 0: not computed
  bool operator==(const Attachment&) const = default;
};

struct AttachmentIndex {
  std::uint64_t offset = 0;  // file offset of the Attachment record
  std::uint64_t length = 0;  // whole record, prefix included
  std::uint64_t log_time = 0;
  std::uint64_t create_time = 0;
  std::uint64_t data_size = 0;
  std::string name;
  std::string media_type;
  bool operator==(const AttachmentIndex&) const = default;
};

struct Statistics {
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0;
  std::uint32_t attachment_count = 0;
  std::uint32_t metadata_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::map<std::uint16_t, std::uint64_t> channel_message_counts;
  bool operator==(const Statistics&) const = default;
};

struct Metadata {
  std::string name;  // e.g. "rig_config", "plan", "calibration", "software"
  StringMap metadata;
  bool operator==(const Metadata&) const = default;
};

struct MetadataIndex {
  std::uint64_t offset = 0;  // file offset of the Metadata record
  std::uint64_t length = 0;  // whole record, prefix included
  std::string name;
  bool operator==(const MetadataIndex&) const = default;
};

struct SummaryOffset {
  std::uint8_t group_opcode = 0;  // opcode of the records in the group
  std::uint64_t group_start = 0;  // file offset of the group's first record
  std::uint64_t group_length = 0;
  bool operator==(const SummaryOffset&) const = default;
};

struct DataEnd {
  std::uint32_t data_section_crc = 0;  // CRC of every byte from file start to this record; 0: none
  bool operator==(const DataEnd&) const = default;
};

// ---- CRC-32 (ISO-HDLC / zlib: reflected poly 0xEDB88320, init and final xor 0xFFFFFFFF) ----
// Incremental use: c = crc32_update(kCrc32Init, a); c = crc32_update(c, b); crc32_final(c).
inline constexpr std::uint32_t kCrc32Init = 0xFFFFFFFFu;
std::uint32_t crc32_update(std::uint32_t state, ByteSpan data);
inline std::uint32_t crc32_final(std::uint32_t state) { return state ^ 0xFFFFFFFFu; }
inline std::uint32_t crc32(ByteSpan data) { return crc32_final(crc32_update(kCrc32Init, data)); }

// ---- Encoding: each appends one complete record (opcode + length + content) to `out` ----
void encode(const Header& r, Bytes& out);
void encode(const Footer& r, Bytes& out);
void encode(const Schema& r, Bytes& out);
void encode(const Channel& r, Bytes& out);
void encode(const Message& r, Bytes& out);
// Message without copying the payload into a Message struct first (the writer's hot path).
void encode_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                    std::uint64_t publish_time, ByteSpan data, Bytes& out);
void encode(const Chunk& r, Bytes& out);
void encode(const MessageIndex& r, Bytes& out);
void encode(const ChunkIndex& r, Bytes& out);
void encode(const Attachment& r, Bytes& out);  // computes nothing: writes r.crc as given
void encode(const AttachmentIndex& r, Bytes& out);
void encode(const Statistics& r, Bytes& out);
void encode(const Metadata& r, Bytes& out);
void encode(const MetadataIndex& r, Bytes& out);
void encode(const SummaryOffset& r, Bytes& out);
void encode(const DataEnd& r, Bytes& out);
// The Attachment CRC the spec defines (over the content before the crc field).
std::uint32_t attachment_crc(const Attachment& r);

// ---- Decoding: `content` is the record content only (no opcode or length prefix). Every length
// is checked against the bytes present before anything is allocated; errors name the field. Extra
// trailing bytes are allowed (the spec lets later versions append fields). ----
Result<Header> decode_header(ByteSpan content);
Result<Footer> decode_footer(ByteSpan content);
Result<Schema> decode_schema(ByteSpan content);
Result<Channel> decode_channel(ByteSpan content);
Result<Message> decode_message(ByteSpan content);
Result<Chunk> decode_chunk(ByteSpan content);
Result<MessageIndex> decode_message_index(ByteSpan content);
Result<ChunkIndex> decode_chunk_index(ByteSpan content);
Result<Attachment> decode_attachment(ByteSpan content);
Result<AttachmentIndex> decode_attachment_index(ByteSpan content);
Result<Statistics> decode_statistics(ByteSpan content);
Result<Metadata> decode_metadata(ByteSpan content);
Result<MetadataIndex> decode_metadata_index(ByteSpan content);
Result<SummaryOffset> decode_summary_offset(ByteSpan content);
Result<DataEnd> decode_data_end(ByteSpan content);

// A Message record's fields with `data` viewing the caller's buffer (no copy).
struct MessageView {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  ByteSpan data;
};
Result<MessageView> decode_message_view(ByteSpan content);

// A Chunk record's fields with `records` viewing the caller's buffer (no copy).
struct ChunkView {
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;
  std::string compression;
  ByteSpan records;
};
Result<ChunkView> decode_chunk_view(ByteSpan content);

// One record located in a buffer: opcode, content view, and its total size (prefix included).
struct RecordView {
  std::uint8_t opcode = 0;
  ByteSpan content;
  std::uint64_t size = 0;  // kRecordPrefixSize + content.size()
};
// Splits the record starting at `buffer[0]`. Fails (with `base_offset` + position in the message)
// when the prefix or the declared content does not fit in `buffer`.
Result<RecordView> next_record(ByteSpan buffer, std::uint64_t base_offset = 0);

// ---- Chunk compression ----
enum class Compression : std::uint8_t { kNone, kLz4, kZstd };
// "" / "none" -> kNone, "lz4", "zstd"; anything else is an invalid_argument error.
Result<Compression> parse_compression(std::string_view name);
// The string stored in Chunk.compression: "", "lz4", "zstd".
std::string_view compression_record_name(Compression c);
// "none", "lz4", "zstd" (for messages and CLI options).
std::string_view compression_display_name(Compression c);
// `level`: zstd 1..19 / lz4 frame 0 (fast) .. 12; ignored for kNone.
Result<Bytes> compress(Compression c, ByteSpan data, int level);
// `compression` as stored in a chunk. Fails unless exactly `uncompressed_size` bytes result; the
// size is checked against `max_size` before the output is allocated.
Result<Bytes> decompress(std::string_view compression, ByteSpan data,
                         std::uint64_t uncompressed_size, std::uint64_t max_size);

}  // namespace hc::recording
