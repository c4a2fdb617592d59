// recover (see mcap_tools.h): two linear passes over a damaged session. The first learns every
// Schema and Channel definition the file still holds, wherever it is (top level, inside any chunk
// that checks, the summary section); the second copies every chunk that checks, so a message
// whose own chunk lost its definitions (a corrupt first chunk) is kept when the definition
// survives elsewhere.
#include <algorithm>
#include <array>
#include <cstdio>
#include <map>
#include <vector>

#include <fmt/format.h>

#include "rig_daemon/recording/mcap_tools.h"

#include "common/file_io.h"

namespace hc::recording {
namespace {

constexpr std::uint64_t kMaxHeaderBytes = std::uint64_t{1} << 20;

// The records of a chunk whose CRC, decompression and record framing all check; false (and
// nothing in `records`) otherwise. The views point into `data`.
bool chunk_records(ByteSpan content, std::uint64_t max_chunk_bytes, Bytes& data,
                   std::vector<RecordView>& records) {
  records.clear();
  auto cv = decode_chunk_view(content);
  if (!cv.ok()) return false;
  auto decompressed =
      decompress(cv->compression, cv->records, cv->uncompressed_size, max_chunk_bytes);
  if (!decompressed.ok() ||
      (cv->uncompressed_crc != 0 && crc32(*decompressed) != cv->uncompressed_crc))
    return false;
  data = std::move(decompressed).value();
  std::uint64_t pos = 0;
  while (pos < data.size()) {
    auto rec = next_record(ByteSpan(data).subspan(static_cast<std::size_t>(pos)), pos);
    if (!rec.ok()) break;
    if (rec->opcode == opcode_byte(Opcode::kMessage) && !decode_message_view(rec->content).ok())
      break;
    records.push_back(*rec);
    pos += rec->size;
  }
  if (pos == data.size()) return true;
  records.clear();
  return false;
}

// Every definition in the file (the first valid one of each id wins).
struct Definitions {
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  void learn(std::uint8_t opcode, ByteSpan content) {
    if (opcode == opcode_byte(Opcode::kSchema)) {
      auto s = decode_schema(content);
      if (s.ok() && s->id != 0) schemas.try_emplace(s->id, std::move(s).value());
    } else if (opcode == opcode_byte(Opcode::kChannel)) {
      auto c = decode_channel(content);
      if (c.ok()) channels.try_emplace(c->id, std::move(c).value());
    }
  }
};

// The bytes after the magic must start with a Header record (MCAP spec: "the first record after
// the leading magic"); a file cut inside the Header is a crash at creation and recovers to an empty
// session.
Status check_mcap_start(const std::filesystem::path& input) {
  std::FILE* f = std::fopen(input.c_str(), "rb");
  if (f == nullptr) return not_found(fmt::format("recover: cannot open {}", input.string()));
  std::array<std::uint8_t, 17> start{};  // magic, opcode, length
  const std::size_t n = std::fread(start.data(), 1, start.size(), f);
  std::fclose(f);
  if (n < kMagic.size() || !std::equal(kMagic.begin(), kMagic.end(), start.begin()))
    return invalid_argument(
        fmt::format("recover: {}: offset 0: not an MCAP file (bad magic)", input.string()));
  if (n > kMagic.size() && start[8] != opcode_byte(Opcode::kHeader))
    return invalid_argument(fmt::format(
        "recover: {}: offset 8: not an MCAP file (the first record is opcode 0x{:02x}, not a "
        "Header)",
        input.string(), start[8]));
  if (n == start.size()) {
    std::uint64_t length = 0;
    for (int i = 0; i < 8; ++i) length |= std::uint64_t{start[9 + i]} << (8 * i);
    // A Header holds two short strings (profile, library); megabytes of it are not a Header.
    if (length > kMaxHeaderBytes)
      return invalid_argument(
          fmt::format("recover: {}: offset 8: not an MCAP file (a Header record of {} bytes)",
                      input.string(), length));
  }
  return {};
}

Result<Definitions> collect_definitions(const std::filesystem::path& input,
                                        std::uint64_t max_chunk_bytes) {
  Definitions defs;
  bool first = true;
  Bytes data;
  std::vector<RecordView> inner;
  Result<LinearScanResult> scan = scan_records(input, [&](const LinearRecord& r) -> Status {
    if (first) {
      first = false;
      if (r.opcode != opcode_byte(Opcode::kHeader) || !decode_header(r.content).ok())
        return invalid_argument(fmt::format(
            "recover: {}: offset {}: not an MCAP file (its Header record does not decode)",
            input.string(), r.offset));
    }
    if (r.opcode == opcode_byte(Opcode::kChunk)) {
      if (chunk_records(r.content, max_chunk_bytes, data, inner))
        for (const RecordView& rec : inner) defs.learn(rec.opcode, rec.content);
      return {};
    }
    defs.learn(r.opcode, r.content);
    return {};
  });
  if (!scan.ok()) return scan.status();
  return defs;
}

}  // namespace

Json RecoverReport::to_json() const {
  return Json{{"chunks_kept", chunks_kept},
              {"chunks_dropped", chunks_dropped},
              {"messages_kept", messages_kept},
              {"messages_dropped", messages_dropped},
              {"metadata_kept", metadata_kept},
              {"attachments_kept", attachments_kept},
              {"definitions_found", definitions_found},
              {"input_bytes_used", input_bytes_used},
              {"input_was_complete", input_was_complete},
              {"stop_reason", stop_reason}};
}

Result<RecoverReport> recover(const std::filesystem::path& input,
                              const std::filesystem::path& output,
                              const McapWriter::Options& options, std::uint64_t max_chunk_bytes) {
  std::error_code ec;
  if (std::filesystem::exists(output, ec) && std::filesystem::equivalent(input, output, ec))
    return invalid_argument(fmt::format("recover: output {} is the input file", output.string()));
  HC_RETURN_IF_ERROR(options.validate());
  // Check the input is MCAP before creating anything.
  HC_RETURN_IF_ERROR(check_mcap_start(input));
  HC_ASSIGN_OR_RETURN(Definitions defs, collect_definitions(input, max_chunk_bytes));

  remove_stale_temporaries(output.parent_path());
  const std::filesystem::path tmp = temp_path_for(output);
  McapWriter::Options opt = options;
  opt.exclusive = false;
  std::unique_ptr<McapWriter> writer;
  RecoverReport rep;
  rep.definitions_found = defs.channels.size();
  std::map<std::uint16_t, bool> schema_ok;   // registered with the writer (or refused)
  std::map<std::uint16_t, bool> channel_ok;  // registered with the writer (or refused)

  // Registers a channel (and its schema) the first time it is needed; false when its definition
  // (or its schema's) is nowhere in the file.
  auto have_channel = [&](std::uint16_t id) -> Result<bool> {
    if (auto it = channel_ok.find(id); it != channel_ok.end()) return it->second;
    bool ok = false;
    if (auto ch = defs.channels.find(id); ch != defs.channels.end()) {
      const std::uint16_t sid = ch->second.schema_id;
      if (sid != 0 && schema_ok.count(sid) == 0) {
        auto s = defs.schemas.find(sid);
        schema_ok[sid] = s != defs.schemas.end() && writer->add_schema(s->second).ok();
      }
      // A channel whose topic another id already took keeps the first (add_channel refuses).
      ok = (sid == 0 || schema_ok[sid]) && writer->add_channel(ch->second).ok();
    }
    channel_ok[id] = ok;
    return ok;
  };
  auto write_message = [&](ByteSpan c) -> Status {
    auto m = decode_message_view(c);
    if (!m.ok()) return {};
    HC_ASSIGN_OR_RETURN(bool known, have_channel(m->channel_id));
    if (!known) {
      ++rep.messages_dropped;
      return {};
    }
    HC_RETURN_IF_ERROR(
        writer->write_message(m->channel_id, m->log_time, m->publish_time, m->data, m->sequence));
    ++rep.messages_kept;
    return {};
  };

  Bytes data;
  std::vector<RecordView> inner;
  bool header_done = false;
  bool in_summary = false;
  Result<LinearScanResult> scan = scan_records(input, [&](const LinearRecord& r) -> Status {
    const auto opc = static_cast<Opcode>(r.opcode);
    if (!header_done) {
      header_done = true;
      if (auto h = decode_header(r.content); h.ok()) opt.profile = h->profile;
      HC_ASSIGN_OR_RETURN(writer, McapWriter::open(tmp, opt));
      return {};
    }
    if (opc == Opcode::kDataEnd) in_summary = true;
    if (in_summary) return {};  // its definitions were learnt in the first pass
    switch (opc) {
      case Opcode::kMessage:
        return write_message(r.content);
      case Opcode::kChunk: {
        if (!chunk_records(r.content, max_chunk_bytes, data, inner)) {
          ++rep.chunks_dropped;
          return {};
        }
        for (const RecordView& rec : inner)
          if (rec.opcode == opcode_byte(Opcode::kMessage))
            HC_RETURN_IF_ERROR(write_message(rec.content));
        ++rep.chunks_kept;
        return {};
      }
      case Opcode::kMetadata: {
        auto md = decode_metadata(r.content);
        if (!md.ok()) return {};
        HC_RETURN_IF_ERROR(writer->write_metadata(md->name, md->metadata));
        ++rep.metadata_kept;
        return {};
      }
      case Opcode::kAttachment: {
        auto a = decode_attachment(r.content);
        if (!a.ok() || (a->crc != 0 && attachment_crc(*a) != a->crc)) return {};
        HC_RETURN_IF_ERROR(
            writer->write_attachment(a->name, a->media_type, a->log_time, a->create_time, a->data));
        ++rep.attachments_kept;
        return {};
      }
      default:
        return {};
    }
  });
  auto cleanup = [&] {
    writer.reset();
    std::filesystem::remove(tmp, ec);
  };
  if (!scan.ok()) {
    if (writer) (void)writer->close();
    cleanup();
    return scan.status();
  }
  if (!writer) {  // the input held only its magic (or part of its Header)
    HC_ASSIGN_OR_RETURN(writer, McapWriter::open(tmp, opt));
  }
  // Definitions of channels that never had a message stay in the summary.
  for (const auto& [id, ch] : defs.channels) {
    Result<bool> known = have_channel(id);
    if (!known.ok()) {
      cleanup();
      return known.status();
    }
  }
  if (scan->truncated && scan->truncated_opcode == opcode_byte(Opcode::kChunk))
    ++rep.chunks_dropped;
  rep.input_bytes_used = scan->end_offset;
  rep.input_was_complete = scan->reached_footer;
  rep.stop_reason = scan->stop_reason;
  auto closed = writer->close();
  if (!closed.ok()) {
    cleanup();
    return closed.status();
  }
  writer.reset();
  std::filesystem::rename(tmp, output, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    return io_error(fmt::format("recover: cannot rename {} to {}: {}", tmp.string(),
                                output.string(), ec.message()));
  }
  return rep;
}

}  // namespace hc::recording
