// The simulator executables (hardcopy-netft-sim, hardcopy-modbus-arm-sim) as a user runs them:
// they print their ports, serve the real clients, and exit cleanly on SIGTERM.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "rig_daemon/backends/modbus_arm_client.h"
#include "rig_daemon/backends/netft_client.h"
#include "test_data.h"

namespace hc::rig {
namespace {

using namespace std::chrono_literals;

// Starts `args` with stdout to a pipe; returns the pid and the read end.
struct Child {
  pid_t pid = -1;
  FILE* out = nullptr;
  ~Child() {
    if (pid > 0) {
      ::kill(pid, SIGTERM);
      int status = 0;
      ::waitpid(pid, &status, 0);
    }
    if (out != nullptr) std::fclose(out);
  }
};

void spawn(Child& c, const std::string& exe, const std::vector<std::string>& args) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  c.pid = ::fork();
  ASSERT_GE(c.pid, 0);
  if (c.pid == 0) {
    ::dup2(fds[1], STDOUT_FILENO);
    ::close(fds[0]);
    ::close(fds[1]);
    std::vector<char*> argv;
    std::string path = (hc::testing::bin_dir() / exe).string();
    argv.push_back(path.data());
    std::vector<std::string> copy = args;
    for (auto& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(path.c_str(), argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  c.out = ::fdopen(fds[0], "r");
}

std::uint16_t read_port(FILE* f, const std::string& key) {
  char line[256];
  while (std::fgets(line, sizeof line, f) != nullptr) {
    const std::string s(line);
    if (s.rfind(key + " ", 0) == 0)
      return static_cast<std::uint16_t>(std::stoi(s.substr(key.size())));
  }
  return 0;
}

TEST(SimulatorTools, NetFtSimServesCalibrationAndRecords) {
  Child c;
  spawn(c, "hardcopy-netft-sim", {"--fz", "12.5", "--counts-per-force", "1000000"});
  const std::uint16_t port = read_port(c.out, "rdt_port");
  const std::uint16_t http = read_port(c.out, "http_port");
  ASSERT_NE(port, 0);
  NetFtOptions o;
  o.port = port;
  o.http_port = http;
  o.calibration_source = "sensor";
  auto client = NetFtClient::open(o);
  ASSERT_TRUE(client.ok()) << client.status().to_string();
  ASSERT_TRUE((*client)->start().ok());
  std::vector<FtSample> s;
  ASSERT_TRUE((*client)->receive(s, 100ms).ok());
  ASSERT_FALSE(s.empty());
  EXPECT_NEAR(s.back().wrench.force_n[2], 12.5, 1e-6);
  ASSERT_TRUE((*client)->stop().ok());
  ::kill(c.pid, SIGTERM);
  int status = 0;
  ASSERT_EQ(::waitpid(c.pid, &status, 0), c.pid);
  c.pid = -1;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

TEST(SimulatorTools, ModbusArmSimAnswersTheClient) {
  Child c;
  spawn(c, "hardcopy-modbus-arm-sim", {});
  const std::uint16_t port = read_port(c.out, "modbus_port");
  ASSERT_NE(port, 0);
  ModbusArmOptions o;
  o.port = port;
  auto client = ModbusArmClient::create(o);
  ASSERT_TRUE(client.ok());
  ASSERT_TRUE((*client)->connect().ok());
  auto st = (*client)->read_status();
  ASSERT_TRUE(st.ok()) << st.status().to_string();
  EXPECT_EQ(st->map_version, arm::kMapVersion);
  EXPECT_FALSE(st->homed);
}

}  // namespace
}  // namespace hc::rig
