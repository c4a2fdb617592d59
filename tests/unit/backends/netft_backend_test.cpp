// Hardware-in-the-loop: the "netft" force-torque backend (through the devices interface and the
// backend registry) against the RDT simulator on 127.0.0.1, including faults: dropped and
// reordered packets, and a stream that stops (recovered by restart, or reported as kError and
// recovered by reset + activate) without losing what was already received.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <thread>

#include "rig_daemon/backends/hardware_backends.h"
#include "rig_daemon/devices/registry.h"
#include "rig_daemon/simulators/rdt_server.h"

namespace hc::rig {
namespace {

using namespace std::chrono_literals;
using devices::DeviceState;
using devices::WrenchSample;

rdt::Wrench signal(double t) {
  rdt::Wrench w;
  w.force_n[2] = 20.0 + 10.0 * std::sin(2 * std::numbers::pi * t);
  w.torque_nm[1] = -0.5;
  return w;
}

devices::DeviceContext context(const std::string& name, const std::string& backend) {
  devices::DeviceContext ctx;
  ctx.name = name;
  ctx.backend = backend;
  ctx.clock = devices::monotonic_clock();
  return ctx;
}

sim::RdtServerOptions server_options(std::uint64_t seed = 1, rdt::Calibration cal = {}) {
  sim::RdtServerOptions so;
  so.seed = seed;
  so.calibration = cal;
  return so;
}

struct NetFtFixture {
  std::unique_ptr<sim::RdtServer> server;
  std::unique_ptr<devices::ForceTorque> ft;
};

NetFtFixture make_netft_fixture(const std::string& extra_yaml = "", sim::RdtServerOptions so = {}) {
  NetFtFixture f;
  if (!so.signal) so.signal = signal;
  auto server = sim::RdtServer::start(so);
  EXPECT_TRUE(server.ok()) << server.status().to_string();
  if (!server.ok()) return f;
  f.server = std::move(*server);
  devices::BackendRegistry registry;
  EXPECT_TRUE(register_hardware_backends(registry).ok());
  auto ft = registry.create<devices::ForceTorque>(context("ft", "netft"));
  EXPECT_TRUE(ft.ok()) << ft.status().to_string();
  if (!ft.ok()) return f;
  f.ft = std::move(*ft);
  const std::string yaml = "port: " + std::to_string(f.server->port()) +
                           "\nhttp_port: " + std::to_string(f.server->http_port()) + "\n" +
                           extra_yaml;
  Status s = devices::configure_from_yaml(*f.ft, yaml);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return f;
}

std::size_t read_for(devices::ForceTorque& ft, std::vector<WrenchSample>& out,
                     std::chrono::milliseconds d) {
  const auto end = std::chrono::steady_clock::now() + d;
  std::size_t n = 0;
  while (std::chrono::steady_clock::now() < end) {
    auto r = ft.read(out, 5ms);
    if (!r.ok()) break;
    n += *r;
  }
  return n;
}

TEST(NetFtBackend, RegistryKnowsTheHardwareBackends) {
  devices::BackendRegistry registry;
  ASSERT_TRUE(register_hardware_backends(registry).ok());
  EXPECT_TRUE(registry.has(devices::DeviceKind::kForceTorque, "netft"));
  EXPECT_TRUE(registry.has(devices::DeviceKind::kArm, "modbus"));
  EXPECT_FALSE(register_hardware_backends(registry).ok());  // names are taken
}

TEST(NetFtBackend, StreamsCalibratedSamplesWithContiguousSequence) {
  NetFtFixture f = make_netft_fixture("calibration_source: sensor\n",
                                      server_options(1, {1'000'000, 1'000, "N", "Nmm"}));
  ASSERT_TRUE(f.ft);
  EXPECT_DOUBLE_EQ(f.ft->calibration().counts_per_n, 1e6);
  ASSERT_TRUE(f.ft->activate().ok()) << f.ft->error().to_string();
  // Calibration fetched from the simulator's netftapi2.xml: 1000 counts per N mm = 1e6 per N m.
  EXPECT_DOUBLE_EQ(f.ft->calibration().counts_per_nm, 1e6);
  std::vector<WrenchSample> s;
  read_for(*f.ft, s, 200ms);
  ASSERT_GT(s.size(), 800u);  // 7 kHz for 0.2 s, with slack for a busy machine
  for (std::size_t i = 0; i < s.size(); ++i) {
    ASSERT_EQ(s[i].sequence, i);
    const double t = static_cast<double>(*s[i].device_stamp_ns) * 1e-9;  // ft_sequence / 7 kHz
    EXPECT_NEAR(s[i].force_n[2], signal(t).force_n[2], 0.01);            // 2 pi 10 N/s x 1/14 ms
    EXPECT_NEAR(s[i].torque_nm[1], -0.5, 1e-6);
  }
  EXPECT_EQ(f.ft->stats().received, s.size());
  EXPECT_EQ(f.ft->stats().lost, 0u);
  ASSERT_TRUE(f.ft->deactivate().ok());
  EXPECT_EQ(f.ft->state(), DeviceState::kInactive);
}

TEST(NetFtBackend, HostBiasKeepsRawCounts) {
  sim::RdtServerOptions so;
  so.signal = [](double) {
    rdt::Wrench w;
    w.force_n[2] = 20.0;
    w.torque_nm[1] = -0.5;
    return w;
  };
  NetFtFixture f = make_netft_fixture("", so);
  ASSERT_TRUE(f.ft);
  ASSERT_TRUE(f.ft->activate().ok());
  std::vector<WrenchSample> s;
  read_for(*f.ft, s, 20ms);
  ASSERT_TRUE(f.ft->bias().ok());
  s.clear();
  read_for(*f.ft, s, 10ms);
  ASSERT_FALSE(s.empty());
  EXPECT_NEAR(s.back().force_n[2], 0.0, 1e-6);
  EXPECT_NEAR(s.back().torque_nm[1], 0.0, 1e-6);
  EXPECT_NEAR(s.back().counts[4], -500'000, 1);  // raw counts unchanged: -0.5 N m x 1e6
  ASSERT_TRUE(f.ft->clear_bias().ok());
  s.clear();
  read_for(*f.ft, s, 10ms);
  ASSERT_FALSE(s.empty());
  EXPECT_NEAR(s.back().torque_nm[1], -0.5, 1e-6);
}

TEST(NetFtBackend, DroppedPacketsAreCountedLostAndReorderedOnesKept) {
  NetFtFixture f = make_netft_fixture("", server_options(7));
  ASSERT_TRUE(f.ft);
  ASSERT_TRUE(f.ft->activate().ok());
  std::vector<WrenchSample> s;
  f.server->set_faults({.drop_probability = 0.05});
  read_for(*f.ft, s, 150ms);
  f.server->set_faults({.reorder = true});
  read_for(*f.ft, s, 100ms);
  f.server->set_faults({});
  read_for(*f.ft, s, 30ms);
  const auto dropped = f.server->stats().packets_dropped;
  EXPECT_GT(dropped, 10u);
  EXPECT_EQ(f.ft->stats().lost, dropped);
  // Every sample delivered exactly once: received + lost covers the sequence range.
  std::vector<std::uint64_t> seq;
  for (const auto& w : s) seq.push_back(w.sequence);
  std::sort(seq.begin(), seq.end());
  EXPECT_EQ(std::adjacent_find(seq.begin(), seq.end()), seq.end());
  EXPECT_EQ(seq.size() + dropped, seq.back() + 1);
}

TEST(NetFtBackend, ShortStallIsBridgedByRestartingTheStream) {
  NetFtFixture f = make_netft_fixture("stall_timeout_s: 0.05\n");
  ASSERT_TRUE(f.ft);
  ASSERT_TRUE(f.ft->activate().ok());
  std::vector<WrenchSample> s;
  read_for(*f.ft, s, 30ms);
  const std::size_t before = s.size();
  ASSERT_GT(before, 0u);
  f.server->set_faults({.stalled = true});
  std::thread unstall([&] {
    std::this_thread::sleep_for(120ms);
    f.server->set_faults({});
  });
  read_for(*f.ft, s, 400ms);
  unstall.join();
  EXPECT_EQ(f.ft->state(), DeviceState::kActive) << f.ft->error().to_string();
  EXPECT_GT(s.size(), before + 100);
  // Sequence numbers keep increasing across the restart (rdt_sequence restarted at 1).
  for (std::size_t i = 1; i < s.size(); ++i) ASSERT_GT(s[i].sequence, s[i - 1].sequence);
  const auto info = f.ft->info();
  const auto restarts = std::find_if(info.details.begin(), info.details.end(),
                                     [](const auto& kv) { return kv.first == "restarts"; });
  ASSERT_NE(restarts, info.details.end());
  EXPECT_NE(restarts->second, "0");
}

TEST(NetFtBackend, StoppedStreamIsReportedAndRecoveredByResetWithoutLosingSamples) {
  NetFtFixture f = make_netft_fixture("stall_timeout_s: 0.05\n");
  ASSERT_TRUE(f.ft);
  ASSERT_TRUE(f.ft->activate().ok());
  std::vector<WrenchSample> s;
  read_for(*f.ft, s, 40ms);
  const std::size_t before = s.size();
  ASSERT_GT(before, 0u);
  f.server->set_faults({.stalled = true});
  Status error;
  const auto end = std::chrono::steady_clock::now() + 2s;
  while (std::chrono::steady_clock::now() < end) {
    auto r = f.ft->read(s, 10ms);
    if (!r.ok()) {
      error = r.status();
      break;
    }
  }
  ASSERT_FALSE(error.ok());
  EXPECT_EQ(error.code(), StatusCode::kUnavailable);
  EXPECT_NE(error.message().find("no RDT record"), std::string::npos) << error.to_string();
  EXPECT_EQ(f.ft->state(), DeviceState::kError);
  EXPECT_EQ(f.ft->stats().errors, 1u);
  EXPECT_GE(s.size(), before);  // what arrived before the stall is all still there
  EXPECT_EQ(f.ft->stats().received, s.size());
  // The sensor comes back: reset + activate resume streaming, sequence numbers continue.
  f.server->set_faults({});
  ASSERT_TRUE(f.ft->reset().ok());
  ASSERT_TRUE(f.ft->activate().ok()) << f.ft->error().to_string();
  const std::size_t at_resume = s.size();
  read_for(*f.ft, s, 30ms);
  ASSERT_GT(s.size(), at_resume);
  EXPECT_GT(s[at_resume].sequence, s[at_resume - 1].sequence);
}

TEST(NetFtBackend, BadConfigAndMissingSensorFailClearly) {
  devices::BackendRegistry registry;
  ASSERT_TRUE(register_hardware_backends(registry).ok());
  auto ft = registry.create<devices::ForceTorque>(context("ft", "netft"));
  ASSERT_TRUE(ft.ok());
  Status s = devices::configure_from_yaml(**ft, "force_unit: furlong\n");
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("force_unit"), std::string::npos) << s.to_string();
  s = devices::configure_from_yaml(**ft, "hots: 1.2.3.4\n");
  EXPECT_NE(s.message().find("hots"), std::string::npos) << s.to_string();
  // Nothing listens: activate fails with kUnavailable after the start attempts.
  std::uint16_t port;
  {
    sim::RdtServerOptions so;
    so.serve_http = false;
    auto server = sim::RdtServer::start(so);
    ASSERT_TRUE(server.ok());
    port = (*server)->port();
  }
  ASSERT_TRUE(devices::configure_from_yaml(**ft, "port: " + std::to_string(port) +
                                                     "\nstart_attempts: 2\nstart_timeout_s: 0.02\n")
                  .ok());
  s = (*ft)->activate();
  EXPECT_EQ(s.code(), StatusCode::kUnavailable) << s.to_string();
}

}  // namespace
}  // namespace hc::rig
