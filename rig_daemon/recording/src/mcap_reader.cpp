// McapReader (see mcap_reader.h). Files are read with pread(2) at the offsets the summary gives, so
// a multi-gigabyte session is never loaded whole; every length is checked against what is left
// before a buffer is sized for it.
#include "rig_daemon/recording/mcap_reader.h"

#include <algorithm>
#include <queue>

#include <fmt/format.h>

#include "mcap_source.h"

namespace hc::recording {
namespace {

// A decompressed chunk kept alive while its messages are delivered.
struct LoadedChunk {
  Bytes records;
  std::uint64_t offset = 0;
};

}  // namespace

class McapReader::Impl {
 public:
  Impl(std::unique_ptr<Source> src, Options options) : src_(std::move(src)), opt_(options) {}

  Status open() {
    const std::uint64_t size = src_->size();
    if (size < kMagic.size() + kRecordPrefixSize)
      return invalid_argument(
          fmt::format("{}: {} bytes, too short for an MCAP file", src_->name(), size));
    Bytes buf;
    HC_RETURN_IF_ERROR(src_->read(0, kMagic.size() + kRecordPrefixSize, buf));
    if (!is_magic(buf))
      return invalid_argument(
          fmt::format("{}: offset 0: not an MCAP file (bad magic)", src_->name()));
    if (buf[8] != static_cast<std::uint8_t>(Opcode::kHeader))
      return invalid_argument(fmt::format("{}: offset 8: expected a Header record, found {}",
                                          src_->name(), opcode_name(buf[8])));
    const std::uint64_t hlen = read_u64(buf.data() + 9);
    if (hlen > size - 17 || hlen > opt_.max_record_size)
      return invalid_argument(
          fmt::format("{}: offset 8: Header length {} exceeds the file", src_->name(), hlen));
    Bytes hb;
    HC_RETURN_IF_ERROR(src_->read(17, hlen, hb));
    auto header = decode_header(hb);
    if (!header.ok()) return at_offset(*src_, 8, header.status());
    summary_.header = std::move(header).value();

    // Footer + closing magic.
    bool complete = false;
    Footer footer;
    if (size >= kMagic.size() + kRecordPrefixSize + hlen + kFooterAndMagicSize) {
      Bytes tail;
      HC_RETURN_IF_ERROR(src_->read(size - kFooterAndMagicSize, kFooterAndMagicSize, tail));
      if (is_magic(ByteSpan(tail).subspan(kFooterAndMagicSize - 8)) &&
          tail[0] == static_cast<std::uint8_t>(Opcode::kFooter) &&
          read_u64(tail.data() + 1) == kFooterContentSize) {
        auto f = decode_footer(ByteSpan(tail).subspan(kRecordPrefixSize, kFooterContentSize));
        if (!f.ok()) return at_offset(*src_, size - kFooterAndMagicSize, f.status());
        footer = f.value();
        complete = true;
      }
    }
    if (!complete && !opt_.allow_truncated)
      return invalid_argument(fmt::format(
          "{}: no Footer and closing magic at the end: the file is truncated or not a complete "
          "MCAP file (try `hardcopy session recover`)",
          src_->name()));
    footer_start_ = complete ? size - kFooterAndMagicSize : size;
    if (complete && footer.summary_start != 0) return read_summary(footer);
    return linear_summary();
  }

