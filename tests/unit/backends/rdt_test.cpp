// RDT codec: byte layouts from ../shared/data/protocols/RDT_PROTOCOL_NOTES.md (8-byte request,
// 36-byte big-endian record), conversion to SI, calibration XML, and sequence accounting.
#include "rig_daemon/backends/rdt.h"

#include <gtest/gtest.h>

#include <vector>

namespace hc::rig::rdt {
namespace {

TEST(RdtRequest, EncodesStartRealtimeAsInTheRosDriver) {
  // ROS netft_rdt_driver sends {0x12,0x34, 0x00,0x02, 0,0,0,0} to start streaming forever.
  const auto bytes = encode_request({0x0002, 0});
  const std::array<std::uint8_t, 8> expected{0x12, 0x34, 0x00, 0x02, 0, 0, 0, 0};
  EXPECT_EQ(bytes, expected);
  const auto bias = encode_request({0x0042, 0x01020304});
  const std::array<std::uint8_t, 8> expected_bias{0x12, 0x34, 0x00, 0x42, 1, 2, 3, 4};
  EXPECT_EQ(bias, expected_bias);
}

TEST(RdtRequest, DecodeRoundTripsAndRejectsMalformed) {
  for (std::uint16_t c : {0x0, 0x2, 0x3, 0x4, 0x41, 0x42}) {
    const Request r{c, 1000};
    const auto bytes = encode_request(r);
    auto back = decode_request(bytes);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    EXPECT_EQ(*back, r);
  }
  const std::vector<std::uint8_t> short_req{0x12, 0x34, 0, 2};
  EXPECT_EQ(decode_request(short_req).status().code(), StatusCode::kInvalidArgument);
  const std::vector<std::uint8_t> bad_header{0x43, 0x21, 0, 2, 0, 0, 0, 0};
  EXPECT_NE(decode_request(bad_header).status().message().find("header"), std::string::npos);
  const std::vector<std::uint8_t> unknown{0x12, 0x34, 0, 7, 0, 0, 0, 0};
  EXPECT_EQ(decode_request(unknown).status().code(), StatusCode::kInvalidArgument);
  const std::vector<std::uint8_t> extended{0x12, 0x34, 0x80, 0x02, 0, 0, 0, 0};
  EXPECT_EQ(decode_request(extended).status().code(), StatusCode::kUnsupported);
  // The ROS client's byte-duplicating pack() is only right for count 0, which is what it sends.
  const std::vector<std::uint8_t> ros_quirk{0x12, 0x34, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00};
  ASSERT_TRUE(decode_request(ros_quirk).ok());
  EXPECT_EQ(decode_request(ros_quirk)->sample_count, 0u);
}

TEST(RdtRecord, DecodesBigEndianFieldsAtTheDocumentedOffsets) {
  // Offsets 0/4/8: rdt_sequence, ft_sequence, status; 12..32: Fx..Tz as int32, big-endian.
  const std::vector<std::uint8_t> bytes{
      0x00, 0x00, 0x00, 0x01,  // rdt_sequence 1
      0x00, 0x01, 0x00, 0x00,  // ft_sequence 65536
      0x80, 0x00, 0x00, 0x00,  // status 0x80000000
      0x00, 0x00, 0x00, 0x0A,  // Fx 10
      0xFF, 0xFF, 0xFF, 0xF6,  // Fy -10
      0x7F, 0xFF, 0xFF, 0xFF,  // Fz INT32_MAX
      0x80, 0x00, 0x00, 0x00,  // Tx INT32_MIN
      0x00, 0x00, 0x01, 0x00,  // Ty 256
      0x01, 0x02, 0x03, 0x04,  // Tz 0x01020304
  };
  ASSERT_EQ(bytes.size(), kRecordBytes);
  auto records = decode_records(bytes);
  ASSERT_TRUE(records.ok()) << records.status().to_string();
  ASSERT_EQ(records->size(), 1u);
  const Record& r = (*records)[0];
  EXPECT_EQ(r.rdt_sequence, 1u);
  EXPECT_EQ(r.ft_sequence, 65536u);
  EXPECT_EQ(r.status, 0x80000000u);
  EXPECT_EQ(r.counts,
            (std::array<std::int32_t, 6>{10, -10, 2147483647, -2147483647 - 1, 256, 0x01020304}));
  EXPECT_EQ(encode_records(*records), bytes);
}

TEST(RdtRecord, BufferedPacketsCarrySeveralRecordsAndBadSizesFail) {
  std::vector<Record> in(5);
  for (std::size_t i = 0; i < in.size(); ++i) {
    in[i].rdt_sequence = static_cast<std::uint32_t>(i + 1);
    in[i].counts[2] = -static_cast<std::int32_t>(i * 1000);
  }
  const auto bytes = encode_records(in);
  EXPECT_EQ(bytes.size(), 5 * kRecordBytes);
  auto out = decode_records(bytes);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(*out, in);
  EXPECT_FALSE(decode_records({}).ok());
  const std::vector<std::uint8_t> truncated(bytes.begin(), bytes.end() - 1);
  EXPECT_NE(decode_records(truncated).status().message().find("36-byte"), std::string::npos);
  const std::vector<std::uint8_t> huge((kMaxRecordsPerPacket + 1) * kRecordBytes);
  EXPECT_FALSE(decode_records(huge).ok());
}

TEST(RdtUnits, CountsToSiFollowTheCalibration) {
  // ROS driver defaults: 1e6 counts per N and 1e6 counts per N m would give 35 N for 35e6 counts.
  Calibration c{1e6, 1e3, "N", "Nmm"};  // the loopback sample document: cpf 1e6, cpt 1e3, N, Nmm
  const Wrench w = to_si({35'000'000, -1'500'000, 0, 2000, 0, -500}, c);
  EXPECT_DOUBLE_EQ(w.force_n[0], 35.0);
  EXPECT_DOUBLE_EQ(w.force_n[1], -1.5);
  EXPECT_DOUBLE_EQ(w.torque_nm[0], 2e-3);  // 2000 counts / 1000 = 2 N mm = 0.002 N m
  EXPECT_DOUBLE_EQ(w.torque_nm[2], -0.5e-3);
  // 1 lbf = 4.4482216152605 N exactly (NIST SP 811, B.8); 1 lbf in = 0.112984829027617 N m.
  Calibration imperial{1e6, 1e6, "lbf", "lbfin"};
  const Wrench wi = to_si({1'000'000, 0, 0, 1'000'000, 0, 0}, imperial);
  EXPECT_NEAR(wi.force_n[0], 4.4482216152605, 1e-12);
  EXPECT_NEAR(wi.torque_nm[0], 0.112984829027617, 1e-12);
  // to_counts inverts to within one count and saturates.
  const auto counts = to_counts(w, c);
  EXPECT_EQ(counts, (std::array<std::int32_t, 6>{35'000'000, -1'500'000, 0, 2000, 0, -500}));
  Wrench big;
  big.force_n[0] = 1e9;
  EXPECT_EQ(to_counts(big, c)[0], 2147483647);
}

TEST(RdtCalibration, ParsesTheSensorDocumentAndNamesMissingFields) {
  const std::string xml =
      "<netft><cfgcpf>1000000</cfgcpf><cfgcpt>1000</cfgcpt><scfgfu>N</scfgfu>"
      "<scfgtu>Nmm</scfgtu></netft>";
  auto c = parse_calibration_xml(xml);
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  EXPECT_EQ(*c, (Calibration{1e6, 1e3, "N", "Nmm"}));
  auto again = parse_calibration_xml(calibration_xml(*c));
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, *c);
  EXPECT_NE(
      parse_calibration_xml("<netft><cfgcpt>1</cfgcpt></netft>").status().message().find("cfgcpf"),
      std::string::npos);
  EXPECT_FALSE(parse_calibration_xml(
                   "<cfgcpf>-5</cfgcpf><cfgcpt>1</cfgcpt><scfgfu>N</scfgfu><scfgtu>Nm</scfgtu>")
                   .ok());
  EXPECT_FALSE(
      parse_calibration_xml(
          "<cfgcpf>5</cfgcpf><cfgcpt>1</cfgcpt><scfgfu>furlong</scfgfu><scfgtu>Nm</scfgtu>")
          .ok());
  EXPECT_FALSE(validate(Calibration{0, 1, "N", "Nm"}).ok());
}

TEST(RdtSequence, CountsGapsAsLostAndRecoversReorderedPackets) {
  SequenceTracker t;
  using V = SequenceTracker::Verdict;
  EXPECT_EQ(t.update(1), V::kFirst);
  EXPECT_EQ(t.update(2), V::kInOrder);
  EXPECT_EQ(t.update(5), V::kInOrder);  // 3 and 4 missing
  EXPECT_EQ(t.lost(), 2u);
  EXPECT_EQ(t.update(4), V::kLate);  // 4 arrives late: no longer lost
  EXPECT_EQ(t.lost(), 1u);
  EXPECT_EQ(t.update(4), V::kDuplicate);
  EXPECT_EQ(t.update(5), V::kDuplicate);
  EXPECT_EQ(t.lost(), 1u);
  EXPECT_EQ(t.update(200), V::kInOrder);
  EXPECT_EQ(t.lost(), 1u + 194u);
  EXPECT_EQ(t.update(3), V::kStale);  // older than the 64-packet window
  // Settled losses: gaps that left the 64-packet window and can no longer be filled.
  SequenceTracker g;
  g.update(1);
  g.update(4);  // 2, 3 missing
  EXPECT_EQ(g.lost(), 2u);
  EXPECT_EQ(g.settled_lost(), 0u);
  g.update(3);                                          // 3 late
  for (std::uint32_t s = 5; s <= 65; ++s) g.update(s);  // 2 is 63 behind 65: still fillable
  EXPECT_EQ(g.settled_lost(), 0u);
  g.update(66);  // 2 is now 64 behind: out of the window
  EXPECT_EQ(g.settled_lost(), 1u);
  EXPECT_EQ(g.lost(), 1u);
  g.update(1000);  // 933 missing, 933 - 63 = 870 of them beyond the window at once
  EXPECT_EQ(g.lost(), 1u + 933u);
  EXPECT_EQ(g.settled_lost(), 1u + 870u);
  for (std::uint32_t s = 1001; s <= 1064; ++s) g.update(s);
  EXPECT_EQ(g.settled_lost(), g.lost());
  // Wrap-around at 2^32 is not a gap (int32 difference, as in the ROS driver).
  SequenceTracker w;
  w.update(0xFFFFFFFEu);
  EXPECT_EQ(w.update(0xFFFFFFFFu), V::kInOrder);
  EXPECT_EQ(w.update(0u), V::kInOrder);
  EXPECT_EQ(w.update(1u), V::kInOrder);
  EXPECT_EQ(w.lost(), 0u);
}

}  // namespace
}  // namespace hc::rig::rdt
