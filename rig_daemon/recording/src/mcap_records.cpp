// MCAP record encoding / decoding, hand-written from https://mcap.dev/spec (see mcap_records.h).
#include "rig_daemon/recording/mcap_records.h"

#include <lz4frame.h>
#include <zstd.h>

#include <bit>
#include <cstring>
#include <limits>

#include <fmt/format.h>

namespace hc::recording {
namespace {

// ---- writing primitives ----
void put_u8(Bytes& out, std::uint8_t v) { out.push_back(v); }
void put_u16(Bytes& out, std::uint16_t v) {
  out.push_back(static_cast<std::uint8_t>(v));
  out.push_back(static_cast<std::uint8_t>(v >> 8));
}
void put_u32(Bytes& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_u64(Bytes& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_raw(Bytes& out, ByteSpan data) { out.insert(out.end(), data.begin(), data.end()); }
void put_raw(Bytes& out, std::string_view s) { out.insert(out.end(), s.begin(), s.end()); }
void put_string(Bytes& out, std::string_view s) {
  put_u32(out, static_cast<std::uint32_t>(s.size()));
  put_raw(out, s);
}
void patch_u32(Bytes& out, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i)
    out[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}
void patch_u64(Bytes& out, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i)
    out[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}

// Writes opcode + a length placeholder; returns where the content starts.
std::size_t begin_record(Bytes& out, Opcode op) {
  put_u8(out, static_cast<std::uint8_t>(op));
  put_u64(out, 0);
  return out.size();
}
void end_record(Bytes& out, std::size_t content_start) {
  patch_u64(out, content_start - 8, out.size() - content_start);
}

void put_string_map(Bytes& out, const StringMap& m) {
  const std::size_t len_at = out.size();
  put_u32(out, 0);
  for (const auto& [k, v] : m) {
    put_string(out, k);
    put_string(out, v);
  }
  patch_u32(out, len_at, static_cast<std::uint32_t>(out.size() - len_at - 4));
}
void put_u16_u64_map(Bytes& out, const std::map<std::uint16_t, std::uint64_t>& m) {
  put_u32(out, static_cast<std::uint32_t>(m.size() * 10));
  for (const auto& [k, v] : m) {
    put_u16(out, k);
    put_u64(out, v);
  }
}

// ---- reading primitives: a cursor that checks every length before use ----
class Cursor {
 public:
  Cursor(ByteSpan data, const char* record) : data_(data), record_(record) {}

  std::size_t pos() const { return pos_; }
  std::size_t left() const { return data_.size() - pos_; }

  Status need(std::size_t n, const char* field) const {
    if (n > left())
      return invalid_argument(fmt::format("{}: {} needs {} bytes at content byte {}, {} left",
                                          record_, field, n, pos_, left()));
    return {};
  }
  Result<std::uint8_t> u8(const char* field) {
    HC_RETURN_IF_ERROR(need(1, field));
    return data_[pos_++];
  }
  Result<std::uint16_t> u16(const char* field) {
    HC_RETURN_IF_ERROR(need(2, field));
    const auto v = static_cast<std::uint16_t>(data_[pos_] | (data_[pos_ + 1] << 8));
    pos_ += 2;
    return v;
  }
  Result<std::uint32_t> u32(const char* field) {
    HC_RETURN_IF_ERROR(need(4, field));
    std::uint32_t v = 0;
    for (int i = 3; i >= 0; --i) v = (v << 8) | data_[pos_ + static_cast<std::size_t>(i)];
    pos_ += 4;
    return v;
  }
  Result<std::uint64_t> u64(const char* field) {
    HC_RETURN_IF_ERROR(need(8, field));
    std::uint64_t v = 0;
    for (int i = 7; i >= 0; --i) v = (v << 8) | data_[pos_ + static_cast<std::size_t>(i)];
    pos_ += 8;
    return v;
  }
  Result<ByteSpan> raw(std::uint64_t n, const char* field) {
    if (n > left())
      return invalid_argument(
          fmt::format("{}: {} length {} exceeds the {} bytes left at content byte {}", record_,
                      field, n, left(), pos_));
    ByteSpan s = data_.subspan(pos_, static_cast<std::size_t>(n));
    pos_ += static_cast<std::size_t>(n);
    return s;
  }
  Result<std::string> string(const char* field) {
    HC_ASSIGN_OR_RETURN(const std::uint32_t n, u32(field));
    HC_ASSIGN_OR_RETURN(const ByteSpan s, raw(n, field));
    return std::string(reinterpret_cast<const char*>(s.data()), s.size());
  }
  Result<Bytes> bytes32(const char* field) {
    HC_ASSIGN_OR_RETURN(const std::uint32_t n, u32(field));
    HC_ASSIGN_OR_RETURN(const ByteSpan s, raw(n, field));
    return Bytes(s.begin(), s.end());
  }
  Result<StringMap> string_map(const char* field) {
    HC_ASSIGN_OR_RETURN(const std::uint32_t n, u32(field));
    HC_ASSIGN_OR_RETURN(const ByteSpan s, raw(n, field));
    Cursor sub(s, record_);
    StringMap m;
    while (sub.left() > 0) {
      HC_ASSIGN_OR_RETURN(std::string k, sub.string(field));
      HC_ASSIGN_OR_RETURN(std::string v, sub.string(field));
      m[std::move(k)] = std::move(v);
    }
    return m;
  }
  Result<std::map<std::uint16_t, std::uint64_t>> u16_u64_map(const char* field) {
    HC_ASSIGN_OR_RETURN(const std::uint32_t n, u32(field));
    if (n % 10 != 0)
      return invalid_argument(
          fmt::format("{}: {} byte length {} is not a multiple of 10", record_, field, n));
    HC_ASSIGN_OR_RETURN(const ByteSpan s, raw(n, field));
    Cursor sub(s, record_);
    std::map<std::uint16_t, std::uint64_t> m;
    while (sub.left() > 0) {
      HC_ASSIGN_OR_RETURN(const std::uint16_t k, sub.u16(field));
      HC_ASSIGN_OR_RETURN(const std::uint64_t v, sub.u64(field));
      m[k] = v;
    }
    return m;
  }

 private:
  ByteSpan data_;
  const char* record_;
  std::size_t pos_ = 0;
};

// Byte-wise table CRC, sliced by 8 for speed (the recorder CRCs ~200 MB/s of frames; mcap #708
// reports a plain byte-table CRC as the C++ writer's bottleneck). zlib's crc32 would do the same
// job; kept local so the records module has no extra dependency and tests pin the exact variant.
struct Crc32Tables {
  std::uint32_t t[8][256];
  Crc32Tables() {
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? (0xEDB88320u ^ (c >> 1)) : (c >> 1);
      t[0][i] = c;
    }
    for (std::uint32_t i = 0; i < 256; ++i)
      for (int s = 1; s < 8; ++s) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFFu];
  }
};
const Crc32Tables& crc_tables() {
  static const Crc32Tables tables;
  return tables;
}

}  // namespace

std::string opcode_name(std::uint8_t opcode) {
  switch (static_cast<Opcode>(opcode)) {
    case Opcode::kHeader:
      return "Header";
    case Opcode::kFooter:
      return "Footer";
    case Opcode::kSchema:
      return "Schema";
    case Opcode::kChannel:
      return "Channel";
    case Opcode::kMessage:
      return "Message";
    case Opcode::kChunk:
      return "Chunk";
    case Opcode::kMessageIndex:
      return "MessageIndex";
    case Opcode::kChunkIndex:
      return "ChunkIndex";
    case Opcode::kAttachment:
      return "Attachment";
    case Opcode::kAttachmentIndex:
      return "AttachmentIndex";
    case Opcode::kStatistics:
      return "Statistics";
    case Opcode::kMetadata:
      return "Metadata";
    case Opcode::kMetadataIndex:
      return "MetadataIndex";
    case Opcode::kSummaryOffset:
      return "SummaryOffset";
    case Opcode::kDataEnd:
      return "DataEnd";
  }
  return fmt::format("Unknown(0x{:02X})", opcode);
}

std::uint32_t crc32_update(std::uint32_t state, ByteSpan data) {
  const auto& t = crc_tables().t;
  std::uint32_t c = state;
  const std::uint8_t* p = data.data();
  std::size_t n = data.size();
  while (n >= 8) {
    std::uint32_t lo = 0;
    std::uint32_t hi = 0;
    std::memcpy(&lo, p, 4);
    std::memcpy(&hi, p + 4, 4);
    if constexpr (std::endian::native == std::endian::big) {
      lo = __builtin_bswap32(lo);
      hi = __builtin_bswap32(hi);
    }
    lo ^= c;
    c = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^
        t[3][hi & 0xFF] ^ t[2][(hi >> 8) & 0xFF] ^ t[1][(hi >> 16) & 0xFF] ^ t[0][hi >> 24];
    p += 8;
    n -= 8;
  }
  while (n-- > 0) c = t[0][(c ^ *p++) & 0xFFu] ^ (c >> 8);
  return c;
}

// ---- encode ----
void encode(const Header& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kHeader);
  put_string(out, r.profile);
  put_string(out, r.library);
  end_record(out, at);
}
void encode(const Footer& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kFooter);
  put_u64(out, r.summary_start);
  put_u64(out, r.summary_offset_start);
  put_u32(out, r.summary_crc);
  end_record(out, at);
}
void encode(const Schema& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kSchema);
  put_u16(out, r.id);
  put_string(out, r.name);
  put_string(out, r.encoding);
  put_u32(out, static_cast<std::uint32_t>(r.data.size()));
  put_raw(out, r.data);
  end_record(out, at);
}
void encode(const Channel& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kChannel);
  put_u16(out, r.id);
  put_u16(out, r.schema_id);
  put_string(out, r.topic);
  put_string(out, r.message_encoding);
  put_string_map(out, r.metadata);
  end_record(out, at);
}
void encode_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                    std::uint64_t publish_time, ByteSpan data, Bytes& out) {
  put_u8(out, static_cast<std::uint8_t>(Opcode::kMessage));
  put_u64(out, 2 + 4 + 8 + 8 + data.size());
  put_u16(out, channel_id);
  put_u32(out, sequence);
  put_u64(out, log_time);
  put_u64(out, publish_time);
  put_raw(out, data);
}
void encode(const Message& r, Bytes& out) {
  encode_message(r.channel_id, r.sequence, r.log_time, r.publish_time, r.data, out);
}
void encode(const Chunk& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kChunk);
  put_u64(out, r.message_start_time);
  put_u64(out, r.message_end_time);
  put_u64(out, r.uncompressed_size);
  put_u32(out, r.uncompressed_crc);
  put_string(out, r.compression);
  put_u64(out, r.records.size());
  put_raw(out, r.records);
  end_record(out, at);
}
void encode(const MessageIndex& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kMessageIndex);
  put_u16(out, r.channel_id);
  put_u32(out, static_cast<std::uint32_t>(r.records.size() * 16));
  for (const auto& [t, o] : r.records) {
    put_u64(out, t);
    put_u64(out, o);
  }
  end_record(out, at);
}
void encode(const ChunkIndex& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kChunkIndex);
  put_u64(out, r.message_start_time);
  put_u64(out, r.message_end_time);
  put_u64(out, r.chunk_start_offset);
  put_u64(out, r.chunk_length);
  put_u16_u64_map(out, r.message_index_offsets);
  put_u64(out, r.message_index_length);
  put_string(out, r.compression);
  put_u64(out, r.compressed_size);
  put_u64(out, r.uncompressed_size);
  end_record(out, at);
}
namespace {
void put_attachment_fields(const Attachment& r, Bytes& out) {
  put_u64(out, r.log_time);
  put_u64(out, r.create_time);
  put_string(out, r.name);
  put_string(out, r.media_type);
  put_u64(out, r.data.size());
  put_raw(out, r.data);
}
}  // namespace
void encode(const Attachment& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kAttachment);
  put_attachment_fields(r, out);
  put_u32(out, r.crc);
  end_record(out, at);
}
std::uint32_t attachment_crc(const Attachment& r) {
  Bytes b;
  put_attachment_fields(r, b);
  return crc32(b);
}
void encode(const AttachmentIndex& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kAttachmentIndex);
  put_u64(out, r.offset);
  put_u64(out, r.length);
  put_u64(out, r.log_time);
  put_u64(out, r.create_time);
  put_u64(out, r.data_size);
  put_string(out, r.name);
  put_string(out, r.media_type);
  end_record(out, at);
}
void encode(const Statistics& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kStatistics);
  put_u64(out, r.message_count);
  put_u16(out, r.schema_count);
  put_u32(out, r.channel_count);
  put_u32(out, r.attachment_count);
  put_u32(out, r.metadata_count);
  put_u32(out, r.chunk_count);
  put_u64(out, r.message_start_time);
  put_u64(out, r.message_end_time);
  put_u16_u64_map(out, r.channel_message_counts);
  end_record(out, at);
}
void encode(const Metadata& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kMetadata);
  put_string(out, r.name);
  put_string_map(out, r.metadata);
  end_record(out, at);
}
void encode(const MetadataIndex& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kMetadataIndex);
  put_u64(out, r.offset);
  put_u64(out, r.length);
  put_string(out, r.name);
  end_record(out, at);
}
void encode(const SummaryOffset& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kSummaryOffset);
  put_u8(out, r.group_opcode);
  put_u64(out, r.group_start);
  put_u64(out, r.group_length);
  end_record(out, at);
}
void encode(const DataEnd& r, Bytes& out) {
  const auto at = begin_record(out, Opcode::kDataEnd);
  put_u32(out, r.data_section_crc);
  end_record(out, at);
}

