// `hardcopy plot` / `report` end to end: a session recorded by the daemon on simulated time is
// plotted, and the data files must carry exactly the numbers of the session's step records (read
// here with the MCAP reader, not through the figures library); bad inputs exit 2 and write nothing.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "cli_run.h"
#include "common/file_io.h"
#include "common/json.h"
#include "common/units.h"
#include "rig_daemon/daemon/daemon.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/rig_config.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/topics.h"
#include "test_data.h"

namespace hc::figures {
namespace {

using hc::testing::hardcopy;
using hc::testing::ScratchDir;

// Two locations pressed to 10 N in 30 steps, one camera, on the embedded default rig and simulated
// time (a few seconds of CPU).
Result<std::filesystem::path> record_short_press(const std::filesystem::path& sessions) {
  HC_ASSIGN_OR_RETURN(rig::RigConfig cfg, rig::embedded_default_rig_config());
  cfg.sessions_dir = sessions;
  HC_ASSIGN_OR_RETURN(rig::Plan plan, rig::parse_plan(R"(protocol: automated
name: press
locations:
  - {position_m: [0.0, 0.0, 0.062], direction: [0, 0, -1]}
  - {position_m: [0.012, 0.0, 0.062], direction: [0, 0, -1]}
force_levels_n: [10]
steps: 30
settle_s: 0.01
max_force_n: 40
workspace: {min_m: [-0.05, -0.05, 0.0], max_m: [0.05, 0.05, 0.12]}
cameras: [cam0]
)",
                                                      "press.yaml"));
  rig::Daemon::Options o;
  o.config = cfg;
  o.clock = std::make_shared<devices::SimulatedClock>(1'000'000'000);
  o.software_version = "test";
  HC_ASSIGN_OR_RETURN(std::unique_ptr<rig::Daemon> d, rig::Daemon::create(o));
  HC_RETURN_IF_ERROR(d->start(plan).status());
  if (!d->wait_idle(600'000)) return internal_error("the press did not finish");
  const Json s = d->last_summary();
  if (s["state"] != "finished") return internal_error("press: " + s.dump());
  return std::filesystem::path(s["session"].get<std::string>());
}

// The steps of a session as the recorder wrote them.
std::vector<Json> steps_of(const std::filesystem::path& session) {
  std::vector<Json> out;
  Result<recording::McapReader> r = recording::McapReader::open(session);
  EXPECT_TRUE(r.ok());
  recording::ReadOptions ro;
  ro.topics = {std::string(session::kStepsTopic)};
  ro.order = recording::ReadOrder::kFile;
  EXPECT_TRUE(r->read_messages(ro, [&](const recording::MessageEvent& e) {
                  out.push_back(*recording::parse_json_message(e.message.data));
                  return true;
                }).ok());
  return out;
}

std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::string cell;
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == '"') {
        if (quoted && i + 1 < line.size() && line[i + 1] == '"') {
          cell += '"';
          ++i;
        } else {
          quoted = !quoted;
        }
      } else if (c == ',' && !quoted) {
        cells.push_back(cell);
        cell.clear();
      } else {
        cell += c;
      }
    }
    cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

class PlotSession : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir();
    Result<std::filesystem::path> s = record_short_press(dir_->path() / "sessions");
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    session_ = *s;
  }
  static void TearDownTestSuite() { delete dir_; }
  static inline ScratchDir* dir_ = nullptr;
  static inline std::filesystem::path session_;
};

