// The Modbus TCP arm simulator against the real ModbusArmClient on 127.0.0.1: homing, finite-speed
// moves, stop, faults, a controller that disappears and comes back, and RTU error paths.
#include "rig_daemon/simulators/modbus_arm_server.h"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <thread>

#include "rig_daemon/backends/modbus_arm_client.h"
#include "test_data.h"

namespace hc::rig::sim {
namespace {

using namespace std::chrono_literals;

struct ArmRig {
  std::unique_ptr<ModbusArmServer> server;
  std::unique_ptr<ModbusArmClient> client;
  std::uint16_t seq = 0;

  Status send(arm::Opcode op, ArmPoseSi p = {}, double speed = 0) {
    arm::CommandBlock c;
    c.opcode = op;
    c.sequence = ++seq;
    c.x_m = p.x_m;
    c.y_m = p.y_m;
    c.z_m = p.z_m;
    c.yaw_rad = p.yaw_rad;
    c.speed_m_s = speed;
    return client->send(c);
  }
  arm::StatusBlock status() {
    auto s = client->read_status();
    EXPECT_TRUE(s.ok()) << s.status().to_string();
    return s.ok() ? *s : arm::StatusBlock{};
  }
  // Polls until MOTION is `m` (or 2 s pass).
  arm::StatusBlock wait_for(arm::Motion m) {
    const auto end = std::chrono::steady_clock::now() + 2s;
    arm::StatusBlock s = status();
    while (s.motion != m && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(2ms);
      s = status();
    }
    return s;
  }
};

ArmRig make_arm_rig() {
  ModbusArmServerOptions so;
  so.home_speed_m_s = 1.0;  // homing from the start pose takes ~0.11 s
  ArmRig rig;
  auto server = ModbusArmServer::start(so);
  EXPECT_TRUE(server.ok()) << server.status().to_string();
  if (!server.ok()) return rig;
  rig.server = std::move(*server);
  ModbusArmOptions co;
  co.port = rig.server->port();
  auto client = ModbusArmClient::create(co);
  EXPECT_TRUE(client.ok()) << client.status().to_string();
  rig.client = std::move(*client);
  EXPECT_TRUE(rig.client->connect().ok());
  return rig;
}

TEST(ModbusArmServer, PowersUpUnhomedAndRefusesMovesUntilHomed) {
  ArmRig rig = make_arm_rig();
  ASSERT_TRUE(rig.client);
  arm::StatusBlock s = rig.status();
  EXPECT_EQ(s.map_version, arm::kMapVersion);
  EXPECT_EQ(s.motion, arm::Motion::kIdle);
  EXPECT_FALSE(s.homed);
  EXPECT_NEAR(s.x_m, 0.05, 1e-6);  // the default start pose
  EXPECT_NEAR(s.y_m, -0.02, 1e-6);
  ASSERT_TRUE(rig.send(arm::Opcode::kMoveTo, {0.01, 0, 0.2, 0}).ok());
  s = rig.status();
  EXPECT_EQ(s.motion, arm::Motion::kFault);
  EXPECT_EQ(s.fault, static_cast<std::uint16_t>(arm::Fault::kNotHomed));
  EXPECT_EQ(s.ack_sequence, rig.seq);
  // A latched fault ignores everything but clear fault (and stop).
  ASSERT_TRUE(rig.send(arm::Opcode::kHome).ok());
  EXPECT_EQ(rig.status().motion, arm::Motion::kFault);
  ASSERT_TRUE(rig.send(arm::Opcode::kClearFault).ok());
  s = rig.status();
  EXPECT_EQ(s.motion, arm::Motion::kIdle);
  EXPECT_EQ(s.fault, 0);
}

TEST(ModbusArmServer, HomesThenMovesAtTheCommandedSpeed) {
  ArmRig rig = make_arm_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.send(arm::Opcode::kHome).ok());
  EXPECT_EQ(rig.status().motion, arm::Motion::kHoming);
  arm::StatusBlock s = rig.wait_for(arm::Motion::kHolding);
  ASSERT_EQ(s.motion, arm::Motion::kHolding);
  EXPECT_TRUE(s.homed);
  EXPECT_NEAR(s.z_m, 0.25, 1e-6);  // home pose
  // 20 mm along x at 0.1 m/s takes 0.2 s; sample the speed half-way.
  ASSERT_TRUE(rig.send(arm::Opcode::kMoveTo, {0.02, 0, 0.25, 0}, 0.1).ok());
  std::this_thread::sleep_for(50ms);
  const arm::StatusBlock a = rig.status();
  std::this_thread::sleep_for(60ms);
  const arm::StatusBlock b = rig.status();
  EXPECT_EQ(a.motion, arm::Motion::kMoving);
  EXPECT_TRUE(a.in_motion);
  ASSERT_GT(b.uptime_ms, a.uptime_ms);
  const double v = (b.x_m - a.x_m) / ((b.uptime_ms - a.uptime_ms) * 1e-3);
  EXPECT_NEAR(v, 0.1, 0.03);  // ms clock and 2 ms control cycle: +-30 %
  EXPECT_DOUBLE_EQ(b.speed_m_s, 0.1);
  s = rig.wait_for(arm::Motion::kHolding);
  EXPECT_NEAR(s.x_m, 0.02, 1e-6);
  EXPECT_NEAR(s.y_m, 0.0, 1e-6);
}

TEST(ModbusArmServer, StopFreezesTheArmMidMove) {
  ArmRig rig = make_arm_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.send(arm::Opcode::kHome).ok());
  rig.wait_for(arm::Motion::kHolding);
  ASSERT_TRUE(rig.send(arm::Opcode::kMoveTo, {0.1, 0, 0.25, 0}, 0.05).ok());  // 2 s move
  std::this_thread::sleep_for(40ms);
  ASSERT_TRUE(rig.client->stop().ok());
  const arm::StatusBlock s = rig.status();
  EXPECT_EQ(s.motion, arm::Motion::kStopped);
  EXPECT_GT(s.x_m, 0.0);
  EXPECT_LT(s.x_m, 0.01);
  std::this_thread::sleep_for(30ms);
  EXPECT_DOUBLE_EQ(rig.status().x_m, s.x_m);
  EXPECT_EQ(rig.server->stats().stops, 1u);
  auto stop_reg = rig.client->read_holding(arm::kRegStop, 1);
  ASSERT_TRUE(stop_reg.ok());
  EXPECT_EQ((*stop_reg)[0], 0);  // STOP reads 0 once stopped
}