// ---- decode ----
Result<Header> decode_header(ByteSpan content) {
  Cursor c(content, "Header");
  Header r;
  HC_ASSIGN_OR_RETURN(r.profile, c.string("profile"));
  HC_ASSIGN_OR_RETURN(r.library, c.string("library"));
  return r;
}
Result<Footer> decode_footer(ByteSpan content) {
  Cursor c(content, "Footer");
  Footer r;
  HC_ASSIGN_OR_RETURN(r.summary_start, c.u64("summary_start"));
  HC_ASSIGN_OR_RETURN(r.summary_offset_start, c.u64("summary_offset_start"));
  HC_ASSIGN_OR_RETURN(r.summary_crc, c.u32("summary_crc"));
  return r;
}
Result<Schema> decode_schema(ByteSpan content) {
  Cursor c(content, "Schema");
  Schema r;
  HC_ASSIGN_OR_RETURN(r.id, c.u16("id"));
  HC_ASSIGN_OR_RETURN(r.name, c.string("name"));
  HC_ASSIGN_OR_RETURN(r.encoding, c.string("encoding"));
  HC_ASSIGN_OR_RETURN(r.data, c.bytes32("data"));
  return r;
}
Result<Channel> decode_channel(ByteSpan content) {
  Cursor c(content, "Channel");
  Channel r;
  HC_ASSIGN_OR_RETURN(r.id, c.u16("id"));
  HC_ASSIGN_OR_RETURN(r.schema_id, c.u16("schema_id"));
  HC_ASSIGN_OR_RETURN(r.topic, c.string("topic"));
  HC_ASSIGN_OR_RETURN(r.message_encoding, c.string("message_encoding"));
  HC_ASSIGN_OR_RETURN(r.metadata, c.string_map("metadata"));
  return r;
}
Result<MessageView> decode_message_view(ByteSpan content) {
  Cursor c(content, "Message");
  MessageView r;
  HC_ASSIGN_OR_RETURN(r.channel_id, c.u16("channel_id"));
  HC_ASSIGN_OR_RETURN(r.sequence, c.u32("sequence"));
  HC_ASSIGN_OR_RETURN(r.log_time, c.u64("log_time"));
  HC_ASSIGN_OR_RETURN(r.publish_time, c.u64("publish_time"));
  r.data = content.subspan(c.pos());
  return r;
}
Result<Message> decode_message(ByteSpan content) {
  HC_ASSIGN_OR_RETURN(const MessageView v, decode_message_view(content));
  Message r;
  r.channel_id = v.channel_id;
  r.sequence = v.sequence;
  r.log_time = v.log_time;
  r.publish_time = v.publish_time;
  r.data.assign(v.data.begin(), v.data.end());
  return r;
}
Result<Chunk> decode_chunk(ByteSpan content) {
  Cursor c(content, "Chunk");
  Chunk r;
  HC_ASSIGN_OR_RETURN(r.message_start_time, c.u64("message_start_time"));
  HC_ASSIGN_OR_RETURN(r.message_end_time, c.u64("message_end_time"));
  HC_ASSIGN_OR_RETURN(r.uncompressed_size, c.u64("uncompressed_size"));
  HC_ASSIGN_OR_RETURN(r.uncompressed_crc, c.u32("uncompressed_crc"));
  HC_ASSIGN_OR_RETURN(r.compression, c.string("compression"));
  HC_ASSIGN_OR_RETURN(const std::uint64_t n, c.u64("records"));
  HC_ASSIGN_OR_RETURN(const ByteSpan recs, c.raw(n, "records"));
  r.records.assign(recs.begin(), recs.end());
  return r;
}
Result<ChunkView> decode_chunk_view(ByteSpan content) {
  Cursor c(content, "Chunk");
  ChunkView r;
  HC_ASSIGN_OR_RETURN(r.message_start_time, c.u64("message_start_time"));
  HC_ASSIGN_OR_RETURN(r.message_end_time, c.u64("message_end_time"));
  HC_ASSIGN_OR_RETURN(r.uncompressed_size, c.u64("uncompressed_size"));
  HC_ASSIGN_OR_RETURN(r.uncompressed_crc, c.u32("uncompressed_crc"));
  HC_ASSIGN_OR_RETURN(r.compression, c.string("compression"));
  HC_ASSIGN_OR_RETURN(const std::uint64_t n, c.u64("records"));
  HC_ASSIGN_OR_RETURN(r.records, c.raw(n, "records"));
  return r;
}
Result<MessageIndex> decode_message_index(ByteSpan content) {
  Cursor c(content, "MessageIndex");
  MessageIndex r;
  HC_ASSIGN_OR_RETURN(r.channel_id, c.u16("channel_id"));
  HC_ASSIGN_OR_RETURN(const std::uint32_t n, c.u32("records"));
  if (n % 16 != 0)
    return invalid_argument(
        fmt::format("MessageIndex: records byte length {} is not a multiple of 16", n));
  HC_ASSIGN_OR_RETURN(const ByteSpan recs, c.raw(n, "records"));
  Cursor sub(recs, "MessageIndex");
  r.records.reserve(n / 16);
  while (sub.left() > 0) {
    HC_ASSIGN_OR_RETURN(const std::uint64_t t, sub.u64("log_time"));
    HC_ASSIGN_OR_RETURN(const std::uint64_t o, sub.u64("offset"));
    r.records.emplace_back(t, o);
  }
  return r;
}
Result<ChunkIndex> decode_chunk_index(ByteSpan content) {
  Cursor c(content, "ChunkIndex");
  ChunkIndex r;
  HC_ASSIGN_OR_RETURN(r.message_start_time, c.u64("message_start_time"));
  HC_ASSIGN_OR_RETURN(r.message_end_time, c.u64("message_end_time"));
  HC_ASSIGN_OR_RETURN(r.chunk_start_offset, c.u64("chunk_start_offset"));
  HC_ASSIGN_OR_RETURN(r.chunk_length, c.u64("chunk_length"));
  HC_ASSIGN_OR_RETURN(r.message_index_offsets, c.u16_u64_map("message_index_offsets"));
  HC_ASSIGN_OR_RETURN(r.message_index_length, c.u64("message_index_length"));
  HC_ASSIGN_OR_RETURN(r.compression, c.string("compression"));
  HC_ASSIGN_OR_RETURN(r.compressed_size, c.u64("compressed_size"));
  HC_ASSIGN_OR_RETURN(r.uncompressed_size, c.u64("uncompressed_size"));
  return r;
}
Result<Attachment> decode_attachment(ByteSpan content) {
  Cursor c(content, "Attachment");
  Attachment r;
  HC_ASSIGN_OR_RETURN(r.log_time, c.u64("log_time"));
  HC_ASSIGN_OR_RETURN(r.create_time, c.u64("create_time"));
  HC_ASSIGN_OR_RETURN(r.name, c.string("name"));
  HC_ASSIGN_OR_RETURN(r.media_type, c.string("media_type"));
  HC_ASSIGN_OR_RETURN(const std::uint64_t n, c.u64("data"));
  HC_ASSIGN_OR_RETURN(const ByteSpan d, c.raw(n, "data"));
  r.data.assign(d.begin(), d.end());
  HC_ASSIGN_OR_RETURN(r.crc, c.u32("crc"));
  return r;
}
Result<AttachmentIndex> decode_attachment_index(ByteSpan content) {
  Cursor c(content, "AttachmentIndex");
  AttachmentIndex r;
  HC_ASSIGN_OR_RETURN(r.offset, c.u64("offset"));
  HC_ASSIGN_OR_RETURN(r.length, c.u64("length"));
  HC_ASSIGN_OR_RETURN(r.log_time, c.u64("log_time"));
  HC_ASSIGN_OR_RETURN(r.create_time, c.u64("create_time"));
  HC_ASSIGN_OR_RETURN(r.data_size, c.u64("data_size"));
  HC_ASSIGN_OR_RETURN(r.name, c.string("name"));
  HC_ASSIGN_OR_RETURN(r.media_type, c.string("media_type"));
  return r;
}
Result<Statistics> decode_statistics(ByteSpan content) {
  Cursor c(content, "Statistics");
  Statistics r;
  HC_ASSIGN_OR_RETURN(r.message_count, c.u64("message_count"));
  HC_ASSIGN_OR_RETURN(r.schema_count, c.u16("schema_count"));
  HC_ASSIGN_OR_RETURN(r.channel_count, c.u32("channel_count"));
  HC_ASSIGN_OR_RETURN(r.attachment_count, c.u32("attachment_count"));
  HC_ASSIGN_OR_RETURN(r.metadata_count, c.u32("metadata_count"));
  HC_ASSIGN_OR_RETURN(r.chunk_count, c.u32("chunk_count"));
  HC_ASSIGN_OR_RETURN(r.message_start_time, c.u64("message_start_time"));
  HC_ASSIGN_OR_RETURN(r.message_end_time, c.u64("message_end_time"));
  HC_ASSIGN_OR_RETURN(r.channel_message_counts, c.u16_u64_map("channel_message_counts"));
  return r;
}
Result<Metadata> decode_metadata(ByteSpan content) {
  Cursor c(content, "Metadata");
  Metadata r;
  HC_ASSIGN_OR_RETURN(r.name, c.string("name"));
  HC_ASSIGN_OR_RETURN(r.metadata, c.string_map("metadata"));
  return r;
}
Result<MetadataIndex> decode_metadata_index(ByteSpan content) {
  Cursor c(content, "MetadataIndex");
  MetadataIndex r;
  HC_ASSIGN_OR_RETURN(r.offset, c.u64("offset"));
  HC_ASSIGN_OR_RETURN(r.length, c.u64("length"));
  HC_ASSIGN_OR_RETURN(r.name, c.string("name"));
  return r;
}
Result<SummaryOffset> decode_summary_offset(ByteSpan content) {
  Cursor c(content, "SummaryOffset");
  SummaryOffset r;
  HC_ASSIGN_OR_RETURN(r.group_opcode, c.u8("group_opcode"));
  HC_ASSIGN_OR_RETURN(r.group_start, c.u64("group_start"));
  HC_ASSIGN_OR_RETURN(r.group_length, c.u64("group_length"));
  return r;
}
Result<DataEnd> decode_data_end(ByteSpan content) {
  Cursor c(content, "DataEnd");
  DataEnd r;
  HC_ASSIGN_OR_RETURN(r.data_section_crc, c.u32("data_section_crc"));
  return r;
}

