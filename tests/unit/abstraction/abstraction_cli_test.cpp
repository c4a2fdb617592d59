// The command-line contract of hardcopy abstract | engrave | offset | boolean | calibration-part:
// exit codes (0 yes, 1 no, 2 bad input), the --json fields, 2-D in gives 2-D out.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_run.h"
#include "fabrication/abstraction/svg.h"
#include "shapes_2d.h"

namespace hc::abstraction {
namespace {

using testing::CliRun;
using testing::hardcopy;

std::string write(const testing::ScratchDir& dir, const std::string& name,
                  const std::string& text) {
  const auto path = dir.path() / name;
  std::ofstream(path) << text;
  return path.string();
}

std::string comb_svg() {
  // Slots 0.5 mm wide, 0.5 and 2 mm deep (closed at F = 1 mm), one 2 mm wide (kept).
  return format_svg(testing::comb({{0.5, 0.5}, {0.5, 2.0}, {2.0, 2.0}}, 2.0, 6.0));
}

TEST(AbstractionCli, AbstractAndEngrave2dPrintTheJsonFields) {
  testing::ScratchDir dir;
  const std::string in = write(dir, "comb.svg", comb_svg());
  for (const std::string cmd : {"abstract", "engrave --depth-mm 0.2"}) {
    const std::string out = (dir.path() / "out.svg").string();
    const CliRun r = hardcopy(cmd + " " + in + " -o " + out + " --feature-mm 1 --json");
    ASSERT_EQ(r.exit_code, 0) << cmd << ": " << r.out;
    const auto j = nlohmann::json::parse(r.out);
    for (const char* key :
         {"samples", "balls", "intrusions_closed", "hausdorff_mm", "printable", "time_s"})
      EXPECT_TRUE(j.contains(key)) << key;
    EXPECT_EQ(j["intrusions_closed"], 2) << cmd;
    EXPECT_EQ(j["printable"], true);
    EXPECT_TRUE(read_svg(out).ok());
  }
}

TEST(AbstractionCli, OffsetAndBoolean2d) {
  testing::ScratchDir dir;
  const std::string a = write(dir, "a.svg", format_svg(testing::rectangle(0, 0, 10, 10)));
  const std::string b = write(dir, "b.svg", format_svg(testing::rectangle(5, 5, 15, 15)));
  const std::string out = (dir.path() / "out.svg").string();
  CliRun r = hardcopy("offset " + a + " -o " + out + " --distance-mm 1 --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = hardcopy("boolean union " + a + " " + b + " -o " + out + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto u = read_svg(out);
  ASSERT_TRUE(u.ok());
  EXPECT_NEAR(area(*u), 175.0, 0.005 * 175.0);  // 100 + 100 - 25
  r = hardcopy("boolean xor " + a + " " + b + " -o " + out);
  EXPECT_EQ(r.exit_code, 2);
}

TEST(AbstractionCli, CalibrationPartIsPrintable) {
  testing::ScratchDir dir;
  const std::string out = (dir.path() / "part.stl").string();
  const CliRun r = hardcopy("calibration-part --depths-mm 0.2:0.6:0.2 --diameters-mm 0.5,1 -o " +
                            out + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["printable"], true);
  EXPECT_EQ(j["legend"].size(), 5u);  // 3 depth rows + 2 diameter columns
}

TEST(AbstractionCli, BadInputExitsTwo) {
  testing::ScratchDir dir;
  const std::string comb = write(dir, "comb.svg", comb_svg());
  const std::string empty =
      write(dir, "empty.svg", R"(<svg xmlns="http://www.w3.org/2000/svg"><g/></svg>)");
  const std::string out = (dir.path() / "out.svg").string();
  const std::string open_mesh =
      (testing::shared_data("meshes") / "ChineseDragon-10kv.off").string();
  const std::string cases[] = {
      "abstract " + comb + " -o " + out + " --feature-mm 0",
      "abstract " + comb + " -o " + out + " --feature-mm -1",
      "abstract " + empty + " -o " + out + " --feature-mm 1",
      "abstract " + (dir.path() / "missing.svg").string() + " -o " + out + " --feature-mm 1",
      "abstract " + comb + " -o " + (dir.path() / "out.stl").string() + " --feature-mm 1",
      "abstract " + open_mesh + " -o " + (dir.path() / "out.stl").string() + " --feature-mm 1",
      "calibration-part --depths-mm 1:0.5:0.1 --diameters-mm 1 -o " +
          (dir.path() / "p.stl").string(),
  };
  for (const auto& c : cases) {
    const CliRun r = hardcopy(c);
    EXPECT_EQ(r.exit_code, 2) << c << "\n" << r.out;
  }
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace hc::abstraction
