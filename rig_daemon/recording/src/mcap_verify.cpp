// verify (see mcap_tools.h; session_info is in mcap_tools.cpp, recover in mcap_recover.cpp).
#include "rig_daemon/recording/mcap_tools.h"

#include <algorithm>
#include <optional>
#include <set>

#include <fmt/format.h>

namespace hc::recording {
namespace {

Bytes prefix_bytes(std::uint8_t opcode, std::uint64_t len) {
  Bytes b;
  b.push_back(opcode);
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<std::uint8_t>(len >> (8 * i)));
  return b;
}

std::uint32_t crc_record(std::uint32_t state, const LinearRecord& r) {
  state = crc32_update(state, prefix_bytes(r.opcode, r.content.size()));
  return crc32_update(state, r.content);
}

// Everything verify learns about one Chunk and the MessageIndex records after it.
struct ChunkSeen {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  ChunkView header;  // records view invalid after the callback
  std::uint64_t compressed_size = 0;
  bool decoded = false;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> messages;
  std::map<std::uint16_t, std::uint64_t> index_offsets;  // channel -> MessageIndex record offset
  std::map<std::uint16_t, MessageIndex> indexes;
  std::uint64_t index_length = 0;
};

// At most this many problems are listed; the rest are only counted.
constexpr std::size_t kMaxProblems = 200;

// What verify learns from its single linear scan of the file (on_record), and the checks it runs
// on that once the scan has ended (check_*; verify calls them in a fixed order, which is the order
// of the report's problems).
class Verifier {
 public:
  Status on_record(const LinearRecord& r);

  void check_scan_end(const LinearScanResult& scan);
  void check_message_indexes();
  void check_footer();
  bool has_summary() const { return footer_ && footer_->summary_start != 0; }
  // The summary section against the data section, when the file has one.
  void check_summary_definitions();
  void check_chunk_indexes();
  void check_statistics();
  void check_metadata_and_attachment_indexes();
  // Whether or not it has one.
  void check_summary_offsets();

  VerifyReport finish() &&;

 private:
  void problem(std::uint64_t off, const std::string& what);
  void define_schema(std::map<std::uint16_t, Schema>& into, ByteSpan c, std::uint64_t off);
  void define_channel(std::map<std::uint16_t, Channel>& into, ByteSpan c, std::uint64_t off,
                      const std::map<std::uint16_t, Schema>& known);
  void note_message(const MessageView& m, std::uint64_t off);

  void on_first_record(const LinearRecord& r);
  void on_footer(const LinearRecord& r);
  void on_data_end(const LinearRecord& r);
  void on_data_record(const LinearRecord& r);
  void on_chunk(const LinearRecord& r);
  void check_chunk_content(std::uint64_t off, const ChunkView& cv, ChunkSeen& cs);
  bool check_chunk_records(std::uint64_t off, const ChunkView& cv, const Bytes& records,
                           ChunkSeen& cs);
  void on_message_index(const LinearRecord& r);
  void on_attachment(const LinearRecord& r);
  void on_summary_record(const LinearRecord& r);
  void check_chunk_message_indexes(const ChunkSeen& cs);
  void check_chunk_index(const ChunkIndex& ci, const ChunkSeen& cs);

  VerifyReport rep_;
  std::uint64_t suppressed_ = 0;

  // Data section.
  std::vector<ChunkSeen> chunks_;
  bool chunk_open_ = false;  // the last data record was a Chunk or one of its MessageIndexes
  std::map<std::uint16_t, Schema> schemas_;
  std::map<std::uint16_t, Channel> channels_;
  std::map<std::uint16_t, std::uint64_t> counts_;
  std::uint64_t total_ = 0;
  std::uint64_t t_min_ = 0, t_max_ = 0;
  std::vector<MetadataIndex> metadata_seen_;
  std::vector<AttachmentIndex> attachments_seen_;