TEST_F(PlotSession, DataFilesCarryTheSessionsNumbers) {
  const std::filesystem::path out = dir_->path() / "plots";
  ASSERT_EQ(hardcopy("plot " + session_.string() + " -o " + out.string()).exit_code, 0);
  const std::vector<Json> steps = steps_of(session_);
  ASSERT_EQ(steps.size(), 2u * 30u);  // 2 locations x 1 level x 30 steps (the fewest a plan may have)
  Result<Json> data = load_json(out / "session_forces.json");
  ASSERT_TRUE(data.ok()) << data.status().to_string();
  const Json& src = (*data)["source"]["steps"];
  ASSERT_EQ(src.size(), steps.size());
  for (std::size_t i = 0; i < steps.size(); ++i) {
    EXPECT_EQ(src[i]["location"], steps[i]["location"]);
    EXPECT_EQ(src[i]["step"], steps[i]["step"]);
    EXPECT_EQ(src[i]["depth_m"].get<double>(), steps[i]["depth_m"].get<double>());  // exact
    EXPECT_EQ(src[i]["force_n"].get<double>(), steps[i]["force_n"].get<double>());
  }
  // The plotted CSV: one row per step, x = depth in mm, y = force in N, in recording order.
  const auto rows = read_csv(out / "session_forces.csv");
  ASSERT_EQ(rows.size(), steps.size() + 1);
  EXPECT_EQ(rows[0][1], "probe depth from the start point (mm)");
  for (std::size_t i = 0; i < steps.size(); ++i) {
    EXPECT_EQ(rows[i + 1][0], "location " + std::to_string(steps[i]["location"].get<int>()));
    EXPECT_EQ(std::stod(rows[i + 1][1]), units::m_to_mm(steps[i]["depth_m"].get<double>()));
    EXPECT_EQ(std::stod(rows[i + 1][2]), steps[i]["force_n"].get<double>());
  }
  // Forces reach the plan's level (10 N within rigd's step tolerance); the probe never backs off
  // during a press (a step whose force is already within tolerance does not move it).
  EXPECT_NEAR(steps[29]["force_n"].get<double>(), 10.0, 1.0);
  for (std::size_t i = 1; i < 30; ++i)
    EXPECT_GE(steps[i]["depth_m"].get<double>(), steps[i - 1]["depth_m"].get<double>());
  EXPECT_GT(steps[29]["depth_m"].get<double>(), steps[0]["depth_m"].get<double>());
  for (const char* f : {"session_forces.png", "session_forces.svg", "session_forces_loc0.png",
                        "session_forces_loc1.svg", "session_forces_loc1.csv", "numbers.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  Result<std::string> png = read_file(out / "session_forces.png");
  ASSERT_TRUE(png.ok());
  EXPECT_EQ(png->substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  Result<Json> numbers = load_json(out / "numbers.json");
  ASSERT_TRUE(numbers.ok());
  EXPECT_EQ((*numbers)["numbers"]["state"], "finished");
  EXPECT_EQ((*numbers)["numbers"]["steps"], 60);
}

TEST_F(PlotSession, ReportIsOnePage) {
  const std::filesystem::path html = dir_->path() / "report.html";
  ASSERT_EQ(hardcopy("report " + session_.string() + " -o " + html.string()).exit_code, 0);
  Result<std::string> page = read_file(html);
  ASSERT_TRUE(page.ok());
  EXPECT_NE(page->find("<h2>Session "), std::string::npos);
  std::size_t images = 0;
  for (std::size_t p = 0; (p = page->find("data:image/svg+xml;base64,", p)) != std::string::npos; ++p)
    ++images;
  EXPECT_EQ(images, 3u);  // the overview and one chart per location
}

TEST_F(PlotSession, BadInputExitsTwoAndWritesNothing) {
  const std::filesystem::path out = dir_->path() / "bad";
  EXPECT_EQ(hardcopy("plot " + (dir_->path() / "missing.mcap").string() + " -o " + out.string())
                .exit_code,
            2);
  // A truncated session (cut in the middle of its data).
  Result<std::string> bytes = read_file(session_);
  ASSERT_TRUE(bytes.ok());
  const std::filesystem::path cut = dir_->path() / "cut.mcap";
  ASSERT_TRUE(write_file_atomic(cut, bytes->substr(0, bytes->size() / 2)).ok());
  EXPECT_EQ(hardcopy("plot " + cut.string() + " -o " + out.string()).exit_code, 2);
  // JSON that is not samples; an unknown extension; an unknown format.
  const std::filesystem::path other = dir_->path() / "other.json";
  ASSERT_TRUE(write_file_atomic(other, R"({"format": "hardcopy.material"})").ok());
  EXPECT_EQ(hardcopy("plot " + other.string() + " -o " + out.string()).exit_code, 2);
  const std::filesystem::path text = dir_->path() / "notes.txt";
  ASSERT_TRUE(write_file_atomic(text, "x").ok());
  EXPECT_EQ(hardcopy("plot " + text.string() + " -o " + out.string()).exit_code, 2);
  EXPECT_EQ(hardcopy("plot " + session_.string() + " -o " + out.string() + " --format jpg")
                .exit_code,
            2);
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_EQ(hardcopy("report " + other.string() + " -o " + (out / "r.html").string()).exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace hc::figures