  Status read_summary(const Footer& footer) {
    const std::uint64_t end =
        footer.summary_offset_start != 0 ? footer.summary_offset_start : footer_start_;
    if (footer.summary_start < kMagic.size() || footer.summary_start > end || end > footer_start_)
      return invalid_argument(fmt::format(
          "{}: Footer: summary_start {} / summary_offset_start {} outside the file (footer at {})",
          src_->name(), footer.summary_start, footer.summary_offset_start, footer_start_));
    if (end - footer.summary_start > opt_.max_record_size)
      return invalid_argument(fmt::format("{}: summary section of {} bytes exceeds the limit",
                                          src_->name(), end - footer.summary_start));
    Bytes buf;
    HC_RETURN_IF_ERROR(src_->read(footer.summary_start, end - footer.summary_start, buf));
    std::uint64_t pos = 0;
    while (pos < buf.size()) {
      const std::uint64_t off = footer.summary_start + pos;
      auto rec = next_record(ByteSpan(buf).subspan(static_cast<std::size_t>(pos)), off);
      if (!rec.ok())
        return Status(rec.status().code(), src_->name() + ": " + rec.status().message());
      HC_RETURN_IF_ERROR(add_summary_record(rec->opcode, rec->content, off));
      pos += rec->size;
    }
    summary_.from_summary_section = true;
    return {};
  }

  Status add_summary_record(std::uint8_t opcode, ByteSpan content, std::uint64_t off) {
    auto wrap = [&](const Status& s) { return at_offset(*src_, off, s); };
    switch (static_cast<Opcode>(opcode)) {
      case Opcode::kSchema: {
        auto r = decode_schema(content);
        if (!r.ok()) return wrap(r.status());
        if (r->id == 0) return wrap(invalid_argument("Schema: id 0 is reserved"));
        summary_.schemas[r->id] = std::move(r).value();
        break;
      }
      case Opcode::kChannel: {
        auto r = decode_channel(content);
        if (!r.ok()) return wrap(r.status());
        summary_.channels[r->id] = std::move(r).value();
        break;
      }
      case Opcode::kStatistics: {
        auto r = decode_statistics(content);
        if (!r.ok()) return wrap(r.status());
        summary_.statistics = std::move(r).value();
        break;
      }
      case Opcode::kChunkIndex: {
        auto r = decode_chunk_index(content);
        if (!r.ok()) return wrap(r.status());
        if (r->chunk_start_offset > footer_start_ ||
            r->chunk_length > footer_start_ - r->chunk_start_offset)
          return wrap(invalid_argument(
              fmt::format("ChunkIndex: chunk at {} length {} outside the data section",
                          r->chunk_start_offset, r->chunk_length)));
        summary_.chunk_indexes.push_back(std::move(r).value());
        break;
      }
      case Opcode::kAttachmentIndex: {
        auto r = decode_attachment_index(content);
        if (!r.ok()) return wrap(r.status());
        summary_.attachment_indexes.push_back(std::move(r).value());
        break;
      }
      case Opcode::kMetadataIndex: {
        auto r = decode_metadata_index(content);
        if (!r.ok()) return wrap(r.status());
        summary_.metadata_indexes.push_back(std::move(r).value());
        break;
      }
      default:
        break;  // SummaryOffset and unknown records are skipped (the spec allows it).
    }
    return {};
  }

