// Hardware-in-the-loop: the "modbus" arm backend (through the devices interface and the backend
// registry) against the Modbus TCP arm simulator on 127.0.0.1: homing, moves at finite speed,
// limits, stop from another thread, and a controller that disappears and comes back.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "rig_daemon/backends/hardware_backends.h"
#include "rig_daemon/devices/registry.h"
#include "rig_daemon/simulators/modbus_arm_server.h"

namespace hc::rig {
namespace {

using namespace std::chrono_literals;
using devices::ArmCommand;
using devices::ArmMotion;
using devices::ArmState;
using devices::DeviceState;

struct ArmFixture {
  std::unique_ptr<sim::ModbusArmServer> server;
  std::unique_ptr<devices::Arm> arm;
  std::uint64_t seq = 100;

  Status send(ArmCommand::Type type, devices::ArmPose target = {}, double speed = 0) {
    ArmCommand c;
    c.type = type;
    c.target = target;
    c.speed_m_s = speed;
    c.sequence = ++seq;
    return arm->write(c);
  }
  ArmState wait_for(ArmMotion m) {
    const auto end = std::chrono::steady_clock::now() + 2s;
    ArmState s;
    while (std::chrono::steady_clock::now() < end) {
      auto r = arm->read();
      if (!r.ok()) break;
      s = *r;
      if (s.motion == m) break;
      std::this_thread::sleep_for(2ms);
    }
    return s;
  }
};

ArmFixture make_arm_fixture() {
  ArmFixture f;
  sim::ModbusArmServerOptions so;
  so.home_speed_m_s = 1.0;
  auto server = sim::ModbusArmServer::start(so);
  EXPECT_TRUE(server.ok()) << server.status().to_string();
  if (!server.ok()) return f;
  f.server = std::move(*server);
  devices::BackendRegistry registry;
  EXPECT_TRUE(register_hardware_backends(registry).ok());
  devices::DeviceContext ctx;
  ctx.name = "arm";
  ctx.backend = "modbus";
  auto arm = registry.create<devices::Arm>(ctx);
  EXPECT_TRUE(arm.ok()) << arm.status().to_string();
  f.arm = std::move(*arm);
  Status s = devices::configure_from_yaml(
      *f.arm, "transport: tcp\nhost: 127.0.0.1\nport: " + std::to_string(f.server->port()) +
                  "\nmax_speed_m_s: 0.2\nresponse_timeout_s: 0.2\nconnect_timeout_s: 0.2\n");
  EXPECT_TRUE(s.ok()) << s.to_string();
  return f;
}

TEST(ModbusArmBackend, HomesAndMovesToPoseAtFiniteSpeed) {
  ArmFixture f = make_arm_fixture();
  ASSERT_TRUE(f.arm);
  ASSERT_TRUE(f.arm->activate().ok()) << f.arm->error().to_string();
  auto first = f.arm->read();
  ASSERT_TRUE(first.ok());
  EXPECT_FALSE(first->homed);
  EXPECT_EQ(first->motion, ArmMotion::kIdle);
  ASSERT_TRUE(f.send(ArmCommand::Type::kHome).ok());
  ArmState s = f.wait_for(ArmMotion::kHolding);
  ASSERT_EQ(s.motion, ArmMotion::kHolding);
  EXPECT_TRUE(s.homed);
  EXPECT_EQ(s.command_sequence, f.seq);  // echoed through the 16-bit COMMAND_SEQ register
  EXPECT_NEAR(s.pose.z_m, 0.25, 1e-6);
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(f.send(ArmCommand::Type::kMoveTo, {0.01, -0.01, 0.2, 0.1}, 0.2).ok());
  s = f.wait_for(ArmMotion::kHolding);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(s.motion, ArmMotion::kHolding);
  EXPECT_NEAR(s.pose.x_m, 0.01, 1e-6);
  EXPECT_NEAR(s.pose.y_m, -0.01, 1e-6);
  EXPECT_NEAR(s.pose.z_m, 0.2, 1e-6);
  EXPECT_NEAR(s.pose.yaw_rad, 0.1, 1e-6);
  EXPECT_NEAR(s.target.x_m, 0.01, 1e-9);
  // sqrt(0.01^2 + 0.01^2 + 0.05^2) = 0.05196 m at 0.2 m/s = 0.26 s (yaw 0.1 rad at 1 rad/s: 0.1 s).
  EXPECT_GT(took_s, 0.2);
  EXPECT_LT(took_s, 1.0);
  EXPECT_GT(*s.device_stamp_ns, 0);
  EXPECT_EQ(f.arm->stats().received, s.sequence + 1);
}

TEST(ModbusArmBackend, RefusesTargetsOutsideTheLimitsAndReportsControllerFaults) {
  ArmFixture f = make_arm_fixture();
  ASSERT_TRUE(f.arm);
  ASSERT_TRUE(f.arm->activate().ok());
  Status s = f.send(ArmCommand::Type::kMoveTo, {0.5, 0, 0.1, 0});
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  s = f.send(ArmCommand::Type::kSetSpeed, {}, 1.0);  // above max_speed_m_s 0.2
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(f.arm->state(), DeviceState::kActive);
  // Not homed: the controller latches fault 4, reported with its text.
  ASSERT_TRUE(f.send(ArmCommand::Type::kMoveTo, {0.01, 0, 0.1, 0}).ok());
  auto st = f.arm->read();
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(st->motion, ArmMotion::kFault);
  EXPECT_EQ(st->fault_code, 4u);
  EXPECT_EQ(st->fault, "move before homing");
  ASSERT_TRUE(f.send(ArmCommand::Type::kClearFault).ok());
  EXPECT_EQ(f.arm->read()->motion, ArmMotion::kIdle);
}

TEST(ModbusArmBackend, StopFromAnotherThreadHaltsAMove) {
  ArmFixture f = make_arm_fixture();
  ASSERT_TRUE(f.arm);
  ASSERT_TRUE(f.arm->activate().ok());
  ASSERT_TRUE(f.send(ArmCommand::Type::kHome).ok());
  f.wait_for(ArmMotion::kHolding);
  ASSERT_TRUE(f.send(ArmCommand::Type::kMoveTo, {0.15, 0, 0.25, 0}, 0.05).ok());  // 3 s move
  std::thread stopper([&] {
    std::this_thread::sleep_for(30ms);
    EXPECT_TRUE(f.arm->stop().ok());
  });
  const ArmState s = f.wait_for(ArmMotion::kStopped);
  stopper.join();
  EXPECT_EQ(s.motion, ArmMotion::kStopped);
  EXPECT_LT(s.pose.x_m, 0.02);
  EXPECT_EQ(f.server->stats().stops, 1u);
}

TEST(ModbusArmBackend, ControllerThatDisappearsIsReportedAndRecoveredByReset) {
  ArmFixture f = make_arm_fixture();
  ASSERT_TRUE(f.arm);
  ASSERT_TRUE(f.arm->activate().ok());
  ASSERT_TRUE(f.send(ArmCommand::Type::kHome).ok());
  f.wait_for(ArmMotion::kHolding);
  ASSERT_TRUE(f.send(ArmCommand::Type::kMoveTo, {0.05, 0, 0.25, 0}, 0.05).ok());
  std::this_thread::sleep_for(50ms);
  auto before = f.arm->read();
  ASSERT_TRUE(before.ok());
  f.server->disappear();
  auto gone = f.arm->read();
  ASSERT_FALSE(gone.ok());
  EXPECT_EQ(gone.status().code(), StatusCode::kUnavailable) << gone.status().to_string();
  EXPECT_EQ(f.arm->state(), DeviceState::kError);
  EXPECT_FALSE(f.arm->stop().ok());   // tried (bounded by the connect timeout), reported
  EXPECT_FALSE(f.arm->reset().ok());  // still gone: stays in kError
  EXPECT_EQ(f.arm->state(), DeviceState::kError);
  ASSERT_TRUE(f.server->reappear().ok());
  ASSERT_TRUE(f.arm->reset().ok()) << f.arm->error().to_string();
  ASSERT_TRUE(f.arm->activate().ok());
  auto back = f.arm->read();
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  // The controller's watchdog stopped the move when the link went down; it kept its pose.
  EXPECT_EQ(back->motion, ArmMotion::kStopped);
  EXPECT_GE(back->pose.x_m, before->pose.x_m);
  EXPECT_LT(back->pose.x_m, 0.05);
  EXPECT_TRUE(back->homed);
  // And it obeys again.
  ASSERT_TRUE(f.send(ArmCommand::Type::kMoveTo, {0.0, 0, 0.25, 0}, 0.2).ok());
  EXPECT_EQ(f.wait_for(ArmMotion::kHolding).motion, ArmMotion::kHolding);
  EXPECT_EQ(f.arm->stats().errors, 1u);
}

TEST(ModbusArmBackend, RtuWithoutASerialPortFailsToActivateClearly) {
  devices::BackendRegistry registry;
  ASSERT_TRUE(register_hardware_backends(registry).ok());
  devices::DeviceContext ctx;
  ctx.name = "arm";
  ctx.backend = "modbus";
  auto arm = registry.create<devices::Arm>(ctx);
  ASSERT_TRUE(arm.ok());
  ASSERT_TRUE(devices::configure_from_yaml(**arm,
                                           "transport: rtu\ndevice: /dev/hardcopy-nope\n"
                                           "baud: 19200\nparity: E\n")
                  .ok());
  Status s = (*arm)->activate();
  EXPECT_EQ(s.code(), StatusCode::kUnavailable);
  EXPECT_NE(s.message().find("rtu:/dev/hardcopy-nope 19200 8E1"), std::string::npos)
      << s.to_string();
  auto fresh = registry.create<devices::Arm>(ctx);
  ASSERT_TRUE(fresh.ok());
  EXPECT_FALSE(devices::configure_from_yaml(**fresh, "transport: rtu\nparity: Q\n").ok());
  Status bad = devices::configure_from_yaml(**fresh,
                                            "workspace_min_m: [0, 0, 0]\n"
                                            "workspace_max_m: [0.1, -0.1, 0.1]\n");
  EXPECT_NE(bad.message().find("workspace"), std::string::npos) << bad.to_string();
}

}  // namespace
}  // namespace hc::rig