Result<RecordView> next_record(ByteSpan buffer, std::uint64_t base_offset) {
  if (buffer.size() < kRecordPrefixSize)
    return invalid_argument(
        fmt::format("offset {}: record prefix needs 9 bytes, {} left", base_offset, buffer.size()));
  RecordView v;
  v.opcode = buffer[0];
  std::uint64_t len = 0;
  for (int i = 8; i >= 1; --i) len = (len << 8) | buffer[static_cast<std::size_t>(i)];
  if (len > buffer.size() - kRecordPrefixSize)
    return invalid_argument(fmt::format("offset {}: {} record length {} exceeds the {} bytes left",
                                        base_offset, opcode_name(v.opcode), len,
                                        buffer.size() - kRecordPrefixSize));
  v.content = buffer.subspan(kRecordPrefixSize, static_cast<std::size_t>(len));
  v.size = kRecordPrefixSize + len;
  return v;
}

// ---- compression ----
Result<Compression> parse_compression(std::string_view name) {
  if (name.empty() || name == "none") return Compression::kNone;
  if (name == "lz4") return Compression::kLz4;
  if (name == "zstd") return Compression::kZstd;
  return invalid_argument(
      fmt::format("unknown compression '{}' (expected none, lz4 or zstd)", name));
}
std::string_view compression_record_name(Compression c) {
  switch (c) {
    case Compression::kNone:
      return "";
    case Compression::kLz4:
      return "lz4";
    case Compression::kZstd:
      return "zstd";
  }
  return "";
}
std::string_view compression_display_name(Compression c) {
  return c == Compression::kNone ? "none" : compression_record_name(c);
}