  // No usable summary: schemas, channels and chunk indexes from one pass over the data section.
  Status linear_summary() {
    Statistics stats;
    bool any_message = false;
    auto note_message = [&](const MessageView& m) {
      if (!any_message) {
        stats.message_start_time = stats.message_end_time = m.log_time;
        any_message = true;
      }
      stats.message_start_time = std::min(stats.message_start_time, m.log_time);
      stats.message_end_time = std::max(stats.message_end_time, m.log_time);
      ++stats.message_count;
      ++stats.channel_message_counts[m.channel_id];
    };
    bool in_summary = false;
    auto r = scan_source(
        *src_,
        [&](const LinearRecord& rec) -> Status {
          const auto op = static_cast<Opcode>(rec.opcode);
          if (op == Opcode::kDataEnd) in_summary = true;
          if (in_summary) return {};
          switch (op) {
            case Opcode::kSchema:
            case Opcode::kChannel:
              return add_summary_record(rec.opcode, rec.content, rec.offset);
            case Opcode::kMessage: {
              auto m = decode_message_view(rec.content);
              if (!m.ok()) return at_offset(*src_, rec.offset, m.status());
              note_message(*m);
              return {};
            }
            case Opcode::kChunk: {
              auto chunk = decode_chunk_view(rec.content);
              if (!chunk.ok()) return at_offset(*src_, rec.offset, chunk.status());
              ChunkIndex ci;
              ci.message_start_time = chunk->message_start_time;
              ci.message_end_time = chunk->message_end_time;
              ci.chunk_start_offset = rec.offset;
              ci.chunk_length = kRecordPrefixSize + rec.content.size();
              ci.compression = chunk->compression;
              ci.compressed_size = chunk->records.size();
              ci.uncompressed_size = chunk->uncompressed_size;
              HC_ASSIGN_OR_RETURN(Bytes records, decompress_checked(*chunk, rec.offset));
              HC_RETURN_IF_ERROR(for_each_inner(
                  records, rec.offset, [&](std::uint8_t opc, ByteSpan c, std::uint64_t) -> Status {
                    if (opc == static_cast<std::uint8_t>(Opcode::kSchema) ||
                        opc == static_cast<std::uint8_t>(Opcode::kChannel))
                      return add_summary_record(opc, c, rec.offset);
                    if (opc == static_cast<std::uint8_t>(Opcode::kMessage)) {
                      auto m = decode_message_view(c);
                      if (!m.ok()) return at_offset(*src_, rec.offset, m.status());
                      note_message(*m);
                    }
                    return {};
                  }));
              summary_.chunk_indexes.push_back(std::move(ci));
              ++stats.chunk_count;
              return {};
            }
            case Opcode::kMetadata:
              summary_.metadata_indexes.push_back(
                  {rec.offset, kRecordPrefixSize + rec.content.size(), ""});
              if (auto md = decode_metadata(rec.content); md.ok())
                summary_.metadata_indexes.back().name = md->name;
              ++stats.metadata_count;
              return {};
            case Opcode::kAttachment: {
              auto a = decode_attachment(rec.content);
              if (!a.ok()) return at_offset(*src_, rec.offset, a.status());
              summary_.attachment_indexes.push_back(
                  {rec.offset, kRecordPrefixSize + rec.content.size(), a->log_time, a->create_time,
                   a->data.size(), a->name, a->media_type});
              ++stats.attachment_count;
              return {};
            }
            default:
              return {};
          }
        },
        opt_.max_record_size);
    if (!r.ok()) return r.status();
    stats.schema_count = static_cast<std::uint16_t>(summary_.schemas.size());
    stats.channel_count = static_cast<std::uint32_t>(summary_.channels.size());
    summary_.statistics = stats;
    summary_.from_summary_section = false;
    return {};
  }

  Result<Bytes> decompress_checked(const ChunkView& chunk, std::uint64_t offset) const {
    auto records =
        decompress(chunk.compression, chunk.records, chunk.uncompressed_size, opt_.max_record_size);
    if (!records.ok()) return at_offset(*src_, offset, records.status().with_context("Chunk"));
    if (opt_.check_chunk_crc && chunk.uncompressed_crc != 0) {
      const std::uint32_t crc = crc32(*records);
      if (crc != chunk.uncompressed_crc)
        return at_offset(
            *src_, offset,
            invalid_argument(
                fmt::format("Chunk: uncompressed CRC mismatch (stored 0x{:08x}, computed 0x{:08x})",
                            chunk.uncompressed_crc, crc)));
    }
    return records;
  }

  // Calls fn(opcode, content, offset-in-records) for every record of a decompressed chunk.
  template <typename Fn>
  Status for_each_inner(const Bytes& records, std::uint64_t chunk_offset, Fn&& fn) const {
    std::uint64_t pos = 0;
    while (pos < records.size()) {
      auto rec = next_record(ByteSpan(records).subspan(static_cast<std::size_t>(pos)), pos);
      if (!rec.ok())
        return at_offset(*src_, chunk_offset, rec.status().with_context("inside Chunk"));
      HC_RETURN_IF_ERROR(fn(rec->opcode, rec->content, pos));
      pos += rec->size;
    }
    return {};
  }