TEST(ModbusArmServer, ReportsWorkspaceSpeedUnknownAndInjectedFaults) {
  ArmRig rig = make_arm_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.send(arm::Opcode::kHome).ok());
  rig.wait_for(arm::Motion::kHolding);
  ASSERT_TRUE(rig.send(arm::Opcode::kMoveTo, {0.5, 0, 0.25, 0}).ok());  // x max is 0.2
  EXPECT_EQ(rig.status().fault, static_cast<std::uint16_t>(arm::Fault::kOutsideWorkspace));
  ASSERT_TRUE(rig.send(arm::Opcode::kClearFault).ok());
  ASSERT_TRUE(rig.send(arm::Opcode::kMoveTo, {0.01, 0, 0.25, 0}, 5.0).ok());  // max 0.25 m/s
  EXPECT_EQ(rig.status().fault, static_cast<std::uint16_t>(arm::Fault::kSpeedOutOfRange));
  ASSERT_TRUE(rig.send(arm::Opcode::kClearFault).ok());
  ASSERT_TRUE(rig.send(static_cast<arm::Opcode>(9)).ok());
  EXPECT_EQ(rig.status().fault, static_cast<std::uint16_t>(arm::Fault::kUnknownCommand));
  ASSERT_TRUE(rig.send(arm::Opcode::kClearFault).ok());
  rig.server->inject_fault(arm::Fault::kFollowingError);
  const arm::StatusBlock s = rig.status();
  EXPECT_EQ(s.motion, arm::Motion::kFault);
  EXPECT_EQ(arm::fault_text(s.fault), "following error");
}

