// A force-calibration session recorded from the simulated rig: the simulated 4-DOF arm presses its
// probe into the (Hertz) specimen in a staircase of depths, down and back up, while the simulated
// F/T sensor (1 kHz) and the simulated FSR (periodic) are read and written in rigd's session layout
// (rig_daemon/session/topics.h) through rigd's Recorder, with the simulator's true force on
// /sim/ground_truth. rigd's plans record either the FSR (hand-held) or the F/T (automated), never
// both, so the test drives the devices itself, as the daemon's scheduler does.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>

#include "common/json.h"
#include "rig_daemon/daemon/recorder.h"
#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/force_torque.h"
#include "rig_daemon/devices/fsr.h"
#include "rig_daemon/devices/registry.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"
#include "rig_daemon/simulation/sim_backends.h"

namespace hc::calib::testing {

struct SimForceSpec {
  std::uint64_t seed = 11;
  // Device configs (YAML flow maps, as in a rig config).
  std::string ft_yaml = "{rate_hz: 1000, offset_n: 0.4, drift_n_per_s: 0.002}";
  std::string fsr_yaml =
      "{sampling: periodic, rate_hz: 100, calibration: {threshold: 0.03, scale_n: 50, exponent: "
      "1.4}}";
  double max_depth_m = 0.0042;  // ~35 N on the default Hertz specimen (E = 1 MPa, R = 5 mm)
  int steps = 30;               // depth steps down (and the same back up)
  double dwell_s = 0.15;
  double unloaded_s = 1.0;  // probe above the surface at the start and the end
  bool record_ft = true;
  bool record_fsr = true;
};

inline Status record_sim_force_session(const std::filesystem::path& path,
                                       const SimForceSpec& spec) {
  namespace dev = hc::devices;
  auto clock = std::make_shared<dev::SimulatedClock>(1'000'000'000);
  dev::sim::WorldOptions wo;
  wo.seed = spec.seed;
  auto world = std::make_shared<dev::sim::World>(wo, clock);
  dev::BackendRegistry registry;
  HC_RETURN_IF_ERROR(dev::register_sim_backends(registry, world));
  const auto ctx = [&](const std::string& name) {
    dev::DeviceContext c;
    c.name = name;
    c.backend = "sim";
    c.clock = clock;
    return c;
  };
  HC_ASSIGN_OR_RETURN(std::unique_ptr<dev::Arm> arm, registry.create<dev::Arm>(ctx("arm")));
  HC_ASSIGN_OR_RETURN(std::unique_ptr<dev::ForceTorque> ft,
                      registry.create<dev::ForceTorque>(ctx("ft")));
  HC_ASSIGN_OR_RETURN(std::unique_ptr<dev::Fsr> fsr, registry.create<dev::Fsr>(ctx("fsr")));
  HC_RETURN_IF_ERROR(dev::configure_from_yaml(*arm, "{}", "arm"));
  HC_RETURN_IF_ERROR(dev::configure_from_yaml(*ft, spec.ft_yaml, "ft"));
  HC_RETURN_IF_ERROR(dev::configure_from_yaml(*fsr, spec.fsr_yaml, "fsr"));
  HC_RETURN_IF_ERROR(arm->activate());
  dev::ArmCommand home;
  home.type = dev::ArmCommand::Type::kHome;
  HC_RETURN_IF_ERROR(arm->write(home));
  clock->advance_ns(10'000'000'000);
  const double top = world->specimen().top_z_m();
  std::uint64_t seq = 1;
  const auto move = [&](double depth) {
    dev::ArmCommand m;
    m.type = dev::ArmCommand::Type::kMoveTo;
    m.target = {0.0, 0.0, top - depth, 0.0};
    m.sequence = ++seq;
    return arm->write(m);
  };
  HC_RETURN_IF_ERROR(move(-0.001));
  clock->advance_ns(10'000'000'000);

  HC_ASSIGN_OR_RETURN(std::unique_ptr<rig::Recorder> rec,
                      rig::Recorder::open(path, rig::Recorder::Options{}));
  const auto meta = [](const std::string& d, const std::string& kind) {
    return recording::StringMap{{"device", d}, {"kind", kind}, {"backend", "sim"}};
  };
  std::uint16_t ch_ft = 0, ch_fsr = 0, ch_truth = 0;
  if (spec.record_ft) {
    const auto& s = session::wrench_sample_schema();
    HC_ASSIGN_OR_RETURN(ch_ft, rec->add_json_channel(session::wrench_topic("ft"), s.name,
                                                     s.json_schema, meta("ft", "force_torque")));
  }
  if (spec.record_fsr) {
    const auto& s = session::fsr_sample_schema();
    HC_ASSIGN_OR_RETURN(ch_fsr, rec->add_json_channel(session::fsr_topic("fsr"), s.name,
                                                      s.json_schema, meta("fsr", "fsr")));
  }
  const session::MessageSchema& truth_schema = session::ground_truth_schema();
  HC_ASSIGN_OR_RETURN(
      ch_truth, rec->add_json_channel(session::kGroundTruthTopic, truth_schema.name,
                                      truth_schema.json_schema, meta("world", "ground_truth")));
  const dev::FsrCalibration fc = fsr->calibration();
  Json calib{{"ft",
              {{"counts_per_n", ft->calibration().counts_per_n},
               {"counts_per_nm", ft->calibration().counts_per_nm}}},
             {"fsr",
              {{"full_scale", fc.full_scale},
               {"threshold", fc.threshold},
               {"scale_n", fc.scale_n},
               {"exponent", fc.exponent}}}};
  HC_RETURN_IF_ERROR(
      rec->write_metadata_now(recording::kMetadataCalibration, {{"json", calib.dump()}}));
  rec->start();
  HC_RETURN_IF_ERROR(ft->activate());
  HC_RETURN_IF_ERROR(fsr->activate());

  std::vector<dev::WrenchSample> wbuf;
  std::vector<dev::FsrSample> fbuf;
  const auto to_bytes = [](const std::string& s) { return recording::Bytes(s.begin(), s.end()); };
  const auto run_for = [&](double seconds) -> Status {
    const std::int64_t end = clock->now_ns() + static_cast<std::int64_t>(seconds * 1e9);
    while (clock->now_ns() < end) {
      clock->advance_ns(5'000'000);
      wbuf.clear();
      fbuf.clear();
      HC_RETURN_IF_ERROR(ft->read(wbuf, dev::Duration(0)).status());
      HC_RETURN_IF_ERROR(fsr->read(fbuf, dev::Duration(0)).status());
      if (spec.record_ft)
        for (const auto& s : wbuf)
          rec->write(ch_ft, s.host_ns, s.host_ns, s.rdt_sequence, to_bytes(session::to_json(s)));
      if (spec.record_fsr)
        for (const auto& s : fbuf) {
          rec->write(ch_fsr, s.host_ns, s.host_ns, static_cast<std::uint32_t>(s.sequence),
                     to_bytes(session::to_json(s)));
          session::GroundTruthRecord t;
          t.host_ns = s.host_ns;
          t.force_n = world->true_force_n(s.host_ns);
          rec->write(ch_truth, s.host_ns, s.host_ns, 0, to_bytes(session::to_json(t)));
        }
    }
    return {};
  };
  HC_RETURN_IF_ERROR(run_for(spec.unloaded_s));
  for (int k = 1; k <= 2 * spec.steps; ++k) {
    const int level = k <= spec.steps ? k : 2 * spec.steps - k;
    HC_RETURN_IF_ERROR(move(spec.max_depth_m * level / spec.steps));
    HC_RETURN_IF_ERROR(run_for(spec.dwell_s));
  }
  HC_RETURN_IF_ERROR(move(-0.001));
  HC_RETURN_IF_ERROR(run_for(spec.unloaded_s));
  return rec->close().status();
}

}  // namespace hc::calib::testing