  Result<LoadedChunk> load_chunk(const ChunkIndex& ci) const {
    if (ci.chunk_length < kRecordPrefixSize || ci.chunk_length > opt_.max_record_size ||
        ci.chunk_start_offset > src_->size() ||
        ci.chunk_length > src_->size() - ci.chunk_start_offset)
      return invalid_argument(fmt::format("{}: ChunkIndex: chunk at {} length {} outside the file",
                                          src_->name(), ci.chunk_start_offset, ci.chunk_length));
    Bytes buf;
    HC_RETURN_IF_ERROR(src_->read(ci.chunk_start_offset, ci.chunk_length, buf));
    auto rec = next_record(buf, ci.chunk_start_offset);
    if (!rec.ok()) return Status(rec.status().code(), src_->name() + ": " + rec.status().message());
    if (rec->opcode != static_cast<std::uint8_t>(Opcode::kChunk))
      return at_offset(*src_, ci.chunk_start_offset,
                       invalid_argument(fmt::format("ChunkIndex points at a {} record, not a Chunk",
                                                    opcode_name(rec->opcode))));
    auto chunk = decode_chunk_view(rec->content);
    if (!chunk.ok()) return at_offset(*src_, ci.chunk_start_offset, chunk.status());
    HC_ASSIGN_OR_RETURN(Bytes records, decompress_checked(*chunk, ci.chunk_start_offset));
    return LoadedChunk{std::move(records), ci.chunk_start_offset};
  }

  struct Filter {
    const ReadOptions* opt;
    std::vector<bool> wanted;  // by channel id; empty = all
    bool accepts(const MessageView& m) const {
      if (m.log_time < opt->start_time || m.log_time >= opt->end_time) return false;
      return wanted.empty() || (m.channel_id < wanted.size() && wanted[m.channel_id]);
    }
  };

  Result<Filter> make_filter(const ReadOptions& options,
                             const std::map<std::uint16_t, Channel>& channels) const {
    Filter f{&options, {}};
    if (options.topics.empty()) return f;
    f.wanted.assign(0x10000, false);
    for (const auto& topic : options.topics) {
      bool found = false;
      for (const auto& [id, ch] : channels)
        if (ch.topic == topic) {
          f.wanted[id] = true;
          found = true;
        }
      if (!found && summary_.from_summary_section)
        return not_found(fmt::format("{}: no channel with topic '{}'", src_->name(), topic));
    }
    return f;
  }

  Result<MessageEvent> make_event(const MessageView& m, std::uint64_t chunk_offset,
                                  const std::map<std::uint16_t, Channel>& channels,
                                  const std::map<std::uint16_t, Schema>& schemas,
                                  std::uint64_t err_offset) const {
    auto ch = channels.find(m.channel_id);
    if (ch == channels.end())
      return at_offset(
          *src_, err_offset,
          invalid_argument(fmt::format("Message on unknown channel id {}", m.channel_id)));
    MessageEvent ev;
    ev.channel = &ch->second;
    if (ch->second.schema_id != 0) {
      auto s = schemas.find(ch->second.schema_id);
      if (s == schemas.end())
        return at_offset(*src_, err_offset,
                         invalid_argument(fmt::format("Channel {} uses unknown schema id {}",
                                                      m.channel_id, ch->second.schema_id)));
      ev.schema = &s->second;
    }
    ev.message = m;
    ev.chunk_offset = chunk_offset;
    return ev;
  }

