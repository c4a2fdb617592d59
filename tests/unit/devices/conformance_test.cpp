// Conformance suite for device backends (after libcamera's lc-compliance): the same checks run on
// every backend in the list: lifecycle order enforcement, errors in the error state, statistics,
// monotonic timestamps, seeded determinism, faults surfacing as errors and lost counts.
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "replay_support.h"
#include "rig_daemon/replay/replay.h"
#include "rig_daemon/session/codec.h"
#include "sim_support.h"
#include "test_data.h"

namespace hc::devices {
namespace {

using testing::SimRig;

struct BackendCase {
  std::string label;
  DeviceKind kind;
  std::string backend;
  std::string yaml;                     // the device's config
  bool needs_trigger;                   // a pulse train must run for items to appear
  bool periodic;                        // items come at a fixed rate (lost + received == due)
  std::uint64_t items_per_counter = 1;  // items sharing one counter value (edges on 2 lines)
  // Backends on the firmware driver run on the board's own (virtual) clock, not the world's, and
  // world faults do not reach them (their link faults are tested in firmware_backend_test.cpp).
  bool on_world_clock = true;
  // Faults injected into the simulated world reach the device.
  bool world_faults = true;
};

// One recorded session (no faults) that every replay case serves.
const std::filesystem::path& session_path() {
  static hc::testing::ScratchDir dir;
  static const std::filesystem::path path = [] {
    const auto p = dir.path() / "conformance.mcap";
    (void)testing::record_session(p, /*dropouts=*/false);
    return p;
  }();
  return path;
}

std::ostream& operator<<(std::ostream& os, const BackendCase& c) { return os << c.label; }

// One delivered item, reduced to what every kind has.
struct Item {
  std::int64_t host_ns = 0;
  std::uint64_t counter = 0;
  std::string repr;  // full content, for determinism checks
};

// Host times of firmware-backed devices come from the host's monotonic clock at board open.
std::string without_host_ns(std::string json) {
  const std::size_t at = json.find("\"host_ns\":");
  if (at == std::string::npos) return json;
  const std::size_t end = json.find_first_of(",}", at);
  return json.erase(at, end - at);
}

Result<std::vector<Item>> read_items(Device& device, Duration timeout) {
  std::vector<Item> items;
  switch (device.kind()) {
    case DeviceKind::kCamera: {
      std::vector<Frame> frames;
      HC_ASSIGN_OR_RETURN(std::size_t n, static_cast<Camera&>(device).read(frames, timeout));
      (void)n;
      for (const Frame& f : frames) {
        std::uint64_t sum = 0;
        for (std::uint8_t p : f.pixels) sum = sum * 131 + p;
        items.push_back({f.host_ns, f.frame_index,
                         std::to_string(f.frame_id) + "/" + std::to_string(sum) + "/" +
                             std::to_string(*f.device_stamp_ns)});
      }
      break;
    }
    case DeviceKind::kTrigger: {
      std::vector<TriggerEdge> edges;
      HC_ASSIGN_OR_RETURN(std::size_t n, static_cast<Trigger&>(device).read(edges, timeout));
      (void)n;
      for (const TriggerEdge& e : edges)
        items.push_back({e.host_ns, e.index, without_host_ns(to_json(e))});
      break;
    }
    case DeviceKind::kFsr: {
      std::vector<FsrSample> samples;
      HC_ASSIGN_OR_RETURN(std::size_t n, static_cast<Fsr&>(device).read(samples, timeout));
      (void)n;
      for (const FsrSample& s : samples)
        items.push_back({s.host_ns, s.sequence, without_host_ns(to_json(s))});
      break;
    }
    case DeviceKind::kForceTorque: {
      std::vector<WrenchSample> samples;
      HC_ASSIGN_OR_RETURN(std::size_t n, static_cast<ForceTorque&>(device).read(samples, timeout));
      (void)n;
      for (const WrenchSample& s : samples) items.push_back({s.host_ns, s.sequence, to_json(s)});
      break;
    }
    case DeviceKind::kArm: {
      HC_ASSIGN_OR_RETURN(ArmState s, static_cast<Arm&>(device).read());
      device.clock().sleep_for(timeout);
      items.push_back({s.host_ns, s.sequence, to_json(s)});
      break;
    }
  }
  return items;
}

class Conformance : public ::testing::TestWithParam<BackendCase> {
 protected:
  std::unique_ptr<Device> make(SimRig& rig, const std::string& name = "dev") {
    if (GetParam().backend == "replay") {
      // A fresh session object per device: pacing anchors at its first activation.
      Result<std::shared_ptr<ReplaySession>> s = ReplaySession::open(session_path());
      EXPECT_TRUE(s.ok());
      rig.replay = s.ok() ? *s : nullptr;
    }
    Result<std::unique_ptr<Device>> made =
        rig.create(GetParam().kind, rig.context(name, GetParam().backend));
    EXPECT_TRUE(made.ok()) << made.status().to_string();
    return made.ok() ? std::move(made).value() : nullptr;
  }
  std::unique_ptr<Device> make_active(SimRig& rig, const std::string& name = "dev") {
    auto d = make(rig, name);
    if (!d) return d;
    EXPECT_TRUE(configure_from_yaml(*d, GetParam().yaml).ok());
    EXPECT_TRUE(d->activate().ok());
    if (GetParam().needs_trigger) start_train(rig, *d);
    if (d->kind() == DeviceKind::kArm && GetParam().backend != "replay") {
      ArmCommand home;
      home.type = ArmCommand::Type::kHome;
      EXPECT_TRUE(static_cast<Arm&>(*d).write(home).ok());
    }
    return d;
  }
  // A 50 Hz pulse train: on the world's trigger timeline, or on the firmware board (through the
  // device itself, or a helper trigger on the same board for the FSR).
  void start_train(SimRig& rig, Device& d) {
    PulseTrain train;
    train.rate_hz = 50.0;
    if (GetParam().backend != "firmware") {
      EXPECT_TRUE(rig.world->trigger_start(train, rig.clock->now_ns()).ok());
    } else if (d.kind() == DeviceKind::kTrigger) {
      EXPECT_TRUE(static_cast<Trigger&>(d).start(train).ok());
    } else {
      helper_ = rig.make<Trigger>(
          "helper_trigger",
          "{backend: firmware, device: sim, adc_channels: [0], adc_noise_v: 0.01}");
      ASSERT_TRUE(helper_);
      ASSERT_TRUE(helper_->activate().ok());
      EXPECT_TRUE(helper_->start(train).ok());
    }
  }
  // Reads for `duration` of simulated time in 10 ms slices (firmware boards advance their own
  // virtual time by the read timeout; the world's clock is moved along with them).
  std::vector<Item> collect(SimRig& rig, Device& d, std::int64_t duration_ns) {
    std::vector<Item> all;
    for (std::int64_t t = 0; t < duration_ns; t += 10'000'000) {
      const std::int64_t before = rig.clock->now_ns();
      Result<std::vector<Item>> items = read_items(d, std::chrono::milliseconds(10));
      EXPECT_TRUE(items.ok()) << items.status().to_string();
      if (!items.ok()) break;
      all.insert(all.end(), items->begin(), items->end());
      rig.clock->set_ns(before + 10'000'000);
    }
    return all;
  }
  void TearDown() override { helper_.reset(); }
  std::unique_ptr<Trigger> helper_;
};

TEST_P(Conformance, LifecycleOrderIsEnforced) {
  SimRig rig;
  auto d = make(rig);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->state(), DeviceState::kUnconfigured);
  EXPECT_EQ(d->activate().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(d->deactivate().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(read_items(*d, Duration(0)).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(d->state(), DeviceState::kUnconfigured);

  ASSERT_TRUE(configure_from_yaml(*d, GetParam().yaml).ok());
  EXPECT_EQ(d->state(), DeviceState::kInactive);
  EXPECT_EQ(read_items(*d, Duration(0)).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(d->deactivate().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(d->activate().ok());
  EXPECT_EQ(d->state(), DeviceState::kActive);
  EXPECT_EQ(d->activate().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(configure_from_yaml(*d, GetParam().yaml).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(d->deactivate().ok());
  EXPECT_EQ(d->state(), DeviceState::kInactive);
  EXPECT_EQ(read_items(*d, Duration(0)).status().code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(d->cleanup().ok());
  EXPECT_EQ(d->state(), DeviceState::kUnconfigured);
  EXPECT_EQ(d->stats().errors, 0u);
}

TEST_P(Conformance, UnknownConfigKeyIsRejectedAndLeavesDeviceUnconfigured) {
  SimRig rig;
  auto d = make(rig);
  ASSERT_TRUE(d);
  std::string yaml = GetParam().yaml;
  yaml = yaml == "{}" ? "{bogus_key: 1}" : yaml.substr(0, yaml.size() - 1) + ", bogus_key: 1}";
  Status s = configure_from_yaml(*d, yaml, "rig.yaml");
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("bogus_key"), std::string::npos) << s.message();
  EXPECT_EQ(d->state(), DeviceState::kUnconfigured);
}

TEST_P(Conformance, DeliversItemsWithMonotonicTimestampsAndCountsThem) {
  SimRig rig;
  auto d = make_active(rig);
  ASSERT_TRUE(d);
  const std::vector<Item> items = collect(rig, *d, 300'000'000);
  ASSERT_GE(items.size(), 3u);
  for (std::size_t i = 1; i < items.size(); ++i) {
    EXPECT_GE(items[i].host_ns, items[i - 1].host_ns) << i;
    // (Replayed arm polls repeat the latest recorded state until a newer one is due.)
    if (GetParam().items_per_counter == 1 && GetParam().kind != DeviceKind::kArm)
      EXPECT_GT(items[i].counter, items[i - 1].counter) << i;
    else
      EXPECT_GE(items[i].counter, items[i - 1].counter) << i;
  }
  if (GetParam().on_world_clock) {
    EXPECT_LE(items.back().host_ns, rig.clock->now_ns());
  }
  const DeviceStats s = d->stats();
  EXPECT_EQ(s.received, items.size());
  EXPECT_EQ(s.lost, 0u);
  EXPECT_EQ(s.last_host_ns, items.back().host_ns);
}

TEST_P(Conformance, SameSeedSameItemsOtherSeedOtherNoise) {
  std::vector<std::vector<Item>> runs;
  for (std::uint64_t seed : {11u, 11u, 12u}) {
    SimRig rig(seed);
    auto d = make_active(rig);
    ASSERT_TRUE(d);
    runs.push_back(collect(rig, *d, 100'000'000));
    helper_.reset();  // releases the firmware board with the world
  }
  ASSERT_EQ(runs[0].size(), runs[1].size());
  for (std::size_t i = 0; i < runs[0].size(); ++i) EXPECT_EQ(runs[0][i].repr, runs[1][i].repr);
  // Devices with noise or a device clock differ for another seed.
  bool differ = runs[0].size() != runs[2].size();
  for (std::size_t i = 0; !differ && i < runs[0].size(); ++i)
    differ = runs[0][i].repr != runs[2][i].repr;
  if (GetParam().kind != DeviceKind::kTrigger && GetParam().kind != DeviceKind::kArm &&
      GetParam().backend == "sim") {
    EXPECT_TRUE(differ);
  }
}

TEST_P(Conformance, DisconnectEntersErrorStateUntilReset) {
  if (!GetParam().world_faults) GTEST_SKIP() << "world faults do not reach this backend";
  SimRig rig;
  auto d = make_active(rig);
  ASSERT_TRUE(d);
  (void)collect(rig, *d, 50'000'000);
  const std::int64_t t = rig.clock->now_ns();
  rig.world->inject({sim::Fault::Kind::kDisconnect, "dev", t, t + 200'000'000, 1.0, 0.0});
  Result<std::vector<Item>> r = read_items(*d, std::chrono::milliseconds(10));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kUnavailable);
  EXPECT_EQ(d->state(), DeviceState::kError);
  EXPECT_EQ(d->error().code(), StatusCode::kUnavailable);
  EXPECT_EQ(d->stats().errors, 1u);
  // Every operation but reset/deactivate reports the stored error.
  EXPECT_EQ(read_items(*d, Duration(0)).status().code(), StatusCode::kUnavailable);
  EXPECT_EQ(d->activate().code(), StatusCode::kUnavailable);
  EXPECT_EQ(d->reset().code(), StatusCode::kUnavailable);  // still disconnected
  EXPECT_EQ(d->state(), DeviceState::kError);
  rig.clock->advance_ns(250'000'000);
  ASSERT_TRUE(d->reset().ok());
  EXPECT_EQ(d->state(), DeviceState::kInactive);
  EXPECT_TRUE(d->error().ok());
  ASSERT_TRUE(d->activate().ok());
  if (GetParam().needs_trigger) start_train(rig, *d);
  EXPECT_FALSE(collect(rig, *d, 100'000'000).empty());
  EXPECT_EQ(d->stats().errors, 1u);
}

TEST_P(Conformance, DropoutsAndStallsAreCountedAsLost) {
  if (!GetParam().periodic) GTEST_SKIP() << "no fixed item rate";
  if (!GetParam().world_faults) GTEST_SKIP() << "world faults do not reach this backend";
  SimRig rig;
  auto d = make_active(rig);
  ASSERT_TRUE(d);
  const std::int64_t t = rig.clock->now_ns();
  rig.world->inject({sim::Fault::Kind::kDropout, "dev", t, t + 200'000'000, 0.5, 0.0});
  rig.world->inject({sim::Fault::Kind::kStall, "dev", t + 300'000'000, t + 400'000'000, 1.0, 0.0});
  const std::vector<Item> items = collect(rig, *d, 600'000'000);
  const DeviceStats s = d->stats();
  EXPECT_GT(s.lost, 0u);
  EXPECT_EQ(s.received, items.size());
  ASSERT_FALSE(items.empty());
  // Counters start at 0 and run on through losses: the last counter accounts for every item due
  // so far, received or lost (the windows end well before the last item).
  EXPECT_EQ((items.back().counter + 1) * GetParam().items_per_counter, s.received + s.lost);
  // The stall window (100 ms) alone loses every item due in it.
  std::int64_t longest_gap = 0;
  for (std::size_t i = 1; i < items.size(); ++i)
    longest_gap = std::max(longest_gap, items[i].host_ns - items[i - 1].host_ns);
  EXPECT_GE(longest_gap, 90'000'000);
}

TEST_P(Conformance, ReadTimesOutWithZeroItemsWhenNothingIsDue) {
  SimRig rig;
  auto d = make(rig);
  ASSERT_TRUE(d);
  ASSERT_TRUE(configure_from_yaml(*d, GetParam().yaml).ok());
  ASSERT_TRUE(d->activate().ok());
  if (d->kind() == DeviceKind::kArm) GTEST_SKIP() << "arm reads are polls";
  if (GetParam().needs_trigger) {
    // No pulse train: nothing ever comes; the wait is simulated time.
    const std::int64_t t0 = rig.clock->now_ns();
    Result<std::vector<Item>> r = read_items(*d, std::chrono::milliseconds(30));
    ASSERT_TRUE(r.ok());
    EXPECT_TRUE(r->empty());
    if (GetParam().on_world_clock) {
      EXPECT_GE(rig.clock->now_ns() - t0, 30'000'000);
    }
  } else {
    ASSERT_TRUE(read_items(*d, std::chrono::milliseconds(100)).ok());
    Result<std::vector<Item>> r = read_items(*d, Duration(0));
    ASSERT_TRUE(r.ok());
    EXPECT_TRUE(r->empty());
  }
}

const BackendCase kCases[] = {
    {"sim_camera_free_run", DeviceKind::kCamera, "sim",
     "{trigger: free_run, width: 320, height: 240, fx: 400, frame_rate_hz: 30}", false, true},
    {"sim_camera_hardware", DeviceKind::kCamera, "sim",
     "{trigger: hardware, width: 320, height: 240, fx: 400}", true, true},
    {"sim_trigger", DeviceKind::kTrigger, "sim", "{lines: [0, 1]}", true, true, 2},
    {"sim_fsr_periodic", DeviceKind::kFsr, "sim", "{rate_hz: 1000}", false, true},
    {"sim_fsr_triggered", DeviceKind::kFsr, "sim", "{sampling: triggered}", true, true},
    {"sim_force_torque", DeviceKind::kForceTorque, "sim", "{rate_hz: 7000}", false, true},
    {"sim_arm", DeviceKind::kArm, "sim", "{}", false, false},
    {"firmware_trigger", DeviceKind::kTrigger, "firmware", "{device: sim, lines: [0, 1]}", true,
     true, 2, false, false},
    {"firmware_fsr", DeviceKind::kFsr, "firmware", "{device: sim, channel: 0, adc_noise_v: 0.01}",
     true, true, 1, false, false},
    {"replay_camera", DeviceKind::kCamera, "replay", "{source: cam0}", false, true, 1, true, false},
    {"replay_trigger", DeviceKind::kTrigger, "replay", "{source: trig}", false, true, 1, true,
     false},
    {"replay_fsr", DeviceKind::kFsr, "replay", "{source: fsr}", false, true, 1, true, false},
    {"replay_force_torque", DeviceKind::kForceTorque, "replay", "{source: ft}", false, true, 1,
     true, false},
    {"replay_arm", DeviceKind::kArm, "replay", "{source: arm}", false, false, 1, true, false},
};

INSTANTIATE_TEST_SUITE_P(SimBackends, Conformance, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<BackendCase>& param_info) {
                           return param_info.param.label;
                         });

}  // namespace
}  // namespace hc::devices