TEST(ModbusArmServer, ClientReconnectsWhenTheControllerComesBack) {
  ArmRig rig = make_arm_rig();
  ASSERT_TRUE(rig.client);
  ASSERT_TRUE(rig.send(arm::Opcode::kHome).ok());
  rig.server->disappear();
  EXPECT_FALSE(rig.server->online());
  auto gone = rig.client->read_status();
  ASSERT_FALSE(gone.ok());
  EXPECT_EQ(gone.status().code(), StatusCode::kUnavailable) << gone.status().to_string();
  EXPECT_FALSE(rig.client->connected());
  // Still gone: the reconnect attempt fails fast with a clear message.
  auto again = rig.client->read_status();
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.status().message().find("connect"), std::string::npos)
      << gone.status().to_string() << " / " << again.status().to_string();
  ASSERT_TRUE(rig.server->reappear().ok());
  auto back = rig.client->read_status();
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->ack_sequence, rig.seq);  // the controller kept its state
  EXPECT_EQ(rig.client->stats().connects, 2u);
  EXPECT_EQ(back->motion, arm::Motion::kStopped);  // the link watchdog stopped the homing
}

TEST(ModbusArmClient, RtuAndBadOptionsFailClearly) {
  ModbusArmOptions o;
  o.transport = "rtu";
  o.device = "/dev/hardcopy-no-such-tty";
  auto c = ModbusArmClient::create(o);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  Status st = (*c)->connect();
  EXPECT_EQ(st.code(), StatusCode::kUnavailable);
  EXPECT_NE(st.message().find("/dev/hardcopy-no-such-tty"), std::string::npos) << st.to_string();
  EXPECT_FALSE((*c)->read_status().ok());
  o.parity = "X";
  EXPECT_EQ(ModbusArmClient::create(o).status().code(), StatusCode::kInvalidArgument);
  o = {};
  o.transport = "can";
  EXPECT_FALSE(ModbusArmClient::create(o).ok());
  o = {};
  o.host = "arm.local";
  EXPECT_FALSE(ModbusArmClient::create(o).ok());
  // TCP to a port where nothing listens: kUnavailable, quickly.
  o = {};
  std::uint16_t port;
  {
    auto s = ModbusArmServer::start({});
    ASSERT_TRUE(s.ok());
    port = (*s)->port();
  }
  o.port = port;
  auto tcp = ModbusArmClient::create(o);
  ASSERT_TRUE(tcp.ok());
  EXPECT_EQ((*tcp)->connect().code(), StatusCode::kUnavailable);
}

// A third-party peer: npm's jsmodbus client drives the simulator through the documented register
// map (home, poll, stop). Skipped when node or jsmodbus is not installed under tests/interop.
TEST(ModbusArmServer, JsmodbusPeerHomesAndStopsTheArm) {
  const auto interop = hc::testing::source_dir() / "tests" / "interop";
  if (!std::filesystem::exists(interop / "node_modules" / "jsmodbus"))
    GTEST_SKIP() << "npm jsmodbus is not installed in tests/interop (npm install jsmodbus@4)";
  if (std::system("node --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "node is not installed";
  ModbusArmServerOptions so;
  so.home_speed_m_s = 1.0;
  auto server = ModbusArmServer::start(so);
  ASSERT_TRUE(server.ok());
  const std::string cmd = "timeout -k 5 60 node " + (interop / "modbus_arm_jsmodbus.cjs").string() +
                          " " + std::to_string((*server)->port()) + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string text;
  std::array<char, 4096> buf{};
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) text.append(buf.data(), n);
  const int rc = ::pclose(p);
  ASSERT_EQ(rc, 0) << text;
  const auto j = nlohmann::json::parse(text);
  EXPECT_EQ(j["map_version"], 0x0100);
  EXPECT_EQ(j["motion_before"], 0);  // idle
  EXPECT_EQ(j["homed_before"], false);
  EXPECT_EQ(j["motion_after"], 3);  // holding at home
  EXPECT_EQ(j["homed_after"], true);
  EXPECT_EQ(j["ack_seq"], j["sent_seq"]);
  EXPECT_EQ(j["x_um"], 0);
  EXPECT_EQ(j["z_um"], 250000);          // home pose z = 0.25 m
  EXPECT_EQ(j["motion_after_stop"], 4);  // stopped
  EXPECT_EQ((*server)->stats().stops, 1u);
}

}  // namespace
}  // namespace hc::rig::sim