  bool header_seen_ = false;
  bool first_ = true;
  bool in_summary_ = false;
  // Summary section.
  std::uint64_t summary_first_ = 0;
  std::map<std::uint16_t, Schema> sum_schemas_;
  std::map<std::uint16_t, Channel> sum_channels_;
  std::optional<Statistics> stats_;
  std::vector<ChunkIndex> chunk_indexes_;
  std::vector<AttachmentIndex> attachment_indexes_;
  std::vector<MetadataIndex> metadata_indexes_;
  std::vector<SummaryOffset> summary_offsets_;
  std::vector<std::tuple<std::uint64_t, std::uint8_t, std::uint64_t>> summary_records_;
  std::optional<Footer> footer_;
  std::uint64_t footer_offset_ = 0;
  std::uint32_t data_crc_ = crc32_update(kCrc32Init, kMagic);
  std::uint32_t summary_crc_ = kCrc32Init;
  bool data_end_seen_ = false;
};

void Verifier::problem(std::uint64_t off, const std::string& what) {
  if (rep_.problems.size() < kMaxProblems)
    rep_.problems.push_back(fmt::format("offset {}: {}", off, what));
  else
    ++suppressed_;
}

void Verifier::define_schema(std::map<std::uint16_t, Schema>& into, ByteSpan c, std::uint64_t off) {
  auto s = decode_schema(c);
  if (!s.ok()) return problem(off, s.status().message());
  if (s->id == 0) return problem(off, "Schema with reserved id 0");
  auto it = into.find(s->id);
  if (it != into.end() && !(it->second == *s))
    return problem(off, fmt::format("Schema id {} redefined differently", s->id));
  into[s->id] = std::move(s).value();
}

void Verifier::define_channel(std::map<std::uint16_t, Channel>& into, ByteSpan c, std::uint64_t off,
                              const std::map<std::uint16_t, Schema>& known) {
  auto ch = decode_channel(c);
  if (!ch.ok()) return problem(off, ch.status().message());
  if (ch->schema_id != 0 && known.count(ch->schema_id) == 0)
    problem(off, fmt::format("Channel {} ('{}') uses undefined schema id {}", ch->id, ch->topic,
                             ch->schema_id));
  auto it = into.find(ch->id);
  if (it != into.end() && !(it->second == *ch))
    return problem(off, fmt::format("Channel id {} redefined differently", ch->id));
  into[ch->id] = std::move(ch).value();
}

void Verifier::note_message(const MessageView& m, std::uint64_t off) {
  if (channels_.count(m.channel_id) == 0)
    problem(off, fmt::format("Message on channel id {} before any Channel record defines it",
                             m.channel_id));
  if (total_ == 0) t_min_ = t_max_ = m.log_time;
  t_min_ = std::min(t_min_, m.log_time);
  t_max_ = std::max(t_max_, m.log_time);
  ++total_;
  ++counts_[m.channel_id];
  ++rep_.messages_checked;
}

// ---- the scan ----

Status Verifier::on_record(const LinearRecord& r) {
  if (first_) on_first_record(r);
  if (static_cast<Opcode>(r.opcode) == Opcode::kFooter)
    on_footer(r);
  else if (!in_summary_)
    on_data_record(r);
  else
    on_summary_record(r);
  return {};
}

void Verifier::on_first_record(const LinearRecord& r) {
  first_ = false;
  if (static_cast<Opcode>(r.opcode) != Opcode::kHeader)
    problem(r.offset, fmt::format("first record is {}, expected Header", opcode_name(r.opcode)));
  else if (auto h = decode_header(r.content); !h.ok())
    problem(r.offset, h.status().message());
  else
    header_seen_ = true;
}

void Verifier::on_footer(const LinearRecord& r) {
  auto f = decode_footer(r.content);
  if (!f.ok()) return problem(r.offset, f.status().message());
  footer_ = *f;
  footer_offset_ = r.offset;
  // The summary CRC covers the Footer up to (not including) the CRC field itself.
  summary_crc_ = crc32_update(summary_crc_, prefix_bytes(r.opcode, r.content.size()));
  summary_crc_ =
      crc32_update(summary_crc_, r.content.first(std::min<std::size_t>(16, r.content.size())));
}

void Verifier::on_data_end(const LinearRecord& r) {
  data_end_seen_ = true;
  auto de = decode_data_end(r.content);
  if (!de.ok()) {
    problem(r.offset, de.status().message());
  } else if (de->data_section_crc != 0) {
    ++rep_.crcs_checked;
    const std::uint32_t computed = crc32_final(data_crc_);
    if (computed != de->data_section_crc)
      problem(r.offset, fmt::format("DataEnd: data section CRC mismatch (stored 0x{:08x}, "
                                    "computed 0x{:08x})",
                                    de->data_section_crc, computed));
  }
  in_summary_ = true;
  summary_first_ = r.offset + kRecordPrefixSize + r.content.size();
}

void Verifier::on_data_record(const LinearRecord& r) {
  const auto opc = static_cast<Opcode>(r.opcode);
  if (opc == Opcode::kDataEnd) return on_data_end(r);
  data_crc_ = crc_record(data_crc_, r);
  if (opc != Opcode::kMessageIndex) chunk_open_ = false;
  switch (opc) {
    case Opcode::kHeader:
      if (r.offset != kMagic.size()) problem(r.offset, "second Header record");
      break;
    case Opcode::kSchema:
      define_schema(schemas_, r.content, r.offset);
      break;
    case Opcode::kChannel:
      define_channel(channels_, r.content, r.offset, schemas_);
      break;
    case Opcode::kMessage: {
      auto m = decode_message_view(r.content);
      if (!m.ok())
        problem(r.offset, m.status().message());
      else
        note_message(*m, r.offset);
      break;
    }
    case Opcode::kChunk:
      on_chunk(r);
      break;
    case Opcode::kMessageIndex:
      on_message_index(r);
      break;
    case Opcode::kMetadata: {
      auto md = decode_metadata(r.content);
      if (!md.ok()) {
        problem(r.offset, md.status().message());
        break;
      }
      metadata_seen_.push_back({r.offset, kRecordPrefixSize + r.content.size(), md->name});
      break;
    }
    case Opcode::kAttachment:
      on_attachment(r);
      break;
    case Opcode::kFooter:
    case Opcode::kDataEnd:
      break;
    case Opcode::kChunkIndex:
    case Opcode::kAttachmentIndex:
    case Opcode::kStatistics:
    case Opcode::kMetadataIndex:
    case Opcode::kSummaryOffset:
      problem(r.offset, fmt::format("{} record in the data section", opcode_name(r.opcode)));
      break;
    default:
      break;  // unknown opcodes are allowed
  }
}

void Verifier::on_chunk(const LinearRecord& r) {
  ++rep_.chunks_checked;
  ChunkSeen cs;
  cs.offset = r.offset;
  cs.length = kRecordPrefixSize + r.content.size();
  if (auto cv = decode_chunk_view(r.content); !cv.ok())
    problem(r.offset, cv.status().message());
  else
    check_chunk_content(r.offset, *cv, cs);
  // Recorded even when it does not decode: the chunk indexes and statistics still count it.
  chunks_.push_back(std::move(cs));
  chunk_open_ = true;
}

// Decompresses the chunk and checks its CRC and records; cs.decoded tells whether its messages
// are all known (only then are its message indexes checked against them).
void Verifier::check_chunk_content(std::uint64_t off, const ChunkView& cv, ChunkSeen& cs) {
  cs.header = cv;
  cs.header.records = {};
  cs.compressed_size = cv.records.size();
  auto records = decompress(cv.compression, cv.records, cv.uncompressed_size, 1ull << 34);
  if (!records.ok()) return problem(off, "Chunk: " + records.status().message());
  bool crc_ok = true;
  if (cv.uncompressed_crc != 0) {
    ++rep_.crcs_checked;
    const std::uint32_t computed = crc32(*records);
    if (computed != cv.uncompressed_crc) {
      crc_ok = false;
      problem(off, fmt::format("Chunk: uncompressed CRC mismatch (stored 0x{:08x}, "
                               "computed 0x{:08x})",
                               cv.uncompressed_crc, computed));
    }
  }
  // The records of a chunk failing its CRC are not read (and its message indexes not checked).
  cs.decoded = crc_ok && check_chunk_records(off, cv, *records, cs);
}

// The records inside a decompressed chunk: false when they do not parse to its end.
bool Verifier::check_chunk_records(std::uint64_t off, const ChunkView& cv, const Bytes& records,
                                   ChunkSeen& cs) {
  std::uint64_t pos = 0;
  while (pos < records.size()) {
    auto rec = next_record(ByteSpan(records).subspan(static_cast<std::size_t>(pos)), pos);
    if (!rec.ok()) {
      problem(off, "inside Chunk: " + rec.status().message());
      return false;
    }
    if (rec->opcode == opcode_byte(Opcode::kSchema)) {
      define_schema(schemas_, rec->content, off);
    } else if (rec->opcode == opcode_byte(Opcode::kChannel)) {
      define_channel(channels_, rec->content, off, schemas_);
    } else if (rec->opcode == opcode_byte(Opcode::kMessage)) {
      auto m = decode_message_view(rec->content);
      if (!m.ok()) {
        problem(off, "inside Chunk at " + std::to_string(pos) + ": " + m.status().message());
      } else {
        note_message(*m, off);
        cs.messages[m->channel_id].emplace_back(m->log_time, pos);
        if (m->log_time < cv.message_start_time || m->log_time > cv.message_end_time)
          problem(off, fmt::format("Chunk: message at {} has log_time {} outside the "
                                   "chunk's [{}, {}]",
                                   pos, m->log_time, cv.message_start_time, cv.message_end_time));
      }
    } else {
      problem(off, fmt::format("Chunk holds a {} record at {}", opcode_name(rec->opcode), pos));
    }
    pos += rec->size;
  }
  return true;
}

void Verifier::on_message_index(const LinearRecord& r) {
  auto mi = decode_message_index(r.content);
  if (!mi.ok()) return problem(r.offset, mi.status().message());
  if (!chunk_open_ || chunks_.empty())
    return problem(r.offset, "MessageIndex not following a Chunk");
  ChunkSeen& cs = chunks_.back();
  if (cs.indexes.count(mi->channel_id) != 0)
    problem(r.offset, fmt::format("second MessageIndex for channel {} after the chunk at {}",
                                  mi->channel_id, cs.offset));
  cs.index_offsets[mi->channel_id] = r.offset;
  cs.index_length += kRecordPrefixSize + r.content.size();
  cs.indexes[mi->channel_id] = std::move(mi).value();
}

void Verifier::on_attachment(const LinearRecord& r) {
  auto a = decode_attachment(r.content);
  if (!a.ok()) return problem(r.offset, a.status().message());
  if (a->crc != 0) {
    ++rep_.crcs_checked;
    const std::uint32_t computed = attachment_crc(*a);
    if (computed != a->crc)
      problem(r.offset, fmt::format("Attachment '{}': CRC mismatch (stored 0x{:08x}, "
                                    "computed 0x{:08x})",
                                    a->name, a->crc, computed));
  }
  attachments_seen_.push_back({r.offset, kRecordPrefixSize + r.content.size(), a->log_time,
                               a->create_time, a->data.size(), a->name, a->media_type});
}

// Summary section (and summary offsets).
void Verifier::on_summary_record(const LinearRecord& r) {
  summary_crc_ = crc_record(summary_crc_, r);
  summary_records_.emplace_back(r.offset, r.opcode, kRecordPrefixSize + r.content.size());
  auto bad = [&](const Status& s) { problem(r.offset, s.message()); };
  // An index record decoded into its list, or reported where it does not decode.
  auto collect = [&](auto decoded, auto* list) {
    if (!decoded.ok())
      bad(decoded.status());
    else
      list->push_back(std::move(decoded).value());
  };
  switch (static_cast<Opcode>(r.opcode)) {
    case Opcode::kSchema:
      define_schema(sum_schemas_, r.content, r.offset);
      break;
    case Opcode::kChannel:
      define_channel(sum_channels_, r.content, r.offset, sum_schemas_);
      break;
    case Opcode::kStatistics: {
      auto s = decode_statistics(r.content);
      if (!s.ok())
        bad(s.status());
      else if (stats_)
        problem(r.offset, "second Statistics record");
      else
        stats_ = *s;
      break;
    }
    case Opcode::kChunkIndex:
      collect(decode_chunk_index(r.content), &chunk_indexes_);
      break;
    case Opcode::kAttachmentIndex:
      collect(decode_attachment_index(r.content), &attachment_indexes_);
      break;
    case Opcode::kMetadataIndex:
      collect(decode_metadata_index(r.content), &metadata_indexes_);
      break;
    case Opcode::kSummaryOffset:
      collect(decode_summary_offset(r.content), &summary_offsets_);
      break;
    case Opcode::kMessage:
    case Opcode::kChunk:
    case Opcode::kMessageIndex:
    case Opcode::kHeader:
    case Opcode::kDataEnd:
    case Opcode::kAttachment:
    case Opcode::kMetadata:
      problem(r.offset, fmt::format("{} record in the summary section", opcode_name(r.opcode)));
      break;
    default:
      break;
  }
}

// ---- the checks after the scan ----

void Verifier::check_scan_end(const LinearScanResult& scan) {
  if (!header_seen_ && rep_.problems.empty()) problem(kMagic.size(), "no Header record");
  if (!scan.reached_footer) problem(scan.end_offset, "file incomplete: " + scan.stop_reason);
  if (!data_end_seen_ && scan.reached_footer)
    problem(footer_offset_, "no DataEnd record before the summary / Footer");
}

// Message indexes against the messages of each chunk.
void Verifier::check_message_indexes() {
  for (const ChunkSeen& cs : chunks_) {
    if (!cs.decoded) continue;
    if (cs.indexes.empty()) continue;  // message indexes are optional; all or nothing per chunk
    check_chunk_message_indexes(cs);
  }
}

void Verifier::check_chunk_message_indexes(const ChunkSeen& cs) {
  for (const auto& [ch, msgs] : cs.messages) {
    auto it = cs.indexes.find(ch);
    if (it == cs.indexes.end()) {
      problem(cs.offset, fmt::format("Chunk has messages on channel {} but no MessageIndex", ch));
      continue;
    }
    auto a = msgs;
    auto b = it->second.records;
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    if (a != b)
      problem(cs.index_offsets.at(ch),
              fmt::format("MessageIndex for channel {} lists {} entries that do not match the "
                          "chunk's {} messages (log_time, offset)",
                          ch, b.size(), a.size()));
  }
  for (const auto& [ch, mi] : cs.indexes)
    if (cs.messages.count(ch) == 0 && !mi.records.empty())
      problem(cs.index_offsets.at(ch),
              fmt::format("MessageIndex for channel {} but the chunk has no message on it", ch));
}

void Verifier::check_footer() {
  rep_.has_summary = has_summary();
  if (!footer_) return;
  const std::uint64_t expect_start = summary_records_.empty() ? 0 : summary_first_;
  // The summary section is the records before the first SummaryOffset.
  std::uint64_t first_so = 0;
  for (const auto& [off, opc, len] : summary_records_)
    if (opc == opcode_byte(Opcode::kSummaryOffset)) {
      first_so = off;
      break;
    }
  const bool only_offsets = !summary_records_.empty() && std::get<1>(summary_records_.front()) ==
                                                             opcode_byte(Opcode::kSummaryOffset);
  if (footer_->summary_start != (only_offsets ? 0 : expect_start))
    problem(footer_offset_, fmt::format("Footer: summary_start {} but the summary starts at {}",
                                        footer_->summary_start, only_offsets ? 0 : expect_start));
  if (footer_->summary_offset_start != first_so)
    problem(footer_offset_,
            fmt::format("Footer: summary_offset_start {} but the first SummaryOffset is at {}",
                        footer_->summary_offset_start, first_so));
  if (footer_->summary_crc != 0) {
    ++rep_.crcs_checked;
    const std::uint32_t computed = crc32_final(summary_crc_);
    if (computed != footer_->summary_crc)
      problem(footer_offset_, fmt::format("Footer: summary CRC mismatch (stored 0x{:08x}, "
                                          "computed 0x{:08x})",
                                          footer_->summary_crc, computed));
  }
}

// Schemas and channels: every one met in the data section is repeated, identically.
void Verifier::check_summary_definitions() {
  for (const auto& [id, s] : schemas_) {
    auto it = sum_schemas_.find(id);
    if (it == sum_schemas_.end())
      problem(footer_->summary_start, fmt::format("summary lacks Schema {} ('{}')", id, s.name));
    else if (!(it->second == s))
      problem(footer_->summary_start,
              fmt::format("summary Schema {} differs from the data section's", id));
  }
  for (const auto& [id, c] : channels_) {
    auto it = sum_channels_.find(id);
    if (it == sum_channels_.end())
      problem(footer_->summary_start, fmt::format("summary lacks Channel {} ('{}')", id, c.topic));
    else if (!(it->second == c))
      problem(footer_->summary_start,
              fmt::format("summary Channel {} differs from the data section's", id));
  }
}

// Chunk indexes: each points at a chunk and describes it exactly; with any, every chunk has one.
void Verifier::check_chunk_indexes() {
  std::map<std::uint64_t, const ChunkSeen*> by_offset;
  for (const auto& cs : chunks_) by_offset[cs.offset] = &cs;
  std::set<std::uint64_t> indexed;
  for (const auto& ci : chunk_indexes_) {
    auto it = by_offset.find(ci.chunk_start_offset);
    if (it == by_offset.end()) {
      problem(footer_->summary_start,
              fmt::format("ChunkIndex points at offset {} where no Chunk starts",
                          ci.chunk_start_offset));
      continue;
    }
    if (!indexed.insert(ci.chunk_start_offset).second)
      problem(ci.chunk_start_offset, "Chunk indexed twice");
    check_chunk_index(ci, *it->second);
  }
  if (!chunk_indexes_.empty())
    for (const auto& cs : chunks_)
      if (indexed.count(cs.offset) == 0) problem(cs.offset, "Chunk missing from the chunk indexes");
}

void Verifier::check_chunk_index(const ChunkIndex& ci, const ChunkSeen& cs) {
  auto mismatch = [&](const char* field, std::uint64_t idx, std::uint64_t actual) {
    if (idx != actual)
      problem(cs.offset,
              fmt::format("ChunkIndex.{} is {} but the chunk has {}", field, idx, actual));
  };
  mismatch("chunk_length", ci.chunk_length, cs.length);
  mismatch("message_start_time", ci.message_start_time, cs.header.message_start_time);
  mismatch("message_end_time", ci.message_end_time, cs.header.message_end_time);
  mismatch("compressed_size", ci.compressed_size, cs.compressed_size);
  mismatch("uncompressed_size", ci.uncompressed_size, cs.header.uncompressed_size);
  mismatch("message_index_length", ci.message_index_length, cs.index_length);
  if (ci.compression != cs.header.compression)
    problem(cs.offset, fmt::format("ChunkIndex.compression '{}' but the chunk has '{}'",
                                   ci.compression, cs.header.compression));
  if (ci.message_index_offsets != cs.index_offsets)
    problem(cs.offset, "ChunkIndex.message_index_offsets do not match the MessageIndex records");
}

void Verifier::check_statistics() {
  if (!stats_) return;
  auto check = [&](const char* field, std::uint64_t stored, std::uint64_t actual) {
    if (stored != actual)
      problem(footer_->summary_start,
              fmt::format("Statistics.{} is {} but the file has {}", field, stored, actual));
  };
  check("message_count", stats_->message_count, total_);
  std::set<std::uint16_t> all_schemas, all_channels;
  for (const auto& [id, s] : sum_schemas_) all_schemas.insert(id);
  for (const auto& [id, s] : schemas_) all_schemas.insert(id);
  for (const auto& [id, c] : sum_channels_) all_channels.insert(id);
  for (const auto& [id, c] : channels_) all_channels.insert(id);
  check("schema_count", stats_->schema_count, all_schemas.size());
  check("channel_count", stats_->channel_count, all_channels.size());
  check("chunk_count", stats_->chunk_count, chunks_.size());
  check("metadata_count", stats_->metadata_count, metadata_seen_.size());
  check("attachment_count", stats_->attachment_count, attachments_seen_.size());
  if (total_ > 0) {
    check("message_start_time", stats_->message_start_time, t_min_);
    check("message_end_time", stats_->message_end_time, t_max_);
  }
  for (const auto& [ch, n] : counts_) {
    auto it = stats_->channel_message_counts.find(ch);
    check(fmt::format("channel_message_counts[{}]", ch).c_str(),
          it == stats_->channel_message_counts.end() ? 0 : it->second, n);
  }
  for (const auto& [ch, n] : stats_->channel_message_counts)
    if (counts_.count(ch) == 0 && n != 0)
      check(fmt::format("channel_message_counts[{}]", ch).c_str(), n, 0);
}

void Verifier::check_metadata_and_attachment_indexes() {
  auto same_md = [](const MetadataIndex& a, const MetadataIndex& b) { return a == b; };
  for (const auto& mi : metadata_indexes_)
    if (std::none_of(metadata_seen_.begin(), metadata_seen_.end(),
                     [&](const MetadataIndex& s) { return same_md(s, mi); }))
      problem(footer_->summary_start,
              fmt::format("MetadataIndex '{}' (offset {}, length {}) matches no "
                          "Metadata record",
                          mi.name, mi.offset, mi.length));
  if (!metadata_indexes_.empty() && metadata_indexes_.size() != metadata_seen_.size())
    problem(footer_->summary_start, fmt::format("{} MetadataIndex records for {} Metadata records",
                                                metadata_indexes_.size(), metadata_seen_.size()));
  for (const auto& ai : attachment_indexes_)
    if (std::none_of(attachments_seen_.begin(), attachments_seen_.end(),
                     [&](const AttachmentIndex& s) { return s == ai; }))
      problem(footer_->summary_start, fmt::format("AttachmentIndex '{}' (offset {}) matches no "
                                                  "Attachment record",
                                                  ai.name, ai.offset));
  if (!attachment_indexes_.empty() && attachment_indexes_.size() != attachments_seen_.size())
    problem(footer_->summary_start,
            fmt::format("{} AttachmentIndex records for {} Attachment records",
                        attachment_indexes_.size(), attachments_seen_.size()));
}

// Summary offsets: each group is exactly a run of records with its opcode.
void Verifier::check_summary_offsets() {
  for (const auto& so : summary_offsets_) {
    std::uint64_t covered = 0;
    bool starts = false;
    for (const auto& [off, opc, len] : summary_records_) {
      if (off < so.group_start || off >= so.group_start + so.group_length) continue;
      if (off == so.group_start) starts = true;
      if (opc != so.group_opcode)
        problem(off, fmt::format("SummaryOffset group {} covers a {} record",
                                 opcode_name(so.group_opcode), opcode_name(opc)));
      covered += len;
    }
    if (!starts || covered != so.group_length)
      problem(so.group_start,
              fmt::format("SummaryOffset for {}: start {} length {} does not match "
                          "whole records",
                          opcode_name(so.group_opcode), so.group_start, so.group_length));
  }
}

VerifyReport Verifier::finish() && {
  if (suppressed_ > 0)
    rep_.problems.push_back(fmt::format("... and {} more problems", suppressed_));
  rep_.ok = rep_.problems.empty();
  return std::move(rep_);
}

}  // namespace

Json VerifyReport::to_json() const {
  return Json{{"ok", ok},
              {"problems", problems},
              {"chunks_checked", chunks_checked},
              {"messages_checked", messages_checked},
              {"crcs_checked", crcs_checked},
              {"has_summary", has_summary}};
}

Result<VerifyReport> verify(const std::filesystem::path& path) {
  Verifier v;
  HC_ASSIGN_OR_RETURN(const LinearScanResult scan,
                      scan_records(path, [&](const LinearRecord& r) { return v.on_record(r); }));
  v.check_scan_end(scan);
  v.check_message_indexes();
  v.check_footer();
  if (v.has_summary()) {
    v.check_summary_definitions();
    v.check_chunk_indexes();
    v.check_statistics();
    v.check_metadata_and_attachment_indexes();
  }
  v.check_summary_offsets();
  return std::move(v).finish();
}

}  // namespace hc::recording
