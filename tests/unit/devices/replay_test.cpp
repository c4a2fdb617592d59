// Replay backends: a session recorded from the simulated devices (laid out as the daemon's
// recorder does: one channel per device stream, metadata device/kind/backend) is served back
// through the same interfaces with the same content, paced by the clock; re-recording the replay
// reproduces the same messages.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>

#include "replay_support.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/replay/replay.h"
#include "rig_daemon/session/codec.h"
#include "sim_support.h"
#include "test_data.h"

namespace hc::devices {
namespace {

namespace rec = hc::recording;
using hc::testing::ScratchDir;
using testing::record_session;
using testing::Recorded;
using testing::Recorder;
using testing::SimRig;

struct Replayer {
  explicit Replayer(const std::filesystem::path& path, double speed = 1.0) {
    ReplaySession::Options o;
    o.speed = speed;
    auto s = ReplaySession::open(path, o);
    EXPECT_TRUE(s.ok()) << s.status().to_string();
    session = *s;
    clock = std::make_shared<SimulatedClock>(5'000'000'000);
    EXPECT_TRUE(register_replay_backends(registry, session).ok());
  }
  template <typename D>
  std::unique_ptr<D> make(const std::string& name, const std::string& yaml = "{}") {
    DeviceContext ctx;
    ctx.name = name;
    ctx.backend = "replay";
    ctx.clock = clock;
    auto d = registry.create<D>(ctx);
    EXPECT_TRUE(d.ok()) << d.status().to_string();
    Status s = configure_from_yaml(**d, yaml);
    EXPECT_TRUE(s.ok()) << s.to_string();
    EXPECT_TRUE((*d)->activate().ok());
    return std::move(d).value();
  }
  std::shared_ptr<ReplaySession> session;
  std::shared_ptr<SimulatedClock> clock;
  BackendRegistry registry;
};

TEST(Replay, ServesEveryRecordedStreamWithTheSameContent) {
  ScratchDir dir;
  const auto path = dir.path() / "s.mcap";
  const Recorded rec = record_session(path);
  ASSERT_FALSE(rec.frames.empty());
  Replayer rp(path);
  EXPECT_EQ(rp.session->streams().size(), 5u);
  auto trig = rp.make<Trigger>("trig");
  auto cam = rp.make<Camera>("cam0");
  auto fsr = rp.make<Fsr>("fsr");
  auto ft = rp.make<ForceTorque>("ft");
  EXPECT_EQ(cam->camera_info().width, 64u);
  std::vector<TriggerEdge> edges;
  std::vector<Frame> frames;
  std::vector<FsrSample> fs;
  std::vector<WrenchSample> ws;
  for (int i = 0; i < 200; ++i) {
    ASSERT_TRUE(trig->read(edges, std::chrono::milliseconds(10)).ok());
    ASSERT_TRUE(cam->read(frames, Duration(0)).ok());
    ASSERT_TRUE(fsr->read(fs, Duration(0)).ok());
    ASSERT_TRUE(ft->read(ws, Duration(0)).ok());
  }
  ASSERT_EQ(edges.size(), rec.edges.size());
  for (std::size_t i = 0; i < edges.size(); ++i) EXPECT_EQ(to_json(edges[i]), rec.edges[i]);
  ASSERT_EQ(fs.size(), rec.fsr.size());
  for (std::size_t i = 0; i < fs.size(); ++i) EXPECT_EQ(to_json(fs[i]), rec.fsr[i]);
  ASSERT_EQ(ws.size(), rec.wrench.size());
  for (std::size_t i = 0; i < ws.size(); ++i) EXPECT_EQ(to_json(ws[i]), rec.wrench[i]);
  ASSERT_EQ(frames.size(), rec.frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].pixels, rec.frames[i].pixels);
    EXPECT_EQ(frames[i].frame_id, rec.frames[i].frame_id);
    EXPECT_EQ(frames[i].host_ns, rec.frames[i].host_ns);
    EXPECT_EQ(frames[i].device_stamp_ns, rec.frames[i].device_stamp_ns);
  }
  // The F/T dropouts show again as sequence gaps.
  EXPECT_GT(ft->stats().lost, 0u);
  EXPECT_EQ(ft->stats().received, ws.size());
}

TEST(Replay, PacesItemsOnTheClockAtTheRequestedSpeed) {
  ScratchDir dir;
  const auto path = dir.path() / "s.mcap";
  const Recorded rec = record_session(path);
  Replayer rp(path, 10.0);
  auto ft = rp.make<ForceTorque>("ft");
  const std::int64_t t0 = rp.clock->now_ns();
  std::vector<WrenchSample> ws;
  // 10x: after 50 ms of clock time, 0.5 s of the recording is available (~500 samples, minus
  // dropouts), and nothing from after it.
  while (rp.clock->now_ns() < t0 + 50'000'000)
    ASSERT_TRUE(ft->read(ws, std::chrono::milliseconds(1)).ok());
  const std::int64_t recorded_now = rp.session->recorded_ns_at(rp.clock->now_ns());
  ASSERT_FALSE(ws.empty());
  EXPECT_LE(ws.back().host_ns, recorded_now);
  EXPECT_NEAR(static_cast<double>(recorded_now - rp.session->start_ns()), 0.5e9, 0.01e9);
  EXPECT_GT(ws.size(), 400u);
  EXPECT_LT(ws.size(), rec.wrench.size());
  // The arm reports the latest recorded state at the replay time; commands are refused.
  auto arm = rp.make<Arm>("arm");
  Result<ArmState> st = arm->read();
  ASSERT_TRUE(st.ok());
  EXPECT_LE(st->host_ns, recorded_now);
  ArmCommand cmd;
  cmd.type = ArmCommand::Type::kHome;
  EXPECT_EQ(arm->write(cmd).code(), StatusCode::kUnsupported);
  EXPECT_EQ(arm->state(), DeviceState::kActive);
}

TEST(Replay, ReRecordingAReplayReproducesTheMessages) {
  ScratchDir dir;
  const auto path = dir.path() / "s.mcap";
  (void)record_session(path);
  Replayer rp(path, 100.0);
  auto ft = rp.make<ForceTorque>("ft");
  auto fsr = rp.make<Fsr>("fsr");
  const auto again = dir.path() / "again.mcap";
  {
    Recorder r(again);
    const auto ch_fsr =
        r.json_channel("fsr", DeviceKind::kFsr, "/fsr/samples", session::fsr_sample_schema());
    const auto ch_ft = r.json_channel("ft", DeviceKind::kForceTorque, "/ft/wrench",
                                      session::wrench_sample_schema());
    // Until the replay clock passes the end of the recording (each read returns as soon as an
    // item is due, so this takes about one call per sample).
    while (rp.session->recorded_ns_at(rp.clock->now_ns()) <= rp.session->end_ns()) {
      std::vector<WrenchSample> ws;
      std::vector<FsrSample> fs;
      ASSERT_TRUE(ft->read(ws, std::chrono::milliseconds(1)).ok());
      ASSERT_TRUE(fsr->read(fs, Duration(0)).ok());
      for (auto& s : ws) r.json(ch_ft, s.host_ns, s.rdt_sequence, to_json(s));
      for (auto& s : fs)
        r.json(ch_fsr, s.host_ns, static_cast<std::uint32_t>(s.sequence), to_json(s));
    }
    r.close();
  }
  // Same (log_time, sequence, bytes) per topic in both files.
  auto messages = [](const std::filesystem::path& p, const std::string& topic) {
    std::vector<std::tuple<std::uint64_t, std::uint32_t, std::string>> out;
    auto reader = rec::McapReader::open(p);
    EXPECT_TRUE(reader.ok());
    rec::ReadOptions f;
    f.topics = {topic};
    EXPECT_TRUE(reader
                    ->read_messages(f,
                                    [&](const rec::MessageEvent& m) {
                                      out.emplace_back(m.message.log_time, m.message.sequence,
                                                       std::string(m.message.data.begin(),
                                                                   m.message.data.end()));
                                      return true;
                                    })
                    .ok());
    return out;
  };
  for (const std::string topic : {"/ft/wrench", "/fsr/samples"}) {
    const auto a = messages(path, topic);
    const auto b = messages(again, topic);
    ASSERT_FALSE(a.empty()) << topic;
    EXPECT_EQ(a.size(), b.size()) << topic;
    EXPECT_EQ(a, b) << topic;
  }
}

TEST(Replay, MissingStreamsAndSessionsAreErrors) {
  ScratchDir dir;
  EXPECT_FALSE(ReplaySession::open(dir.path() / "none.mcap").ok());
  const auto path = dir.path() / "s.mcap";
  (void)record_session(path);
  Replayer rp(path);
  DeviceContext ctx;
  ctx.name = "ft9";
  ctx.backend = "replay";
  ctx.clock = rp.clock;
  auto d = rp.registry.create<ForceTorque>(ctx);
  ASSERT_TRUE(d.ok());
  Status s = configure_from_yaml(**d, "{}");
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("ft9"), std::string::npos);
  EXPECT_TRUE(configure_from_yaml(**d, "{source: ft}").ok());  // serves another device's stream
  BackendRegistry none;
  EXPECT_EQ(register_replay_backends(none, nullptr).code(), StatusCode::kInvalidArgument);
  ReplaySession::Options bad;
  bad.speed = 0.0;
  EXPECT_EQ(ReplaySession::open(path, bad).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace hc::devices
