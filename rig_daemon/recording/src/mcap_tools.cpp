// session_info (see mcap_tools.h; verify is in mcap_verify.cpp, recover in mcap_recover.cpp).
#include "rig_daemon/recording/mcap_tools.h"

#include <algorithm>

#include "rig_daemon/recording/session_conventions.h"

namespace hc::recording {

Json SessionInfo::to_json() const {
  Json chans = Json::array();
  for (const auto& c : channels) {
    chans.push_back(Json{{"id", c.id},
                         {"topic", c.topic},
                         {"message_encoding", c.message_encoding},
                         {"schema_name", c.schema_name},
                         {"schema_encoding", c.schema_encoding},
                         {"message_count", c.message_count},
                         {"first_log_time_ns", c.first_log_time},
                         {"last_log_time_ns", c.last_log_time},
                         {"rate_hz", finite_or_null(c.rate_hz)},
                         {"metadata", c.metadata}});
  }
  Json devs = Json::array();
  for (const auto& d : device_stats)
    devs.push_back(Json{{"device", d.device},
                        {"received", d.received},
                        {"lost", d.lost},
                        {"late", d.late},
                        {"incomplete", d.incomplete}});
  return Json{{"path", path},
              {"file_size", file_size},
              {"profile", header.profile},
              {"library", header.library},
              {"has_summary", has_summary},
              {"message_count", message_count},
              {"chunk_count", chunk_count},
              {"start_time_ns", start_time},
              {"end_time_ns", end_time},
              {"duration_s", finite_or_null(duration_s)},
              {"compression_chunks", compression_chunks},
              {"compressed_bytes", compressed_bytes},
              {"uncompressed_bytes", uncompressed_bytes},
              {"channels", chans},
              {"metadata", metadata_names},
              {"attachments", attachment_names},
              {"device_stats", devs},
              {"session_state", session_state},
              {"session_reason", session_reason}};
}

Result<SessionInfo> session_info(const std::filesystem::path& path) {
  McapReader::Options ro;
  ro.allow_truncated = true;
  HC_ASSIGN_OR_RETURN(McapReader reader, McapReader::open(path, ro));
  const FileSummary& sum = reader.summary();
  SessionInfo info;
  info.path = path.string();
  info.file_size = reader.file_size();
  info.header = sum.header;
  info.has_summary = sum.from_summary_section;
  info.chunk_count = sum.chunk_indexes.size();
  for (const auto& ci : sum.chunk_indexes) {
    ++info.compression_chunks[ci.compression.empty() ? "none" : ci.compression];
    info.compressed_bytes += ci.compressed_size;
    info.uncompressed_bytes += ci.uncompressed_size;
  }
  // Per-channel count and first / last log time.
  struct Acc {
    std::uint64_t n = 0, first = 0, last = 0;
    void add(std::uint64_t t, std::uint64_t k = 1) {
      if (n == 0) first = last = t;
      first = std::min(first, t);
      last = std::max(last, t);
      n += k;
    }
  };
  std::map<std::uint16_t, Acc> acc;
  bool have_indexes = sum.from_summary_section && !sum.chunk_indexes.empty();
  for (const auto& ci : sum.chunk_indexes)
    if (ci.message_index_offsets.empty() && ci.uncompressed_size > 0) have_indexes = false;
  if (have_indexes) {
    for (const auto& ci : sum.chunk_indexes) {
      HC_ASSIGN_OR_RETURN(const auto indexes, reader.read_message_indexes(ci));
      for (const auto& mi : indexes)
        for (const auto& [t, off] : mi.records) acc[mi.channel_id].add(t);
    }
  } else {
    ReadOptions all;
    all.order = ReadOrder::kFile;
    HC_RETURN_IF_ERROR(reader.read_messages(all, [&](const MessageEvent& e) {
      acc[e.message.channel_id].add(e.message.log_time);
      return true;
    }));
  }
  Acc total;
  for (const auto& [id, ch] : sum.channels) {
    ChannelInfo c;
    c.id = id;
    c.topic = ch.topic;
    c.message_encoding = ch.message_encoding;
    if (auto s = sum.schemas.find(ch.schema_id); s != sum.schemas.end()) {
      c.schema_name = s->second.name;
      c.schema_encoding = s->second.encoding;
    }
    c.metadata = ch.metadata;
    if (auto a = acc.find(id); a != acc.end()) {
      c.message_count = a->second.n;
      c.first_log_time = a->second.first;
      c.last_log_time = a->second.last;
      if (a->second.n >= 2 && a->second.last > a->second.first)
        c.rate_hz = static_cast<double>(a->second.n - 1) /
                    (static_cast<double>(a->second.last - a->second.first) * 1e-9);
      total.add(a->second.first, a->second.n);
      total.add(a->second.last, 0);
    }
    info.channels.push_back(std::move(c));
  }
  info.message_count = total.n;
  info.start_time = total.first;
  info.end_time = total.last;
  info.duration_s = static_cast<double>(total.last - total.first) * 1e-9;
  for (const auto& mi : sum.metadata_indexes) info.metadata_names.push_back(mi.name);
  for (const auto& ai : sum.attachment_indexes) info.attachment_names.push_back(ai.name);
  // Device statistics: the last "device_stats" Metadata record.
  HC_ASSIGN_OR_RETURN(const auto metadata, reader.read_metadata());
  const Metadata* stats = nullptr;
  for (const auto& md : metadata) {
    if (md.name == kMetadataDeviceStats) stats = &md;
    if (md.name == kMetadataSessionEnd) {
      auto st = md.metadata.find("state");
      auto re = md.metadata.find("reason");
      info.session_state = st == md.metadata.end() ? "" : st->second;
      info.session_reason = re == md.metadata.end() ? "" : re->second;
    }
  }
  if (stats != nullptr) {
    std::map<std::string, DeviceStats> devs;
    for (const auto& [key, value] : stats->metadata) {
      const auto dot = key.rfind('.');
      if (dot == std::string::npos || dot == 0) continue;
      const std::string dev = key.substr(0, dot);
      const std::string field = key.substr(dot + 1);
      std::uint64_t v = 0;
      try {
        v = std::stoull(value);
      } catch (const std::exception&) {
        continue;  // not a count: ignored
      }
      DeviceStats& d = devs[dev];
      d.device = dev;
      if (field == "received")
        d.received = v;
      else if (field == "lost")
        d.lost = v;
      else if (field == "late")
        d.late = v;
      else if (field == "incomplete")
        d.incomplete = v;
    }
    for (auto& [name, d] : devs) info.device_stats.push_back(d);
  }
  return info;
}

}  // namespace hc::recording
