// The Net F/T RDT simulator against the real NetFtClient on 127.0.0.1: streaming rate, values,
// bias, calibration over HTTP, buffered mode, and the injected faults (drops, reordering, stalls).
#include "rig_daemon/simulators/rdt_server.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <thread>

#include "rig_daemon/backends/netft_client.h"

namespace hc::rig::sim {
namespace {

using namespace std::chrono_literals;

// Fz = 10 + 5 sin(2 pi 2 t) N, Tx = 0.25 N m: easy to check at any record's time.
rdt::Wrench test_signal(double t) {
  rdt::Wrench w;
  w.force_n[2] = 10.0 + 5.0 * std::sin(2 * std::numbers::pi * 2.0 * t);
  w.torque_nm[0] = 0.25;
  return w;
}

struct RdtRig {
  std::unique_ptr<RdtServer> server;
  std::unique_ptr<NetFtClient> client;
};

RdtRig make_rdt_rig(RdtServerOptions so = {}, NetFtOptions co = {}) {
  if (!so.signal) so.signal = test_signal;
  RdtRig rig;
  auto server = RdtServer::start(so);
  EXPECT_TRUE(server.ok()) << server.status().to_string();
  if (!server.ok()) return rig;
  rig.server = std::move(*server);
  co.port = rig.server->port();
  co.http_port = rig.server->http_port();
  auto client = NetFtClient::open(co);
  EXPECT_TRUE(client.ok()) << client.status().to_string();
  if (client.ok()) rig.client = std::move(*client);
  return rig;
}

std::vector<FtSample> collect(NetFtClient& c, std::chrono::milliseconds for_how_long) {
  std::vector<FtSample> out;
  const auto end = std::chrono::steady_clock::now() + for_how_long;
  while (std::chrono::steady_clock::now() < end) {
    auto n = c.receive(out, 5ms);
    EXPECT_TRUE(n.ok()) << n.status().to_string();
  }
  return out;
}

TEST(RdtServer, StreamsAt7kHzWithTheConfiguredSignal) {
  RdtRig rig = make_rdt_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.client->start().ok());
  const auto samples = collect(*rig.client, 300ms);
  ASSERT_TRUE(rig.client->stop().ok());
  // 7000 records/s for ~0.3 s; a loaded 2-core CI box may lag, never exceed (+ max burst).
  EXPECT_GT(samples.size(), 1500u);
  EXPECT_LT(samples.size(), 2800u);
  EXPECT_EQ(rig.client->stats().lost, 0u);
  std::uint32_t expect_seq = 1;
  for (const FtSample& s : samples) {
    EXPECT_EQ(s.record.rdt_sequence, expect_seq++);
    const double t = s.record.ft_sequence / 7000.0;  // ft_sequence counts at 7 kHz
    // One count is 1e-6 N; the ft_sequence rounding to 1/7000 s moves Fz by at most
    // 5 * 2 pi * 2 / 7000 / 2 = 4.5e-3 N.
    EXPECT_NEAR(s.wrench.force_n[2], test_signal(t).force_n[2], 5e-3);
    EXPECT_NEAR(s.wrench.torque_nm[0], 0.25, 1e-6);
    EXPECT_EQ(s.record.status, 0u);
  }
  // Host timestamps are monotonic.
  for (std::size_t i = 1; i < samples.size(); ++i)
    EXPECT_GE(samples[i].host_ns, samples[i - 1].host_ns);
}

TEST(RdtServer, BiasSubtractsTheLoadAtThatMoment) {
  RdtServerOptions so;
  so.signal = [](double) {
    rdt::Wrench w;
    w.force_n = {1.0, -2.0, 30.0};
    return w;
  };
  RdtRig rig = make_rdt_rig(so);
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.client->start().ok());
  auto before = collect(*rig.client, 30ms);
  ASSERT_FALSE(before.empty());
  EXPECT_NEAR(before.back().wrench.force_n[2], 30.0, 1e-6);
  ASSERT_TRUE(rig.client->bias().ok());
  std::this_thread::sleep_for(30ms);
  auto after = collect(*rig.client, 30ms);
  ASSERT_FALSE(after.empty());
  for (double f : after.back().wrench.force_n) EXPECT_NEAR(f, 0.0, 1e-6);
}

TEST(RdtServer, CalibrationFromTheSensorsHttpDocument) {
  RdtServerOptions so;
  so.calibration = {1'000'000, 1000, "N", "Nmm"};
  NetFtOptions co;
  co.calibration_source = "sensor";
  RdtRig rig = make_rdt_rig(so, co);
  ASSERT_TRUE(rig.client);
  EXPECT_EQ(rig.client->calibration(), so.calibration);
  ASSERT_TRUE(rig.client->start().ok());
  auto s = collect(*rig.client, 20ms);
  ASSERT_FALSE(s.empty());
  EXPECT_NEAR(s.back().wrench.torque_nm[0], 0.25, 1e-3);  // 1 count = 1e-3 N mm = 1e-6 N m
  EXPECT_GE(rig.server->stats().http_requests, 1u);
  // No HTTP server: a clear kUnavailable, not a hang.
  so.serve_http = false;
  auto quiet = RdtServer::start(so);
  ASSERT_TRUE(quiet.ok());
  co.port = (*quiet)->port();
  co.http_port = (*quiet)->port();  // UDP port: nothing listens on TCP there
  auto failed = NetFtClient::open(co);
  ASSERT_FALSE(failed.ok());
  EXPECT_EQ(failed.status().code(), StatusCode::kUnavailable) << failed.status().to_string();
}

