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

constexpr std::uint8_t op(Opcode o) { return static_cast<std::uint8_t>(o); }

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
  VerifyReport rep;
  constexpr std::size_t kMaxProblems = 200;
  std::uint64_t suppressed = 0;
  auto problem = [&](std::uint64_t off, const std::string& what) {
    if (rep.problems.size() < kMaxProblems)
      rep.problems.push_back(fmt::format("offset {}: {}", off, what));
    else
      ++suppressed;
  };

  std::vector<ChunkSeen> chunks;
  bool chunk_open = false;  // the last data record was a Chunk or one of its MessageIndexes
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::map<std::uint16_t, std::uint64_t> counts;
  std::uint64_t total = 0;
  std::uint64_t t_min = 0, t_max = 0;
  std::vector<MetadataIndex> metadata_seen;
  std::vector<AttachmentIndex> attachments_seen;

  bool header_seen = false;
  bool first = true;
  bool in_summary = false;
  std::uint64_t summary_first = 0;
  std::map<std::uint16_t, Schema> sum_schemas;
  std::map<std::uint16_t, Channel> sum_channels;
  std::optional<Statistics> stats;
  std::vector<ChunkIndex> chunk_indexes;
  std::vector<AttachmentIndex> attachment_indexes;
  std::vector<MetadataIndex> metadata_indexes;
  std::vector<SummaryOffset> summary_offsets;
  std::vector<std::tuple<std::uint64_t, std::uint8_t, std::uint64_t>> summary_records;
  std::optional<Footer> footer;
  std::uint64_t footer_offset = 0;
  std::uint32_t data_crc = crc32_update(kCrc32Init, kMagic);
  std::uint32_t summary_crc = kCrc32Init;
  bool data_end_seen = false;

  auto define_schema = [&](std::map<std::uint16_t, Schema>& into, ByteSpan c, std::uint64_t off) {
    auto s = decode_schema(c);
    if (!s.ok()) return problem(off, s.status().message());
    if (s->id == 0) return problem(off, "Schema with reserved id 0");
    auto it = into.find(s->id);
    if (it != into.end() && !(it->second == *s))
      return problem(off, fmt::format("Schema id {} redefined differently", s->id));
    into[s->id] = std::move(s).value();
  };
  auto define_channel = [&](std::map<std::uint16_t, Channel>& into, ByteSpan c, std::uint64_t off,
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
  };
  auto note_message = [&](const MessageView& m, std::uint64_t off) {
    if (channels.count(m.channel_id) == 0)
      problem(off, fmt::format("Message on channel id {} before any Channel record defines it",
                               m.channel_id));
    if (total == 0) t_min = t_max = m.log_time;
    t_min = std::min(t_min, m.log_time);
    t_max = std::max(t_max, m.log_time);
    ++total;
    ++counts[m.channel_id];
    ++rep.messages_checked;
  };

  auto scan = scan_records(path, [&](const LinearRecord& r) -> Status {
    const auto opc = static_cast<Opcode>(r.opcode);
    if (first) {
      first = false;
      if (opc != Opcode::kHeader)
        problem(r.offset,
                fmt::format("first record is {}, expected Header", opcode_name(r.opcode)));
      else if (auto h = decode_header(r.content); !h.ok())
        problem(r.offset, h.status().message());
      else
        header_seen = true;
    }
    if (opc == Opcode::kFooter) {
      auto f = decode_footer(r.content);
      if (!f.ok()) {
        problem(r.offset, f.status().message());
        return {};
      }
      footer = *f;
      footer_offset = r.offset;
      summary_crc = crc32_update(summary_crc, prefix_bytes(r.opcode, r.content.size()));
      summary_crc =
          crc32_update(summary_crc, r.content.first(std::min<std::size_t>(16, r.content.size())));
      return {};
    }
    if (!in_summary) {
      if (opc == Opcode::kDataEnd) {
        data_end_seen = true;
        auto de = decode_data_end(r.content);
        if (!de.ok()) {
          problem(r.offset, de.status().message());
        } else if (de->data_section_crc != 0) {
          ++rep.crcs_checked;
          const std::uint32_t computed = crc32_final(data_crc);
          if (computed != de->data_section_crc)
            problem(r.offset, fmt::format("DataEnd: data section CRC mismatch (stored 0x{:08x}, "
                                          "computed 0x{:08x})",
                                          de->data_section_crc, computed));
        }
        in_summary = true;
        summary_first = r.offset + kRecordPrefixSize + r.content.size();
        return {};
      }
      data_crc = crc_record(data_crc, r);
      if (opc != Opcode::kMessageIndex) chunk_open = false;
      switch (opc) {
        case Opcode::kHeader:
          if (r.offset != kMagic.size()) problem(r.offset, "second Header record");
          break;
        case Opcode::kSchema:
          define_schema(schemas, r.content, r.offset);
          break;
        case Opcode::kChannel:
          define_channel(channels, r.content, r.offset, schemas);
          break;
        case Opcode::kMessage: {
          auto m = decode_message_view(r.content);
          if (!m.ok())
            problem(r.offset, m.status().message());
          else
            note_message(*m, r.offset);
          break;
        }
        case Opcode::kChunk: {
          ++rep.chunks_checked;
          ChunkSeen cs;
          cs.offset = r.offset;
          cs.length = kRecordPrefixSize + r.content.size();
          auto cv = decode_chunk_view(r.content);
          if (!cv.ok()) {
            problem(r.offset, cv.status().message());
            chunks.push_back(std::move(cs));
            chunk_open = true;
            break;
          }
          cs.header = *cv;
          cs.header.records = {};
          cs.compressed_size = cv->records.size();
          auto records =
              decompress(cv->compression, cv->records, cv->uncompressed_size, 1ull << 34);
          if (!records.ok()) {
            problem(r.offset, "Chunk: " + records.status().message());
          } else {
            bool crc_ok = true;
            if (cv->uncompressed_crc != 0) {
              ++rep.crcs_checked;
              const std::uint32_t computed = crc32(*records);
              if (computed != cv->uncompressed_crc) {
                crc_ok = false;
                problem(r.offset, fmt::format("Chunk: uncompressed CRC mismatch (stored 0x{:08x}, "
                                              "computed 0x{:08x})",
                                              cv->uncompressed_crc, computed));
              }
            }
            std::uint64_t pos = 0;
            bool inner_ok = crc_ok;
            while (inner_ok && pos < records->size()) {
              auto rec =
                  next_record(ByteSpan(*records).subspan(static_cast<std::size_t>(pos)), pos);
              if (!rec.ok()) {
                problem(r.offset, "inside Chunk: " + rec.status().message());
                inner_ok = false;
                break;
              }
              if (rec->opcode == op(Opcode::kSchema)) {
                define_schema(schemas, rec->content, r.offset);
              } else if (rec->opcode == op(Opcode::kChannel)) {
                define_channel(channels, rec->content, r.offset, schemas);
              } else if (rec->opcode == op(Opcode::kMessage)) {
                auto m = decode_message_view(rec->content);
                if (!m.ok()) {
                  problem(r.offset,
                          "inside Chunk at " + std::to_string(pos) + ": " + m.status().message());
                } else {
                  note_message(*m, r.offset);
                  cs.messages[m->channel_id].emplace_back(m->log_time, pos);
                  if (m->log_time < cv->message_start_time || m->log_time > cv->message_end_time)
                    problem(r.offset,
                            fmt::format("Chunk: message at {} has log_time {} outside the "
                                        "chunk's [{}, {}]",
                                        pos, m->log_time, cv->message_start_time,
                                        cv->message_end_time));
                }
              } else {
                problem(r.offset, fmt::format("Chunk holds a {} record at {}",
                                              opcode_name(rec->opcode), pos));
              }
              pos += rec->size;
            }
            cs.decoded = inner_ok;
          }
          chunks.push_back(std::move(cs));
          chunk_open = true;
          break;
        }
        case Opcode::kMessageIndex: {
          auto mi = decode_message_index(r.content);
          if (!mi.ok()) {
            problem(r.offset, mi.status().message());
            break;
          }
          if (!chunk_open || chunks.empty()) {
            problem(r.offset, "MessageIndex not following a Chunk");
            break;
          }
          ChunkSeen& cs = chunks.back();
          if (cs.indexes.count(mi->channel_id) != 0)
            problem(r.offset,
                    fmt::format("second MessageIndex for channel {} after the chunk at {}",
                                mi->channel_id, cs.offset));
          cs.index_offsets[mi->channel_id] = r.offset;
          cs.index_length += kRecordPrefixSize + r.content.size();
          cs.indexes[mi->channel_id] = std::move(mi).value();
          break;
        }
        case Opcode::kMetadata: {
          auto md = decode_metadata(r.content);
          if (!md.ok()) {
            problem(r.offset, md.status().message());
            break;
          }
          metadata_seen.push_back({r.offset, kRecordPrefixSize + r.content.size(), md->name});
          break;
        }
        case Opcode::kAttachment: {
          auto a = decode_attachment(r.content);
          if (!a.ok()) {
            problem(r.offset, a.status().message());
            break;
          }
          if (a->crc != 0) {
            ++rep.crcs_checked;
            const std::uint32_t computed = attachment_crc(*a);
            if (computed != a->crc)
              problem(r.offset, fmt::format("Attachment '{}': CRC mismatch (stored 0x{:08x}, "
                                            "computed 0x{:08x})",
                                            a->name, a->crc, computed));
          }
          attachments_seen.push_back({r.offset, kRecordPrefixSize + r.content.size(), a->log_time,
                                      a->create_time, a->data.size(), a->name, a->media_type});
          break;
        }
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
      return {};
    }
    // Summary section (and summary offsets).
    summary_crc = crc_record(summary_crc, r);
    summary_records.emplace_back(r.offset, r.opcode, kRecordPrefixSize + r.content.size());
    auto bad = [&](const Status& s) { problem(r.offset, s.message()); };
    switch (opc) {
      case Opcode::kSchema:
        define_schema(sum_schemas, r.content, r.offset);
        break;
      case Opcode::kChannel:
        define_channel(sum_channels, r.content, r.offset, sum_schemas);
        break;
      case Opcode::kStatistics: {
        auto s = decode_statistics(r.content);
        if (!s.ok())
          bad(s.status());
        else if (stats)
          problem(r.offset, "second Statistics record");
        else
          stats = *s;
        break;
      }
      case Opcode::kChunkIndex: {
        auto s = decode_chunk_index(r.content);
        if (!s.ok())
          bad(s.status());
        else
          chunk_indexes.push_back(std::move(s).value());
        break;
      }
      case Opcode::kAttachmentIndex: {
        auto s = decode_attachment_index(r.content);
        if (!s.ok())
          bad(s.status());
        else
          attachment_indexes.push_back(std::move(s).value());
        break;
      }
      case Opcode::kMetadataIndex: {
        auto s = decode_metadata_index(r.content);
        if (!s.ok())
          bad(s.status());
        else
          metadata_indexes.push_back(std::move(s).value());
        break;
      }
      case Opcode::kSummaryOffset: {
        auto s = decode_summary_offset(r.content);
        if (!s.ok())
          bad(s.status());
        else
          summary_offsets.push_back(*s);
        break;
      }
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
    return {};
  });
  if (!scan.ok()) return scan.status();

  if (!header_seen && rep.problems.empty()) problem(kMagic.size(), "no Header record");
  if (!scan->reached_footer) problem(scan->end_offset, "file incomplete: " + scan->stop_reason);
  if (!data_end_seen && scan->reached_footer)
    problem(footer_offset, "no DataEnd record before the summary / Footer");

  // Message indexes against the messages of each chunk.
  for (const ChunkSeen& cs : chunks) {
    if (!cs.decoded) continue;
    if (cs.indexes.empty()) continue;  // message indexes are optional; all or nothing per chunk
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

  rep.has_summary = footer && footer->summary_start != 0;
  if (footer) {
    const std::uint64_t expect_start = summary_records.empty() ? 0 : summary_first;
    // The summary section is the records before the first SummaryOffset.
    std::uint64_t first_so = 0;
    for (const auto& [off, opc, len] : summary_records)
      if (opc == op(Opcode::kSummaryOffset)) {
        first_so = off;
        break;
      }
    const bool only_offsets = !summary_records.empty() &&
                              std::get<1>(summary_records.front()) == op(Opcode::kSummaryOffset);
    if (footer->summary_start != (only_offsets ? 0 : expect_start))
      problem(footer_offset, fmt::format("Footer: summary_start {} but the summary starts at {}",
                                         footer->summary_start, only_offsets ? 0 : expect_start));
    if (footer->summary_offset_start != first_so)
      problem(footer_offset,
              fmt::format("Footer: summary_offset_start {} but the first SummaryOffset is at {}",
                          footer->summary_offset_start, first_so));
    if (footer->summary_crc != 0) {
      ++rep.crcs_checked;
      const std::uint32_t computed = crc32_final(summary_crc);
      if (computed != footer->summary_crc)
        problem(footer_offset, fmt::format("Footer: summary CRC mismatch (stored 0x{:08x}, "
                                           "computed 0x{:08x})",
                                           footer->summary_crc, computed));
    }
  }

  if (rep.has_summary) {
    // Schemas and channels: every one met in the data section is repeated, identically.
    for (const auto& [id, s] : schemas) {
      auto it = sum_schemas.find(id);
      if (it == sum_schemas.end())
        problem(footer->summary_start, fmt::format("summary lacks Schema {} ('{}')", id, s.name));
      else if (!(it->second == s))
        problem(footer->summary_start,
                fmt::format("summary Schema {} differs from the data section's", id));
    }
    for (const auto& [id, c] : channels) {
      auto it = sum_channels.find(id);
      if (it == sum_channels.end())
        problem(footer->summary_start, fmt::format("summary lacks Channel {} ('{}')", id, c.topic));
      else if (!(it->second == c))
        problem(footer->summary_start,
                fmt::format("summary Channel {} differs from the data section's", id));
    }
    // Chunk indexes.
    std::map<std::uint64_t, const ChunkSeen*> by_offset;
    for (const auto& cs : chunks) by_offset[cs.offset] = &cs;
    std::set<std::uint64_t> indexed;
    if (!chunk_indexes.empty() || !chunks.empty()) {
      for (const auto& ci : chunk_indexes) {
        auto it = by_offset.find(ci.chunk_start_offset);
        if (it == by_offset.end()) {
          problem(footer->summary_start,
                  fmt::format("ChunkIndex points at offset {} where no Chunk starts",
                              ci.chunk_start_offset));
          continue;
        }
        if (!indexed.insert(ci.chunk_start_offset).second)
          problem(ci.chunk_start_offset, "Chunk indexed twice");
        const ChunkSeen& cs = *it->second;
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
          problem(cs.offset,
                  "ChunkIndex.message_index_offsets do not match the MessageIndex records");
      }
      if (!chunk_indexes.empty())
        for (const auto& cs : chunks)
          if (indexed.count(cs.offset) == 0)
            problem(cs.offset, "Chunk missing from the chunk indexes");
    }
    // Statistics.
    if (stats) {
      auto check = [&](const char* field, std::uint64_t stored, std::uint64_t actual) {
        if (stored != actual)
          problem(footer->summary_start,
                  fmt::format("Statistics.{} is {} but the file has {}", field, stored, actual));
      };
      check("message_count", stats->message_count, total);
      std::set<std::uint16_t> all_schemas, all_channels;
      for (const auto& [id, s] : sum_schemas) all_schemas.insert(id);
      for (const auto& [id, s] : schemas) all_schemas.insert(id);
      for (const auto& [id, c] : sum_channels) all_channels.insert(id);
      for (const auto& [id, c] : channels) all_channels.insert(id);
      check("schema_count", stats->schema_count, all_schemas.size());
      check("channel_count", stats->channel_count, all_channels.size());
      check("chunk_count", stats->chunk_count, chunks.size());
      check("metadata_count", stats->metadata_count, metadata_seen.size());
      check("attachment_count", stats->attachment_count, attachments_seen.size());
      if (total > 0) {
        check("message_start_time", stats->message_start_time, t_min);
        check("message_end_time", stats->message_end_time, t_max);
      }
      for (const auto& [ch, n] : counts) {
        auto it = stats->channel_message_counts.find(ch);
        check(fmt::format("channel_message_counts[{}]", ch).c_str(),
              it == stats->channel_message_counts.end() ? 0 : it->second, n);
      }
      for (const auto& [ch, n] : stats->channel_message_counts)
        if (counts.count(ch) == 0 && n != 0)
          check(fmt::format("channel_message_counts[{}]", ch).c_str(), n, 0);
    }
    // Metadata and attachment indexes.
    auto same_md = [](const MetadataIndex& a, const MetadataIndex& b) { return a == b; };
    for (const auto& mi : metadata_indexes)
      if (std::none_of(metadata_seen.begin(), metadata_seen.end(),
                       [&](const MetadataIndex& s) { return same_md(s, mi); }))
        problem(footer->summary_start,
                fmt::format("MetadataIndex '{}' (offset {}, length {}) matches no "
                            "Metadata record",
                            mi.name, mi.offset, mi.length));
    if (!metadata_indexes.empty() && metadata_indexes.size() != metadata_seen.size())
      problem(footer->summary_start, fmt::format("{} MetadataIndex records for {} Metadata records",
                                                 metadata_indexes.size(), metadata_seen.size()));
    for (const auto& ai : attachment_indexes)
      if (std::none_of(attachments_seen.begin(), attachments_seen.end(),
                       [&](const AttachmentIndex& s) { return s == ai; }))
        problem(footer->summary_start, fmt::format("AttachmentIndex '{}' (offset {}) matches no "
                                                   "Attachment record",
                                                   ai.name, ai.offset));
    if (!attachment_indexes.empty() && attachment_indexes.size() != attachments_seen.size())
      problem(footer->summary_start,
              fmt::format("{} AttachmentIndex records for {} Attachment records",
                          attachment_indexes.size(), attachments_seen.size()));
  }
  // Summary offsets: each group is exactly a run of records with its opcode.
  for (const auto& so : summary_offsets) {
    std::uint64_t covered = 0;
    bool starts = false;
    for (const auto& [off, opc, len] : summary_records) {
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
  if (suppressed > 0) rep.problems.push_back(fmt::format("... and {} more problems", suppressed));
  rep.ok = rep.problems.empty();
  return rep;
}

}  // namespace hc::recording