  Status read_indexed(const ReadOptions& options, const MessageCallback& cb) const {
    HC_ASSIGN_OR_RETURN(const Filter filter, make_filter(options, summary_.channels));
    std::vector<const ChunkIndex*> chunks;
    for (const auto& ci : summary_.chunk_indexes) {
      if (ci.message_end_time < options.start_time || ci.message_start_time >= options.end_time)
        continue;
      if (!filter.wanted.empty() && !ci.message_index_offsets.empty()) {
        bool any = false;
        for (const auto& [ch, off] : ci.message_index_offsets) any = any || filter.wanted[ch];
        if (!any) continue;
      }
      chunks.push_back(&ci);
    }
    if (options.order == ReadOrder::kFile) {
      std::sort(chunks.begin(), chunks.end(), [](const ChunkIndex* a, const ChunkIndex* b) {
        return a->chunk_start_offset < b->chunk_start_offset;
      });
      for (const ChunkIndex* ci : chunks) {
        HC_ASSIGN_OR_RETURN(const LoadedChunk chunk, load_chunk(*ci));
        bool stop = false;
        HC_RETURN_IF_ERROR(for_each_inner(
            chunk.records, chunk.offset, [&](std::uint8_t op, ByteSpan c, std::uint64_t) -> Status {
              if (stop || op != static_cast<std::uint8_t>(Opcode::kMessage)) return {};
              auto m = decode_message_view(c);
              if (!m.ok()) return at_offset(*src_, chunk.offset, m.status());
              if (!filter.accepts(*m)) return {};
              HC_ASSIGN_OR_RETURN(
                  const MessageEvent ev,
                  make_event(*m, chunk.offset, summary_.channels, summary_.schemas, chunk.offset));
              stop = !cb(ev);
              return {};
            }));
        if (stop) return {};
      }
      return {};
    }
    // Log-time order: merge chunks, loading each once the merge reaches its start time.
    std::stable_sort(chunks.begin(), chunks.end(), [](const ChunkIndex* a, const ChunkIndex* b) {
      if (a->message_start_time != b->message_start_time)
        return a->message_start_time < b->message_start_time;
      return a->chunk_start_offset < b->chunk_start_offset;
    });
    struct Item {
      std::uint64_t log_time;
      std::uint64_t chunk_offset;
      std::uint64_t pos;
      MessageView view;
      std::shared_ptr<LoadedChunk> chunk;
    };
    auto later = [](const Item& a, const Item& b) {
      if (a.log_time != b.log_time) return a.log_time > b.log_time;
      if (a.chunk_offset != b.chunk_offset) return a.chunk_offset > b.chunk_offset;
      return a.pos > b.pos;
    };
    std::priority_queue<Item, std::vector<Item>, decltype(later)> heap(later);
    std::size_t next = 0;
    while (true) {
      while (next < chunks.size() &&
             (heap.empty() || chunks[next]->message_start_time <= heap.top().log_time)) {
        HC_ASSIGN_OR_RETURN(LoadedChunk loaded, load_chunk(*chunks[next]));
        auto chunk = std::make_shared<LoadedChunk>(std::move(loaded));
        HC_RETURN_IF_ERROR(
            for_each_inner(chunk->records, chunk->offset,
                           [&](std::uint8_t op, ByteSpan c, std::uint64_t pos) -> Status {
                             if (op != static_cast<std::uint8_t>(Opcode::kMessage)) return {};
                             auto m = decode_message_view(c);
                             if (!m.ok()) return at_offset(*src_, chunk->offset, m.status());
                             if (filter.accepts(*m))
                               heap.push(Item{m->log_time, chunk->offset, pos, *m, chunk});
                             return {};
                           }));
        ++next;
      }
      if (heap.empty()) return {};
      Item it = heap.top();
      heap.pop();
      HC_ASSIGN_OR_RETURN(const MessageEvent ev,
                          make_event(it.view, it.chunk_offset, summary_.channels, summary_.schemas,
                                     it.chunk_offset));
      if (!cb(ev)) return {};
    }
  }

