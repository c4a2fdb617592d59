// rigd's command-line contract for the page: --http ADDR:PORT prints the page's URL and writes the
// token next to the control socket (rigd.token, 0600), removed again at exit; a non-loopback
// address without the config's allow_remote is bad usage (exit 2); --no-http serves nothing.
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "cli_run.h"
#include "common/file_io.h"
#include "live_support.h"

namespace hc::rig {
namespace {

using hc::testing::bin_dir;
using hc::testing::ScratchDir;

// rigd as a child process with stderr in DIR/rigd.log; SIGTERM on destruction.
struct RigdProcess {
  pid_t pid = -1;
  std::filesystem::path log;
  RigdProcess(const std::filesystem::path& dir, const std::vector<std::string>& extra) {
    log = dir / "rigd.log";
    std::vector<std::string> args{(bin_dir() / "rigd").string(), "--sessions-dir",
                                  (dir / "sessions").string(), "--socket",
                                  (dir / "rigd.sock").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    pid = ::fork();
    if (pid == 0) {
      if (std::freopen(log.c_str(), "w", stderr) == nullptr) ::_exit(126);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
  }
  // The log once `needle` appears in it (up to 20 s), or what there is.
  std::string wait_log(const std::string& needle) const {
    std::string text;
    for (int i = 0; i < 400; ++i) {
      std::ifstream in(log);
      std::stringstream ss;
      ss << in.rdbuf();
      text = ss.str();
      if (text.find(needle) != std::string::npos) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return text;
  }
  int stop() {
    if (pid <= 0) return -1;
    ::kill(pid, SIGTERM);
    int status = 0;
    ::waitpid(pid, &status, 0);
    pid = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  int wait() {
    int status = 0;
    ::waitpid(pid, &status, 0);
    pid = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  ~RigdProcess() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
  }
};

TEST(RigdHttp, PrintsTheUrlAndWritesAnOwnerOnlyToken) {
  ScratchDir dir;
  RigdProcess rigd(dir.path(), {"--http", "127.0.0.1:0"});
  const std::string log = rigd.wait_log("control socket");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(log, m, std::regex(R"(live page (http://127\.0\.0\.1:(\d+)/)\?token=([0-9a-f]{64}))")))
      << log;
  const int port = std::stoi(m[2]);
  const std::string token = m[3];
  const auto token_file = dir / "rigd.token";
  struct stat st{};
  ASSERT_EQ(::stat(token_file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(*read_file(token_file), token + "\n");
  httplib::Client c("127.0.0.1", port);
  auto status = c.Get("/api/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(Json::parse(status->body)["daemon"], "rigd");
  // rigctl status --json is the same document (idle: nothing moves).
  const hc::testing::CliRun ctl = hc::testing::run_command(
      (bin_dir() / "rigctl").string() + " --socket " + (dir / "rigd.sock").string() +
      " status --json 2>/dev/null");
  ASSERT_EQ(ctl.exit_code, 0);
  EXPECT_EQ(Json::parse(ctl.out), Json::parse(status->body));
  EXPECT_EQ(c.Post("/api/estop", "", "text/plain")->status, 403);
  EXPECT_EQ(c.Post("/api/estop", httplib::Headers{{"Authorization", "Bearer " + token}}, "",
                   "text/plain")
                ->status,
            200);
  EXPECT_EQ(rigd.stop(), 0);
  EXPECT_FALSE(std::filesystem::exists(token_file));
}

TEST(RigdHttp, RemoteAddressNeedsTheConfigAndNoHttpServesNothing) {
  ScratchDir dir;
  RigdProcess remote(dir.path(), {"--http", "0.0.0.0:0"});
  EXPECT_EQ(remote.wait(), 2);
  EXPECT_NE(remote.wait_log("loopback").find("not a loopback address"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "rigd.token"));
  RigdProcess bad(dir.path(), {"--http", "127.0.0.1"});
  EXPECT_EQ(bad.wait(), 2);
  ScratchDir dir2;
  RigdProcess none(dir2.path(), {"--no-http"});
  const std::string log = none.wait_log("control socket");
  EXPECT_EQ(log.find("live page"), std::string::npos) << log;
  EXPECT_FALSE(std::filesystem::exists(dir2 / "rigd.token"));
  EXPECT_EQ(none.stop(), 0);
}

}  // namespace
}  // namespace hc::rig
