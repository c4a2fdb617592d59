// The arm's Modbus register map (rig_daemon/backends/arm_register_map.h): fixed-point scaling,
// word order (checked against libmodbus's own MODBUS_GET/SET_INT32 macros), command and status
// blocks, and malformed register blocks.
#include "rig_daemon/backends/arm_register_map.h"

#include <gtest/gtest.h>
#include <modbus.h>

#include <cmath>
#include <vector>

namespace hc::rig::arm {
namespace {

TEST(ArmRegisterMap, Int32WordOrderMatchesLibmodbus) {
  for (std::int32_t v : {0, 1, -1, 123456, -123456, 0x7FFFFFFF, -0x7FFFFFFF - 1, 0x00010000}) {
    std::uint16_t ours[2];
    put_i32(ours, v);
    std::uint16_t theirs[2];
    MODBUS_SET_INT32_TO_INT16(theirs, 0, static_cast<std::uint32_t>(v));
    EXPECT_EQ(ours[0], theirs[0]);
    EXPECT_EQ(ours[1], theirs[1]);
    EXPECT_EQ(get_i32(ours), v);
    EXPECT_EQ(static_cast<std::int32_t>(
                  static_cast<std::uint32_t>(MODBUS_GET_INT32_FROM_INT16(theirs, 0))),
              v);
  }
  // 0.123456 m = 123456 um = 0x0001E240: high word 0x0001, low word 0xE240.
  std::uint16_t r[2];
  put_i32(r, to_fixed(0.123456, kCountsPerMetre, "x").value());
  EXPECT_EQ(r[0], 0x0001);
  EXPECT_EQ(r[1], 0xE240);
}

TEST(ArmRegisterMap, FixedPointRoundsAndRejectsWhatDoesNotFit) {
  EXPECT_EQ(to_fixed(-0.0000004, kCountsPerMetre, "x").value(), 0);  // rounds to nearest um
  EXPECT_EQ(to_fixed(-0.0000006, kCountsPerMetre, "x").value(), -1);
  EXPECT_EQ(to_fixed(3.14159265358979, kCountsPerRadian, "yaw").value(), 3141593);
  EXPECT_FALSE(to_fixed(2148.0, kCountsPerMetre, "x").ok());  // > 2^31 um
  EXPECT_FALSE(to_fixed(std::nan(""), kCountsPerMetre, "x").ok());
  EXPECT_NE(to_fixed_unsigned(-0.1, kCountsPerMetrePerS, "speed").status().message().find("speed"),
            std::string::npos);
}

TEST(ArmRegisterMap, CommandBlockRoundTrips) {
  CommandBlock c;
  c.opcode = Opcode::kMoveTo;
  c.sequence = 65535;
  c.x_m = 0.1;
  c.y_m = -0.05;
  c.z_m = 0.2;
  c.yaw_rad = -1.5;
  c.speed_m_s = 0.02;
  c.yaw_speed_rad_s = 0.5;
  auto regs = encode_command(c);
  ASSERT_TRUE(regs.ok()) << regs.status().to_string();
  EXPECT_EQ((*regs)[kRegCommand], 2);
  EXPECT_EQ((*regs)[kRegCommandSeq], 65535);
  // y = -50000 um = 0xFFFF3CB0
  EXPECT_EQ((*regs)[kRegTargetY], 0xFFFF);
  EXPECT_EQ((*regs)[kRegTargetY + 1], 0x3CB0);
  // speed 0.02 m/s = 20000 um/s
  EXPECT_EQ((*regs)[kRegSpeed], 0);
  EXPECT_EQ((*regs)[kRegSpeed + 1], 20000);
  auto back = decode_command(*regs);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->opcode, Opcode::kMoveTo);
  EXPECT_DOUBLE_EQ(back->x_m, 0.1);
  EXPECT_DOUBLE_EQ(back->y_m, -0.05);
  EXPECT_DOUBLE_EQ(back->yaw_rad, -1.5);
  EXPECT_DOUBLE_EQ(back->speed_m_s, 0.02);
  EXPECT_FALSE(encode_command(CommandBlock{}).ok());  // no opcode
  c.speed_m_s = -1;
  EXPECT_FALSE(encode_command(c).ok());
  const std::vector<std::uint16_t> short_block(13);
  EXPECT_FALSE(decode_command(short_block).ok());
}

TEST(ArmRegisterMap, StatusBlockRoundTripsAndMalformedBlocksFail) {
  StatusBlock s;
  s.motion = Motion::kMoving;
  s.fault = 0;
  s.homed = true;
  s.in_motion = true;
  s.ack_sequence = 7;
  s.x_m = -0.2;
  s.z_m = 0.3;
  s.yaw_rad = 0.25;
  s.speed_m_s = 0.05;
  s.uptime_ms = 0xDEADBEEF;
  s.heartbeat = 42;
  auto regs = encode_status(s);
  EXPECT_EQ(regs[kInMapVersion], 0x0100);
  EXPECT_EQ(regs[kInFlags], 3);
  EXPECT_EQ(regs[kInUptime], 0xDEAD);
  EXPECT_EQ(regs[kInUptime + 1], 0xBEEF);
  auto back = decode_status(regs);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->motion, Motion::kMoving);
  EXPECT_TRUE(back->homed);
  EXPECT_DOUBLE_EQ(back->x_m, -0.2);
  EXPECT_DOUBLE_EQ(back->z_m, 0.3);
  EXPECT_DOUBLE_EQ(back->yaw_rad, 0.25);
  EXPECT_EQ(back->uptime_ms, 0xDEADBEEFu);
  EXPECT_EQ(back->heartbeat, 42);

  auto bad = regs;
  bad[kInMapVersion] = 0x0200;
  EXPECT_NE(decode_status(bad).status().message().find("version 2.0"), std::string::npos);
  bad = regs;
  bad[kInMotion] = 6;
  EXPECT_FALSE(decode_status(bad).ok());
  bad = regs;
  bad[kInFlags] = 4;
  EXPECT_FALSE(decode_status(bad).ok());
  EXPECT_FALSE(decode_status(std::span<const std::uint16_t>(regs.data(), 17)).ok());
  // A minor version bump (1.1) still decodes.
  bad = regs;
  bad[kInMapVersion] = 0x0101;
  EXPECT_TRUE(decode_status(bad).ok());
}

TEST(ArmRegisterMap, FaultTexts) {
  EXPECT_EQ(fault_text(0), "");
  EXPECT_EQ(fault_text(1), "target outside the workspace");
  EXPECT_EQ(fault_text(6), "emergency stop");
  EXPECT_EQ(fault_text(99), "unknown fault 99");
}

}  // namespace
}  // namespace hc::rig::arm
