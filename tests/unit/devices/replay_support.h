// Recording a simulated capture the way the daemon's recorder lays out a session
// (rig_daemon/session/topics.h), for the replay tests.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "sim_support.h"

namespace hc::devices::testing {

namespace rec = hc::recording;

inline rec::Bytes bytes(const std::string& s) { return rec::Bytes(s.begin(), s.end()); }

// A minimal recorder with the daemon's layout (rig_daemon/session/topics.h).
class Recorder {
 public:
  explicit Recorder(const std::filesystem::path& path) {
    rec::McapWriter::Options o;
    o.chunk_size = 256 << 10;
    auto w = rec::McapWriter::open(path, o);
    EXPECT_TRUE(w.ok()) << w.status().to_string();
    writer_ = std::move(w).value();
  }
  std::uint16_t json_channel(const std::string& device, DeviceKind kind, const std::string& topic,
                             const session::MessageSchema& schema) {
    auto sid = writer_->add_schema(schema.name, rec::kJsonSchemaEncoding,
                                   bytes(std::string(schema.json_schema)));
    EXPECT_TRUE(sid.ok());
    return channel(device, kind, topic, rec::kJsonEncoding, *sid);
  }
  std::uint16_t image_channel(const std::string& device) {
    if (!image_schema_) {
      auto sid = writer_->add_schema(rec::kRawImageSchemaName, rec::kProtobufEncoding,
                                     rec::raw_image_schema());
      EXPECT_TRUE(sid.ok());
      image_schema_ = *sid;
    }
    return channel(device, DeviceKind::kCamera, "/" + device + "/image", rec::kProtobufEncoding,
                   image_schema_);
  }
  void json(std::uint16_t ch, std::int64_t log, std::uint32_t seq, const std::string& text) {
    ASSERT_TRUE(writer_->write_message(ch, log, log, bytes(text), seq).ok());
  }
  void frame(std::uint16_t ch, const std::string& device, const Frame& f) {
    rec::Bytes out;
    const std::int64_t stamp = f.device_stamp_ns.value_or(f.host_ns);
    rec::encode_raw_image_view(stamp, device, f.width, f.height, "mono8", f.stride_bytes, f.pixels,
                               out);
    ASSERT_TRUE(
        writer_->write_message(ch, f.host_ns, stamp, out, static_cast<std::uint32_t>(f.frame_id))
            .ok());
  }
  void close() { ASSERT_TRUE(writer_->close().ok()); }

 private:
  std::uint16_t channel(const std::string& device, DeviceKind kind, const std::string& topic,
                        std::string_view encoding, std::uint16_t schema) {
    auto id = writer_->add_channel(
        topic, encoding, schema,
        {{"device", device}, {"kind", std::string(to_string(kind))}, {"backend", "sim"}});
    EXPECT_TRUE(id.ok());
    return *id;
  }
  std::unique_ptr<rec::McapWriter> writer_;
  std::uint16_t image_schema_ = 0;
};

struct Recorded {
  std::vector<std::string> edges, fsr, wrench, arm;
  std::vector<Frame> frames;
};

// 1 s of a simulated capture: a 15 Hz trigger, a triggered camera and FSR, F/T at 1 kHz, the arm
// pressing, with a few F/T dropouts.
inline Recorded record_session(const std::filesystem::path& path, bool dropouts = true) {
  SimRig rig(5);
  Recorder r(path);
  auto trig = rig.make<Trigger>("trig", "{lines: [0]}");
  auto cam = rig.make<Camera>("cam0", "{trigger: hardware, width: 64, height: 48, fx: 80}");
  auto fsr = rig.make<Fsr>("fsr", "{sampling: triggered}");
  auto ft = rig.make<ForceTorque>("ft", "{rate_hz: 1000}");
  auto arm = rig.make<Arm>("arm");
  for (Device* d :
       std::initializer_list<Device*>{trig.get(), cam.get(), fsr.get(), ft.get(), arm.get()})
    EXPECT_TRUE(d->activate().ok());
  const auto ch_edges =
      r.json_channel("trig", DeviceKind::kTrigger, "/trig/edges", session::trigger_edge_schema());
  const auto ch_cam = r.image_channel("cam0");
  const auto ch_fsr =
      r.json_channel("fsr", DeviceKind::kFsr, "/fsr/samples", session::fsr_sample_schema());
  const auto ch_ft =
      r.json_channel("ft", DeviceKind::kForceTorque, "/ft/wrench", session::wrench_sample_schema());
  const auto ch_arm =
      r.json_channel("arm", DeviceKind::kArm, "/arm/state", session::arm_state_schema());
  const std::int64_t t0 = rig.clock->now_ns();
  if (dropouts) {
    rig.world->inject(
        {sim::Fault::Kind::kDropout, "ft", t0 + 100'000'000, t0 + 200'000'000, 0.3, 0.0});
  }
  ArmCommand home;
  home.type = ArmCommand::Type::kHome;
  EXPECT_TRUE(arm->write(home).ok());
  PulseTrain train;
  train.rate_hz = 15.0;
  EXPECT_TRUE(trig->start(train).ok());
  Recorded out;
  while (rig.clock->now_ns() < t0 + 1'000'000'000) {
    rig.clock->advance_ns(20'000'000);
    std::vector<TriggerEdge> edges;
    std::vector<Frame> frames;
    std::vector<FsrSample> fs;
    std::vector<WrenchSample> ws;
    EXPECT_TRUE(trig->read(edges, Duration(0)).ok());
    EXPECT_TRUE(cam->read(frames, Duration(0)).ok());
    EXPECT_TRUE(fsr->read(fs, Duration(0)).ok());
    EXPECT_TRUE(ft->read(ws, Duration(0)).ok());
    Result<ArmState> st = arm->read();
    EXPECT_TRUE(st.ok());
    for (auto& e : edges) {
      r.json(ch_edges, e.host_ns, static_cast<std::uint32_t>(e.device_counter), to_json(e));
      out.edges.push_back(to_json(e));
    }
    for (auto& f : frames) {
      r.frame(ch_cam, "cam0", f);
      out.frames.push_back(f);
    }
    for (auto& s : fs) {
      r.json(ch_fsr, s.host_ns, static_cast<std::uint32_t>(s.sequence), to_json(s));
      out.fsr.push_back(to_json(s));
    }
    for (auto& s : ws) {
      r.json(ch_ft, s.host_ns, s.rdt_sequence, to_json(s));
      out.wrench.push_back(to_json(s));
    }
    r.json(ch_arm, st->host_ns, static_cast<std::uint32_t>(st->sequence), to_json(*st));
    out.arm.push_back(to_json(*st));
  }
  EXPECT_EQ(ft->stats().lost > 0, dropouts);
  r.close();
  return out;
}

}  // namespace hc::devices::testing
