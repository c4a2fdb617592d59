// Interop with the npm reference implementation: @mcap/core's McapIndexedReader (through
// tests/interop/read_mcap.mjs) reads sessions our writer produced with zstd, lz4 and no
// compression, and reports the same per-channel message counts; protobufjs decodes our
// foxglove.RawImage / CompressedImage frames with the FileDescriptorSet our schemas carry (the way
// Foxglove does). Skips only when node is not installed.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>

#include "cli_run.h"
#include "common/json.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"
#include "test_data.h"

namespace hc::recording {
namespace {

const std::filesystem::path kInterop = HARDCOPY_INTEROP_DIR;

bool have_node() { return std::system("node --version >/dev/null 2>&1") == 0; }

// The peer's stdout and stderr together.
hc::testing::CliRun run(const std::string& cmd) { return hc::testing::run_command(cmd + " 2>&1"); }

struct Expected {
  std::map<std::string, int> counts;
};

// JSON force samples, mono8 RawImage frames, JPEG-ish CompressedImage frames, metadata and an
// attachment; chunks small enough that every file has many.
Expected write_session(const std::filesystem::path& path, Compression c, int threads) {
  McapWriter::Options opt;
  opt.compression = c;
  opt.chunk_size = 16 * 1024;
  opt.compression_threads = threads;
  opt.library = "hardcopy interop test";
  auto w = McapWriter::open(path, opt);
  EXPECT_TRUE(w.ok());
  auto& writer = **w;
  const std::string js = json_schema_for("hardcopy.Wrench", {{"fx", JsonFieldType::kNumber, "N"},
                                                             {"fz", JsonFieldType::kNumber, "N"}});
  const auto s_json =
      writer.add_schema("hardcopy.Wrench", kJsonSchemaEncoding, Bytes(js.begin(), js.end()))
          .value();
  const auto s_raw =
      writer.add_schema(kRawImageSchemaName, kProtobufEncoding, raw_image_schema()).value();
  const auto s_cmp =
      writer.add_schema(kCompressedImageSchemaName, kProtobufEncoding, compressed_image_schema())
          .value();
  const auto ft = writer.add_channel("/ft/wrench", kJsonEncoding, s_json).value();
  const auto fsr = writer.add_channel("/fsr/raw", kJsonEncoding, s_json).value();
  const auto cam = writer.add_channel("/camera/0/image", kProtobufEncoding, s_raw).value();
  const auto jpg = writer.add_channel("/camera/1/compressed", kProtobufEncoding, s_cmp).value();
  writer.add_channel("/unused", kJsonEncoding, s_json).value();
  EXPECT_TRUE(writer.write_metadata(kMetadataRigConfig, {{"yaml", "cameras: 2"}}).ok());
  Expected e;
  Bytes frame;
  for (int i = 0; i < 2100; ++i) {  // 0.3 s of F/T at 7 kHz
    const std::uint64_t t =
        1'700'000'000'000'000'000ull + static_cast<std::uint64_t>(i) * 142'857ull;
    EXPECT_TRUE(
        writer.write_message(ft, t, t, json_message(Json{{"fx", 0.1 * i}, {"fz", -0.2 * i}})).ok());
    ++e.counts["/ft/wrench"];
    if (i % 7 == 0) {
      EXPECT_TRUE(writer.write_message(fsr, t, t, json_message(Json{{"fx", 0}, {"fz", i}})).ok());
      ++e.counts["/fsr/raw"];
    }
    if (i % 467 == 0) {  // ~15 fps
      Bytes px(160 * 120);
      for (std::size_t k = 0; k < px.size(); ++k)
        px[k] = static_cast<std::uint8_t>(k ^ static_cast<std::size_t>(i));
      encode_raw_image_view(static_cast<std::int64_t>(t), "camera0", 160, 120, "mono8", 160, px,
                            frame);
      EXPECT_TRUE(writer.write_message(cam, t, t, frame).ok());
      ++e.counts["/camera/0/image"];
      CompressedImage ci{
          static_cast<std::int64_t>(t), "camera1", {0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3, 4, 5}, "jpeg"};
      encode_compressed_image(ci, frame);
      EXPECT_TRUE(writer.write_message(jpg, t, t, frame).ok());
      ++e.counts["/camera/1/compressed"];
    }
  }
  e.counts["/unused"] = 0;
  EXPECT_TRUE(
      writer.write_attachment("calibration.yaml", "application/yaml", 1, 2, Bytes{'a'}).ok());
  EXPECT_TRUE(writer.write_metadata(kMetadataDeviceStats, {{"ft0.lost", "0"}}).ok());
  EXPECT_TRUE(writer.close().ok());
  return e;
}

class NpmReader : public ::testing::TestWithParam<std::pair<Compression, int>> {};

TEST_P(NpmReader, ReadsOurSessionsWithSameCounts) {
  if (!have_node()) GTEST_SKIP() << "node is not installed: the npm reference reader cannot run";
  ASSERT_TRUE(std::filesystem::exists(kInterop / "node_modules" / "@mcap" / "core"))
      << "npm peers missing: run `npm ci --prefix tests/interop` (scripts/setup does)";
  testing::ScratchDir dir;
  const auto path = dir / "session.mcap";
  const Expected e = write_session(path, GetParam().first, GetParam().second);
  // Bounded: once (of many runs, under heavy machine load) the node peer slept in its event loop
  // forever after loading its decompressors; a hang of the peer is retried once, then fails.
  const std::string cmd =
      "timeout -k 5 60 node " + (kInterop / "read_mcap.mjs").string() + " " + path.string();
  hc::testing::CliRun r = run(cmd);
  if (r.exit_code == 124) r = run(cmd);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = parse_json(r.out, "read_mcap.mjs output");
  ASSERT_TRUE(j.ok()) << r.out;
  int total = 0;
  for (const auto& [topic, n] : e.counts) {
    EXPECT_EQ((*j)["channels"][topic].get<int>(), n) << topic;
    total += n;
  }
  EXPECT_EQ((*j)["channels"].size(), e.counts.size());
  EXPECT_EQ((*j)["messages"].get<int>(), total);
  EXPECT_TRUE((*j)["log_time_ordered"].get<bool>());
  EXPECT_EQ((*j)["library"], "hardcopy interop test");
  EXPECT_GT((*j)["chunks"].get<int>(), 5);
  EXPECT_EQ((*j)["statistics"]["message_count"], std::to_string(total));
  EXPECT_EQ((*j)["metadata"], Json::array({"rig_config", "device_stats"}));
  EXPECT_EQ((*j)["attachments"], Json::array({"calibration.yaml"}));
  // Frames decoded by protobufjs from our descriptor.
  const Json& raw = (*j)["images"]["/camera/0/image"];
  EXPECT_EQ(raw["decoded"].get<int>(), e.counts.at("/camera/0/image"));
  EXPECT_EQ(raw["width"], 160);
  EXPECT_EQ(raw["height"], 120);
  EXPECT_EQ(raw["encoding"], "mono8");
  EXPECT_EQ(raw["frame_id"], "camera0");
  EXPECT_EQ(raw["data_length"], 160 * 120);
  // Last frame is i = 1868: bytes k ^ 1868 (low byte 0x4C).
  EXPECT_EQ(raw["first_bytes"], Json::array({0x4C, 0x4D, 0x4E, 0x4F, 0x48, 0x49, 0x4A, 0x4B}));
  // timestamp of i = 1868: 1.7e18 + 1868 * 142857 ns.
  const std::uint64_t t_last = 1'700'000'000'000'000'000ull + 1868ull * 142'857ull;
  EXPECT_EQ(raw["timestamp"]["seconds"], std::to_string(t_last / 1'000'000'000ull));
  EXPECT_EQ(raw["timestamp"]["nanos"].get<std::uint64_t>(), t_last % 1'000'000'000ull);
  const Json& cmp = (*j)["images"]["/camera/1/compressed"];
  EXPECT_EQ(cmp["decoded"].get<int>(), e.counts.at("/camera/1/compressed"));
  EXPECT_EQ(cmp["format"], "jpeg");
  EXPECT_EQ(cmp["frame_id"], "camera1");
  EXPECT_EQ(cmp["first_bytes"], Json::array({0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3, 4}));
}

INSTANTIATE_TEST_SUITE_P(Compressions, NpmReader,
                         ::testing::Values(std::pair{Compression::kZstd, 0},
                                           std::pair{Compression::kLz4, 0},
                                           std::pair{Compression::kNone, 0},
                                           std::pair{Compression::kZstd, 2}),
                         [](const auto& p) {
                           return std::string(compression_display_name(p.param.first)) +
                                  (p.param.second > 0 ? "_threads" : "");
                         });

}  // namespace
}  // namespace hc::recording
