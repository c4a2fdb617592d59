// Reading sessions back for the daemon's tests: every message of a session file decoded per
// topic with R1's reader, plus an association check that is independent of the daemon's own.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/json.h"
#include "rig_daemon/daemon/session_layout.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"

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

}  // namespace hc::rig::testing