  Status read_linear(const ReadOptions& options, const MessageCallback& cb) const {
    // Channels and schemas as met in the file (a file without summary defines them inline).
    std::map<std::uint16_t, Channel> channels = summary_.channels;
    std::map<std::uint16_t, Schema> schemas = summary_.schemas;
    HC_ASSIGN_OR_RETURN(const Filter filter, make_filter(options, channels));
    struct Owned {
      Message msg;
      std::uint64_t chunk_offset;
    };
    std::vector<Owned> sorted;  // kLogTime: collected, then stably sorted
    bool stop = false;
    bool in_summary = false;
    auto handle = [&](std::uint8_t op, ByteSpan c, std::uint64_t chunk_offset,
                      std::uint64_t err_offset) -> Status {
      if (op == static_cast<std::uint8_t>(Opcode::kSchema)) {
        auto s = decode_schema(c);
        if (!s.ok()) return at_offset(*src_, err_offset, s.status());
        schemas[s->id] = std::move(s).value();
      } else if (op == static_cast<std::uint8_t>(Opcode::kChannel)) {
        auto ch = decode_channel(c);
        if (!ch.ok()) return at_offset(*src_, err_offset, ch.status());
        channels[ch->id] = std::move(ch).value();
      } else if (op == static_cast<std::uint8_t>(Opcode::kMessage) && !stop) {
        auto m = decode_message_view(c);
        if (!m.ok()) return at_offset(*src_, err_offset, m.status());
        if (!options.topics.empty()) {
          auto ch = channels.find(m->channel_id);
          if (ch == channels.end()) return {};
          if (std::find(options.topics.begin(), options.topics.end(), ch->second.topic) ==
              options.topics.end())
            return {};
        }
        if (m->log_time < options.start_time || m->log_time >= options.end_time) return {};
        if (options.order == ReadOrder::kLogTime) {
          HC_ASSIGN_OR_RETURN(const MessageEvent ev,
                              make_event(*m, chunk_offset, channels, schemas, err_offset));
          (void)ev;  // validates channel / schema now, while the offset is known
          Message owned{m->channel_id, m->sequence, m->log_time, m->publish_time,
                        Bytes(m->data.begin(), m->data.end())};
          sorted.push_back({std::move(owned), chunk_offset});
        } else {
          HC_ASSIGN_OR_RETURN(const MessageEvent ev,
                              make_event(*m, chunk_offset, channels, schemas, err_offset));
          stop = !cb(ev);
        }
      }
      return {};
    };
    (void)filter;
    auto r = scan_source(
        *src_,
        [&](const LinearRecord& rec) -> Status {
          if (stop || in_summary) return {};
          const auto op = static_cast<Opcode>(rec.opcode);
          if (op == Opcode::kDataEnd) {
            in_summary = true;
            return {};
          }
          if (op == Opcode::kChunk) {
            auto chunk = decode_chunk_view(rec.content);
            if (!chunk.ok()) return at_offset(*src_, rec.offset, chunk.status());
            HC_ASSIGN_OR_RETURN(const Bytes records, decompress_checked(*chunk, rec.offset));
            return for_each_inner(records, rec.offset,
                                  [&](std::uint8_t opc, ByteSpan c, std::uint64_t) {
                                    return handle(opc, c, rec.offset, rec.offset);
                                  });
          }
          return handle(rec.opcode, rec.content, 0, rec.offset);
        },
        opt_.max_record_size);
    if (!r.ok()) return r.status();
    if (options.order == ReadOrder::kLogTime) {
      std::stable_sort(sorted.begin(), sorted.end(), [](const Owned& a, const Owned& b) {
        return a.msg.log_time < b.msg.log_time;
      });
      for (const auto& o : sorted) {
        MessageView v{o.msg.channel_id, o.msg.sequence, o.msg.log_time, o.msg.publish_time,
                      o.msg.data};
        HC_ASSIGN_OR_RETURN(const MessageEvent ev,
                            make_event(v, o.chunk_offset, channels, schemas, 0));
        if (!cb(ev)) break;
      }
    }
    return {};
  }

