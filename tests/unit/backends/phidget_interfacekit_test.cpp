// Phidget InterfaceKit 8/8/8 report decoding (layout of libphidget21's cphidgetinterfacekit.c,
// firmware 900-999), on hand-assembled reports, plus malformed reports.
#include "rig_daemon/backends/phidget_interfacekit.h"

#include <gtest/gtest.h>

#include <vector>

namespace hc::rig::phidget {
namespace {

TEST(PhidgetReport, DecodesAHandAssembledReport) {
  // Sensor 0: two samples 0xABC, 0xFFF; sensor 1: one sample 0x123. Interleaved by sample index:
  // s0[0] (even: bytes BC A_), s1[0] (odd: low nibble of the previous byte, then 23),
  // s0[1] (even: FF F_).
  const std::vector<std::uint8_t> report = {
      0x80 | 0x10 | 0x01,  // counter 2, ratiometric, overrun flag for sensors 0/1
      0xFE,                // inputs: bit 0 clear -> input 0 on, the rest off
      0x05,                // outputs 0 and 2 on
      0x30,                // overruns: sensor 0 dropped 3 samples, sensor 1 none
      0x21,
      0x00,
      0x00,
      0x00,  // counts: sensor 0: 2, sensor 1: 1
      0xBC,
      0xA1,
      0x23,  // 0xABC, 0x123
      0xFF,
      0xF0,  // 0xFFF
  };
  auto r = decode_report(report);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->packet_counter, 2);
  EXPECT_TRUE(r->ratiometric);
  EXPECT_FALSE(r->overcurrent);
  EXPECT_TRUE(r->inputs[0]);
  EXPECT_FALSE(r->inputs[1]);
  EXPECT_TRUE(r->outputs[0]);
  EXPECT_FALSE(r->outputs[1]);
  EXPECT_TRUE(r->outputs[2]);
  EXPECT_EQ(r->overruns[0], 3);
  EXPECT_EQ(r->raw[0], (std::vector<std::uint16_t>{0xABC, 0xFFF}));
  EXPECT_EQ(r->raw[1], (std::vector<std::uint16_t>{0x123}));
  for (int i = 2; i < kSensors; ++i) EXPECT_TRUE(r->raw[i].empty());
  // The encoder writes the same bytes.
  auto again = encode_report(*r);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, report);
}

TEST(PhidgetReport, SensorValueFollowsLibphidget21) {
  // value = round(raw * 1.001 / 4.095), clamped to 1000 (cphidgetinterfacekit.c).
  EXPECT_EQ(sensor_value(0), 0u);
  EXPECT_EQ(sensor_value(2748), 672u);   // 2748 * 1.001 / 4.095 = 671.72
  EXPECT_EQ(sensor_value(2048), 501u);   // 500.63
  EXPECT_EQ(sensor_value(4091), 1000u);  // 1000.02
  EXPECT_EQ(sensor_value(4095), 1000u);  // 1001 clamped
  EXPECT_EQ(sensor_value(70000), 1000u);
}

TEST(PhidgetReport, FullReportRoundTripsAcrossAllSensors) {
  InterfaceKitReport in;
  in.packet_counter = 3;
  in.overcurrent = true;
  for (int i = 0; i < kSensors; ++i)
    for (int j = 0; j <= i; ++j) in.raw[i].push_back(static_cast<std::uint16_t>(i * 500 + j * 7));
  in.overruns[7] = 15;
  auto bytes = encode_report(in);
  ASSERT_TRUE(bytes.ok());
  // 36 samples x 1.5 bytes + 3 header + 1 overrun + 4 counts = 62 bytes.
  EXPECT_EQ(bytes->size(), 62u);
  auto out = decode_report(*bytes);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->raw, in.raw);
  EXPECT_EQ(out->overruns, in.overruns);
  EXPECT_TRUE(out->overcurrent);
}

TEST(PhidgetReport, MalformedReportsFail) {
  EXPECT_FALSE(decode_report(std::vector<std::uint8_t>{0x00, 0xFF}).ok());
  // Overrun flag set but no overrun byte.
  EXPECT_FALSE(decode_report(std::vector<std::uint8_t>{0x0F, 0xFF, 0x00}).ok());
  // Counts announce 15 + 15 samples that are not there.
  auto r = decode_report(std::vector<std::uint8_t>{0x00, 0xFF, 0x00, 0xFF, 0x00, 0x00, 0x00, 1});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("30 samples"), std::string::npos) << r.status().to_string();
  InterfaceKitReport big;
  big.raw[0].assign(16, 1);
  EXPECT_FALSE(encode_report(big).ok());
  big.raw[0].assign(1, 0x1000);
  EXPECT_FALSE(encode_report(big).ok());
}

TEST(PhidgetReport, PacketCounterCountsLostReports) {
  PacketCounter c;
  EXPECT_EQ(c.update(0), 0u);
  EXPECT_EQ(c.update(1), 0u);
  EXPECT_EQ(c.update(3), 1u);  // 2 missing
  EXPECT_EQ(c.update(0), 0u);  // wraps 3 -> 0
  EXPECT_EQ(c.update(0), 3u);  // 1, 2, 3 missing
}

TEST(PhidgetUsb, NoBoardIsAClearError) {
  auto kit = InterfaceKitUsb::open();
  if (kit.ok()) GTEST_SKIP() << "a real InterfaceKit 8/8/8 is connected";
  EXPECT_TRUE(kit.status().code() == StatusCode::kNotFound ||
              kit.status().code() == StatusCode::kUnavailable)
      << kit.status().to_string();
  EXPECT_NE(kit.status().message().find("InterfaceKit"), std::string::npos);
}

}  // namespace
}  // namespace hc::rig::phidget
