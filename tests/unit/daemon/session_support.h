// Reading sessions back for the daemon's tests: every message of a session file decoded per
// topic with R1's reader, plus an association check that is independent of the daemon's own.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/json.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/topics.h"

namespace hc::rig::testing {

struct Msg {
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  std::uint32_t sequence = 0;
  std::string topic;
  recording::Bytes data;
};

struct SessionContents {
  std::map<std::string, std::vector<Msg>> by_topic;
  std::map<std::string, recording::StringMap> metadata;  // last record of each name
  std::vector<Msg> all;                                  // in file order
};

inline SessionContents read_session(const std::filesystem::path& path) {
  SessionContents out;
  Result<recording::McapReader> reader = recording::McapReader::open(path);
  EXPECT_TRUE(reader.ok()) << reader.status().to_string();
  if (!reader.ok()) return out;
  recording::ReadOptions ro;
  ro.order = recording::ReadOrder::kFile;
  Status s = reader->read_messages(ro, [&](const recording::MessageEvent& e) {
    Msg m;
    m.log_time = e.message.log_time;
    m.publish_time = e.message.publish_time;
    m.sequence = e.message.sequence;
    m.topic = e.channel->topic;
    m.data.assign(e.message.data.begin(), e.message.data.end());
    out.by_topic[m.topic].push_back(m);
    out.all.push_back(std::move(m));
    return true;
  });
  EXPECT_TRUE(s.ok()) << s.to_string();
  Result<std::vector<recording::Metadata>> md = reader->read_metadata();
  EXPECT_TRUE(md.ok());
  if (md.ok())
    for (const recording::Metadata& m : *md) out.metadata[m.name] = m.metadata;
  return out;
}

inline Json json_of(const Msg& m) {
  Result<Json> j = recording::parse_json_message(m.data);
  EXPECT_TRUE(j.ok());
  return j.ok() ? *j : Json();
}

// Independent of the daemon's associator: from the recorded messages alone, every camera delivers
// one frame per rising edge, in order, within `max_latency_ns` after its edge; (hand-held) every
// FSR sample names an edge that exists, one per edge; (automated) every edge has an F/T sample
// within 1 ms (the bar for trigger-to-sample association error in simulation).
struct Check {
  std::size_t edges = 0;
  std::size_t frames = 0;
  std::int64_t max_ft_error_ns = 0;
};

inline Check check_association(const testing::SessionContents& c,
                               const std::vector<std::string>& cams, bool hand_held) {
  Check out;
  std::vector<std::pair<std::uint64_t, std::int64_t>> edges;  // index, host_ns
  for (const testing::Msg& m : c.by_topic.at("/trigger/edges")) {
    const Json j = json_of(m);
    if (!j["rising"].get<bool>()) continue;
    edges.emplace_back(j["index"].get<std::uint64_t>(), j["host_ns"].get<std::int64_t>());
    EXPECT_EQ(m.log_time, j["host_ns"].get<std::uint64_t>());  // log_time = host monotonic ns
  }
  out.edges = edges.size();
  for (const std::string& cam : cams) {
    const auto& frames = c.by_topic.at(session::camera_topic(cam));
    EXPECT_EQ(frames.size(), edges.size()) << cam;
    for (std::size_t k = 0; k < std::min(frames.size(), edges.size()); ++k) {
      const std::int64_t dt = static_cast<std::int64_t>(frames[k].log_time) - edges[k].second;
      // Exposure + readout of a 240-line Basler-like sensor: 240 x 20.52 us + 3.87 ms + exposure
      // (RIG_PROTOCOL_FACTS.md); 100 ms is far above it and far below the trigger period.
      EXPECT_GT(dt, 0) << cam << " frame " << k;
      EXPECT_LT(dt, 100'000'000) << cam << " frame " << k;
      ++out.frames;
    }
  }
  if (hand_held) {
    const auto& fsr = c.by_topic.at("/fsr/samples");
    EXPECT_EQ(fsr.size(), edges.size());
    for (std::size_t k = 0; k < std::min(fsr.size(), edges.size()); ++k)
      EXPECT_EQ(json_of(fsr[k])["trigger_index"].get<std::uint64_t>(), edges[k].first);
  } else {
    std::vector<std::int64_t> ft;
    for (const testing::Msg& m : c.by_topic.at("/ft/wrench"))
      ft.push_back(static_cast<std::int64_t>(m.log_time));
    std::sort(ft.begin(), ft.end());
    for (const auto& [index, t] : edges) {
      auto it = std::lower_bound(ft.begin(), ft.end(), t);
      std::int64_t best = INT64_MAX;
      if (it != ft.end()) best = std::min(best, *it - t);
      if (it != ft.begin()) best = std::min(best, t - *std::prev(it));
      out.max_ft_error_ns = std::max(out.max_ft_error_ns, best);
    }
    EXPECT_LT(out.max_ft_error_ns, 1'000'000);
  }
  // The daemon's own sync records agree: one per edge, all complete.
  const auto& sync = c.by_topic.at(std::string(session::kSyncTopic));
  EXPECT_EQ(sync.size(), edges.size());
  for (const testing::Msg& m : sync)
    EXPECT_TRUE(json_of(m)["complete"].get<bool>()) << json_of(m).dump();
  return out;
}

}  // namespace hc::rig::testing