  Status read_messages(const ReadOptions& options, const MessageCallback& cb) const {
    if (options.use_index && summary_.from_summary_section &&
        (!summary_.chunk_indexes.empty() ||
         (summary_.statistics && summary_.statistics->message_count == 0)))
      return read_indexed(options, cb);
    return read_linear(options, cb);
  }

  Result<std::map<std::uint16_t, std::uint64_t>> message_counts() const {
    if (summary_.statistics) {
      auto counts = summary_.statistics->channel_message_counts;
      for (const auto& [id, ch] : summary_.channels) counts.try_emplace(id, 0);
      return counts;
    }
    std::map<std::uint16_t, std::uint64_t> counts;
    for (const auto& [id, ch] : summary_.channels) counts[id] = 0;
    ReadOptions all;
    all.order = ReadOrder::kFile;
    HC_RETURN_IF_ERROR(read_messages(all, [&](const MessageEvent& e) {
      ++counts[e.message.channel_id];
      return true;
    }));
    return counts;
  }

  Result<std::vector<Metadata>> read_metadata() const {
    std::vector<Metadata> out;
    for (const auto& mi : summary_.metadata_indexes) {
      if (mi.length < kRecordPrefixSize || mi.length > opt_.max_record_size ||
          mi.offset > src_->size() || mi.length > src_->size() - mi.offset)
        return invalid_argument(
            fmt::format("{}: MetadataIndex '{}': record at {} length {} outside the file",
                        src_->name(), mi.name, mi.offset, mi.length));
      Bytes buf;
      HC_RETURN_IF_ERROR(src_->read(mi.offset, mi.length, buf));
      auto rec = next_record(buf, mi.offset);
      if (!rec.ok())
        return Status(rec.status().code(), src_->name() + ": " + rec.status().message());
      if (rec->opcode != static_cast<std::uint8_t>(Opcode::kMetadata))
        return at_offset(*src_, mi.offset,
                         invalid_argument(fmt::format("MetadataIndex points at a {} record",
                                                      opcode_name(rec->opcode))));
      auto md = decode_metadata(rec->content);
      if (!md.ok()) return at_offset(*src_, mi.offset, md.status());
      out.push_back(std::move(md).value());
    }
    return out;
  }

  Result<std::vector<MessageIndex>> read_message_indexes(const ChunkIndex& ci) const {
    std::vector<MessageIndex> out;
    if (ci.message_index_length == 0) return out;
    const std::uint64_t start = ci.chunk_start_offset + ci.chunk_length;
    if (start < ci.chunk_start_offset || start > src_->size() ||
        ci.message_index_length > src_->size() - start ||
        ci.message_index_length > opt_.max_record_size)
      return invalid_argument(
          fmt::format("{}: ChunkIndex: message indexes at {} length {} outside the file",
                      src_->name(), start, ci.message_index_length));
    Bytes buf;
    HC_RETURN_IF_ERROR(src_->read(start, ci.message_index_length, buf));
    std::uint64_t pos = 0;
    while (pos < buf.size()) {
      auto rec = next_record(ByteSpan(buf).subspan(static_cast<std::size_t>(pos)), start + pos);
      if (!rec.ok())
        return Status(rec.status().code(), src_->name() + ": " + rec.status().message());
      if (rec->opcode == static_cast<std::uint8_t>(Opcode::kMessageIndex)) {
        auto mi = decode_message_index(rec->content);
        if (!mi.ok()) return at_offset(*src_, start + pos, mi.status());
        out.push_back(std::move(mi).value());
      }
      pos += rec->size;
    }
    return out;
  }