TEST(RdtServer, BufferedModeAndSampleCount) {
  RdtServerOptions so;
  so.records_per_buffered_packet = 20;
  NetFtOptions co;
  co.buffered = true;
  RdtRig rig = make_rdt_rig(so, co);
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.client->start(/*sample_count=*/700).ok());
  auto s = collect(*rig.client, 200ms);  // 700 records at 7 kHz = 0.1 s
  EXPECT_EQ(s.size(), 700u);
  EXPECT_EQ(rig.client->stats().datagrams, 35u);  // 700 / 20 per packet
  EXPECT_FALSE(rig.server->stats().streaming);
}

TEST(RdtServer, DroppedPacketsAreCountedExactly) {
  RdtServerOptions so;
  so.seed = 42;
  RdtRig rig = make_rdt_rig(so);
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.client->start().ok());
  rig.server->set_faults({.drop_probability = 0.1});
  auto s = collect(*rig.client, 200ms);
  rig.server->set_faults({});
  s = collect(*rig.client, 20ms);  // a last in-order packet closes any trailing gap
  ASSERT_TRUE(rig.client->stop().ok());
  std::this_thread::sleep_for(10ms);
  const auto server = rig.server->stats();
  EXPECT_GT(server.packets_dropped, 50u);  // ~10 % of ~1400
  EXPECT_EQ(rig.client->stats().lost, server.packets_dropped);
}

TEST(RdtServer, ReorderedPacketsAreKeptAndNotCountedLost) {
  RdtRig rig = make_rdt_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.client->start().ok());
  rig.server->set_faults({.reorder = true});
  auto s = collect(*rig.client, 100ms);
  rig.server->set_faults({});
  auto more = collect(*rig.client, 20ms);
  s.insert(s.end(), more.begin(), more.end());
  const auto stats = rig.client->stats();
  EXPECT_GT(stats.late, 100u);
  EXPECT_EQ(stats.lost, 0u);
  // Every sequence number from 1 to the last arrived exactly once.
  std::vector<std::uint32_t> seqs;
  for (const auto& x : s) seqs.push_back(x.record.rdt_sequence);
  std::sort(seqs.begin(), seqs.end());
  for (std::size_t i = 0; i < seqs.size(); ++i) ASSERT_EQ(seqs[i], i + 1);
}

TEST(RdtServer, StalledStreamDeliversNothingThenResumesWithoutAGap) {
  RdtRig rig = make_rdt_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.client->start().ok());
  collect(*rig.client, 20ms);
  rig.server->set_faults({.stalled = true});
  std::this_thread::sleep_for(10ms);
  collect(*rig.client, 10ms);  // what was in flight
  EXPECT_TRUE(collect(*rig.client, 100ms).empty());
  rig.server->set_faults({});
  EXPECT_FALSE(collect(*rig.client, 30ms).empty());
  EXPECT_EQ(rig.client->stats().lost, 0u);  // a frozen sensor skips no sequence numbers
}

TEST(RdtServer, StatusWordAndLatchReset) {
  RdtRig rig = make_rdt_rig();
  ASSERT_TRUE(rig.client);
  rig.server->set_faults({.status_word = 0x00010000u});
  ASSERT_TRUE(rig.client->start().ok());
  auto s = collect(*rig.client, 20ms);
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.back().record.status, 0x00010000u);
  EXPECT_GT(rig.client->stats().status_errors, 0u);
  ASSERT_TRUE(rig.client->send({0x0041, 0}).ok());
  std::this_thread::sleep_for(20ms);
  collect(*rig.client, 10ms);
  s = collect(*rig.client, 20ms);
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.back().record.status, 0u);
}

TEST(NetFtClient, StartWithoutASensorTimesOutAndBadOptionsFail) {
  // Bind a UDP port, then close it: nothing listens there.
  RdtServerOptions so;
  so.serve_http = false;
  std::uint16_t port;
  {
    auto s = RdtServer::start(so);
    ASSERT_TRUE(s.ok());
    port = (*s)->port();
  }
  NetFtOptions co;
  co.port = port;
  co.start_attempts = 3;
  co.start_timeout_s = 0.02;
  auto client = NetFtClient::open(co);
  ASSERT_TRUE(client.ok());
  const auto t0 = std::chrono::steady_clock::now();
  Status st = (*client)->start();
  EXPECT_EQ(st.code(), StatusCode::kDeadlineExceeded) << st.to_string();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
  EXPECT_EQ((*client)->stats().start_attempts, 3u);
  co.host = "not-an-ip";
  EXPECT_EQ(NetFtClient::open(co).status().code(), StatusCode::kInvalidArgument);
  co.host = "127.0.0.1";
  co.calibration.counts_per_force = -1;
  EXPECT_FALSE(NetFtClient::open(co).ok());
}

}  // namespace
}  // namespace hc::rig::sim
