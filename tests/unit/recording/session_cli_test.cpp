// `hardcopy session ...` as a user runs it: exit codes 0 / 1 / 2, --json output, recover + verify
// on a cut-off file, export.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <iterator>

#include "cli_run.h"
#include "common/json.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"
#include "test_data.h"

namespace hc::recording {
namespace {

using hc::testing::CliRun;
using hc::testing::hardcopy;

void make_session(const std::filesystem::path& path) {
  McapWriter::Options opt;
  opt.chunk_size = 2000;
  auto w = McapWriter::open(path, opt);
  ASSERT_TRUE(w.ok());
  const std::string js =
      json_schema_for("hardcopy.Fsr", {{"raw", JsonFieldType::kInteger, "counts"}});
  const auto s =
      (*w)->add_schema("hardcopy.Fsr", kJsonSchemaEncoding, Bytes(js.begin(), js.end())).value();
  const auto ch = (*w)->add_channel("/fsr0/samples", kJsonEncoding, s).value();
  for (int i = 0; i < 500; ++i)
    ASSERT_TRUE((*w)->write_message(ch, 1000 + 2'000'000ull * static_cast<std::uint64_t>(i), 0,
                                    json_message(Json{{"raw", i}}))
                    .ok());
  ASSERT_TRUE(
      (*w)->write_metadata(kMetadataDeviceStats, {{"fsr0.received", "500"}, {"fsr0.lost", "4"}})
          .ok());
  ASSERT_TRUE((*w)->close().ok());
}

TEST(SessionCli, InfoVerifyRecoverExport) {
  testing::ScratchDir dir;
  const auto s = dir / "s.mcap";
  make_session(s);

  CliRun r = hardcopy("session info --json " + s.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = parse_json(r.out, "info");
  ASSERT_TRUE(j.ok()) << r.out;
  EXPECT_EQ((*j)["message_count"], 500);
  EXPECT_EQ((*j)["channels"][0]["topic"], "/fsr0/samples");
  EXPECT_NEAR((*j)["channels"][0]["rate_hz"].get<double>(), 500.0, 1e-9);  // 2 ms apart
  EXPECT_EQ((*j)["device_stats"][0]["lost"], 4);
  r = hardcopy("session info " + s.string());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("/fsr0/samples"), std::string::npos) << r.out;

  EXPECT_EQ(hardcopy("session verify " + s.string()).exit_code, 0);
  r = hardcopy("session verify --json " + s.string());
  ASSERT_EQ(r.exit_code, 0);
  EXPECT_EQ(parse_json(r.out, "verify")->at("ok"), true);

  // Cut off as by a crash: verify says no (1); recover makes a valid file (0) that verifies (0).
  std::ifstream in(s, std::ios::binary);
  const std::string full((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  {
    std::ofstream out(dir / "cut.mcap", std::ios::binary);
    out << full.substr(0, full.size() * 2 / 3);
  }
  EXPECT_EQ(hardcopy("session verify " + (dir / "cut.mcap").string()).exit_code, 1);
  r = hardcopy("session recover --json " + (dir / "cut.mcap").string() + " -o " +
               (dir / "rec.mcap").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto rj = parse_json(r.out, "recover");
  ASSERT_TRUE(rj.ok());
  EXPECT_GT((*rj)["messages_kept"].get<int>(), 200);
  EXPECT_LT((*rj)["messages_kept"].get<int>(), 500);
  EXPECT_EQ(hardcopy("session verify " + (dir / "rec.mcap").string()).exit_code, 0);

  // Unreadable input: 2; unknown channel: 2; bad option: 2.
  {
    std::ofstream out(dir / "junk.mcap", std::ios::binary);
    out << "not an mcap file at all";
  }
  EXPECT_EQ(hardcopy("session verify " + (dir / "junk.mcap").string()).exit_code, 2);
  EXPECT_EQ(hardcopy("session info " + (dir / "missing.mcap").string()).exit_code, 2);
  EXPECT_EQ(hardcopy("session recover " + (dir / "junk.mcap").string() + " -o " +
                     (dir / "x.mcap").string())
                .exit_code,
            2);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.mcap"));
  EXPECT_EQ(hardcopy("session recover " + s.string() + " -o " + (dir / "y.mcap").string() +
                     " --compression gzip")
                .exit_code,
            2);
  EXPECT_EQ(hardcopy("session export " + s.string() + " --channel /nope -o " + (dir / "e").string())
                .exit_code,
            2);

  r = hardcopy("session export --json " + s.string() + " --channel /fsr0/samples -o " +
               (dir / "e").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream csv(dir / "e" / "fsr0_samples.csv");
  std::string header, first;
  std::getline(csv, header);
  std::getline(csv, first);
  EXPECT_EQ(header, "log_time_ns,publish_time_ns,sequence,raw");
  EXPECT_EQ(first, "1000,0,0,0");
}

}  // namespace
}  // namespace hc::recording