  Result<Attachment> read_attachment(const AttachmentIndex& ai) const {
    if (ai.length < kRecordPrefixSize || ai.length > opt_.max_record_size ||
        ai.offset > src_->size() || ai.length > src_->size() - ai.offset)
      return invalid_argument(
          fmt::format("{}: AttachmentIndex '{}': record at {} length {} outside the file",
                      src_->name(), ai.name, ai.offset, ai.length));
    Bytes buf;
    HC_RETURN_IF_ERROR(src_->read(ai.offset, ai.length, buf));
    auto rec = next_record(buf, ai.offset);
    if (!rec.ok()) return Status(rec.status().code(), src_->name() + ": " + rec.status().message());
    if (rec->opcode != static_cast<std::uint8_t>(Opcode::kAttachment))
      return at_offset(*src_, ai.offset,
                       invalid_argument(fmt::format("AttachmentIndex points at a {} record",
                                                    opcode_name(rec->opcode))));
    auto a = decode_attachment(rec->content);
    if (!a.ok()) return at_offset(*src_, ai.offset, a.status());
    if (a->crc != 0) {
      const std::uint32_t crc = attachment_crc(*a);
      if (crc != a->crc)
        return at_offset(
            *src_, ai.offset,
            invalid_argument(fmt::format("Attachment '{}': CRC mismatch (stored 0x{:08x}, "
                                         "computed 0x{:08x})",
                                         a->name, a->crc, crc)));
    }
    return a;
  }

  const FileSummary& summary() const { return summary_; }
  std::uint64_t file_size() const { return src_->size(); }

 private:
  std::unique_ptr<Source> src_;
  Options opt_;
  FileSummary summary_;
  std::uint64_t footer_start_ = 0;
};

Result<McapReader> McapReader::open(const std::filesystem::path& path, const Options& options) {
  HC_ASSIGN_OR_RETURN(auto src, FileSource::open(path));
  auto impl = std::make_unique<Impl>(std::move(src), options);
  HC_RETURN_IF_ERROR(impl->open());
  return McapReader(std::move(impl));
}
Result<McapReader> McapReader::open(const std::filesystem::path& path) {
  return open(path, Options{});
}
Result<McapReader> McapReader::from_bytes(ByteSpan bytes, const Options& options) {
  auto impl = std::make_unique<Impl>(std::make_unique<MemorySource>(bytes), options);
  HC_RETURN_IF_ERROR(impl->open());
  return McapReader(std::move(impl));
}

McapReader::McapReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
McapReader::McapReader(McapReader&&) noexcept = default;
McapReader& McapReader::operator=(McapReader&&) noexcept = default;
McapReader::~McapReader() = default;

const FileSummary& McapReader::summary() const { return impl_->summary(); }
const Channel* McapReader::find_channel(std::string_view topic) const {
  for (const auto& [id, ch] : impl_->summary().channels)
    if (ch.topic == topic) return &ch;
  return nullptr;
}
std::uint64_t McapReader::file_size() const { return impl_->file_size(); }
Status McapReader::read_messages(const ReadOptions& filter, const MessageCallback& callback) const {
  return impl_->read_messages(filter, callback);
}
Result<std::map<std::uint16_t, std::uint64_t>> McapReader::message_counts() const {
  return impl_->message_counts();
}
Result<std::vector<Metadata>> McapReader::read_metadata() const { return impl_->read_metadata(); }
Result<std::vector<MessageIndex>> McapReader::read_message_indexes(const ChunkIndex& index) const {
  return impl_->read_message_indexes(index);
}
Result<Attachment> McapReader::read_attachment(const AttachmentIndex& index) const {
  return impl_->read_attachment(index);
}

Result<LinearScanResult> scan_records(const std::filesystem::path& path,
                                      const std::function<Status(const LinearRecord&)>& on_record,
                                      std::uint64_t max_record_size) {
  HC_ASSIGN_OR_RETURN(auto src, FileSource::open(path));
  return scan_source(*src, on_record, max_record_size);
}

}  // namespace hc::recording