Result<Bytes> compress(Compression c, ByteSpan data, int level) {
  switch (c) {
    case Compression::kNone:
      return Bytes(data.begin(), data.end());
    case Compression::kZstd: {
      Bytes out(ZSTD_compressBound(data.size()));
      const std::size_t n = ZSTD_compress(out.data(), out.size(), data.data(), data.size(), level);
      if (ZSTD_isError(n) != 0)
        return internal_error(fmt::format("zstd compression failed: {}", ZSTD_getErrorName(n)));
      out.resize(n);
      return out;
    }
    case Compression::kLz4: {
      LZ4F_preferences_t prefs{};
      prefs.compressionLevel = level;
      prefs.frameInfo.contentSize = data.size();
      prefs.frameInfo.blockSizeID = LZ4F_max4MB;
      Bytes out(LZ4F_compressFrameBound(data.size(), &prefs));
      const std::size_t n =
          LZ4F_compressFrame(out.data(), out.size(), data.data(), data.size(), &prefs);
      if (LZ4F_isError(n) != 0)
        return internal_error(fmt::format("lz4 compression failed: {}", LZ4F_getErrorName(n)));
      out.resize(n);
      return out;
    }
  }
  return internal_error("unknown compression");
}

Result<Bytes> decompress(std::string_view compression, ByteSpan data,
                         std::uint64_t uncompressed_size, std::uint64_t max_size) {
  if (uncompressed_size > max_size)
    return invalid_argument(
        fmt::format("uncompressed size {} exceeds the limit {}", uncompressed_size, max_size));
  if (compression.empty()) {
    if (data.size() != uncompressed_size)
      return invalid_argument(
          fmt::format("uncompressed chunk holds {} bytes but uncompressed_size says {}",
                      data.size(), uncompressed_size));
    return Bytes(data.begin(), data.end());
  }
  if (compression == "zstd") {
    // A zstd frame cannot expand by more than ~ 1:(2^17) (block-level limit); refuse sizes no
    // input of this length could produce before allocating.
    if (uncompressed_size / 131072 > data.size() + 1)
      return invalid_argument(
          fmt::format("zstd: {} compressed bytes cannot hold {} uncompressed bytes", data.size(),
                      uncompressed_size));
    Bytes out(static_cast<std::size_t>(uncompressed_size));
    const std::size_t n = ZSTD_decompress(out.data(), out.size(), data.data(), data.size());
    if (ZSTD_isError(n) != 0)
      return invalid_argument(fmt::format("zstd: {}", ZSTD_getErrorName(n)));
    if (n != uncompressed_size)
      return invalid_argument(fmt::format("zstd: decompressed {} bytes, uncompressed_size says {}",
                                          n, uncompressed_size));
    return out;
  }
  if (compression == "lz4") {
    // LZ4 cannot expand by more than 255:1.
    if (uncompressed_size / 255 > data.size() + 1)
      return invalid_argument(
          fmt::format("lz4: {} compressed bytes cannot hold {} uncompressed bytes", data.size(),
                      uncompressed_size));
    LZ4F_dctx* dctx = nullptr;
    if (LZ4F_isError(LZ4F_createDecompressionContext(&dctx, LZ4F_VERSION)) != 0)
      return internal_error("lz4: cannot create a decompression context");
    Bytes out(static_cast<std::size_t>(uncompressed_size));
    std::size_t in_pos = 0;
    std::size_t out_pos = 0;
    Status status;
    while (true) {
      std::size_t dst = out.size() - out_pos;
      std::size_t src = data.size() - in_pos;
      // A spare byte of output room makes "more data than declared" detectable.
      std::uint8_t* dst_ptr = out.data() + out_pos;
      std::uint8_t extra = 0;
      if (dst == 0) {
        dst_ptr = &extra;
        dst = 1;
      }
      const std::size_t hint =
          LZ4F_decompress(dctx, dst_ptr, &dst, data.data() + in_pos, &src, nullptr);
      if (LZ4F_isError(hint) != 0) {
        status = invalid_argument(fmt::format("lz4: {}", LZ4F_getErrorName(hint)));
        break;
      }
      if (dst_ptr == &extra && dst > 0) {
        status = invalid_argument(
            fmt::format("lz4: frame holds more than the {} bytes declared", uncompressed_size));
        break;
      }
      in_pos += src;
      out_pos += (dst_ptr == &extra) ? 0 : dst;
      if (hint == 0) break;  // frame complete
      if (src == 0 && dst == 0) {
        status = invalid_argument("lz4: truncated frame");
        break;
      }
      if (in_pos >= data.size()) {
        status = invalid_argument("lz4: truncated frame");
        break;
      }
    }
    LZ4F_freeDecompressionContext(dctx);
    HC_RETURN_IF_ERROR(status);
    if (out_pos != uncompressed_size)
      return invalid_argument(fmt::format("lz4: decompressed {} bytes, uncompressed_size says {}",
                                          out_pos, uncompressed_size));
    return out;
  }
  return unsupported(fmt::format("unknown chunk compression '{}'", compression));
}

}  // namespace hc::recording
