#include "rig_daemon/simulators/fake_gv_camera.h"
#include "common/clock.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <thread>
#include <vector>

extern char** environ;

namespace hc::rig::sim {
namespace {

constexpr const char* kLockPath = "/tmp/hardcopy-arv-fake-gv-camera.lock";
constexpr std::uint16_t kGvcpPort = 3956;

}  // namespace

std::string FakeGvCamera::find_binary(const std::string& name) {
  if (name.find('/') != std::string::npos)
    return ::access(name.c_str(), X_OK) == 0 ? name : std::string();
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = (std::filesystem::path(dir) / name).string();
    if (!dir.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return {};
}

bool gvcp_discovery_answers(const std::string& address, double timeout_s) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(kGvcpPort);
  ::inet_pton(AF_INET, address.c_str(), &addr.sin_addr);
  const std::uint8_t cmd[8] = {0x42, 0x11, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01};
  bool ok = false;
  if (::sendto(fd, cmd, sizeof cmd, 0, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) ==
      static_cast<ssize_t>(sizeof cmd)) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout_s * 1000)) > 0) {
      std::uint8_t ack[600];
      const ssize_t n = ::recv(fd, ack, sizeof ack, 0);
      ok = n >= 8 && ack[2] == 0x00 && ack[3] == 0x03;  // DISCOVERY_ACK
    }
  }
  ::close(fd);
  return ok;
}

Result<std::unique_ptr<FakeGvCamera>> FakeGvCamera::start(const FakeGvCameraOptions& options) {
  const std::string binary = find_binary(options.binary);
  if (binary.empty())
    return not_found("'" + options.binary +
                     "' is not installed (Debian package aravis-tools); cannot run the fake "
                     "GigE Vision camera");
  std::unique_ptr<FakeGvCamera> cam(new FakeGvCamera());
  cam->serial_ = options.serial;
  cam->lock_fd_ = ::open(kLockPath, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  if (cam->lock_fd_ < 0) return io_error(std::string(kLockPath) + ": " + std::strerror(errno));
  const auto t0 = std::chrono::steady_clock::now();
  while (::flock(cam->lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    if (seconds_since(t0) > options.lock_timeout_s)
      return Status(StatusCode::kDeadlineExceeded,
                    "another fake GigE camera (lock " + std::string(kLockPath) + ") ran for " +
                        std::to_string(options.lock_timeout_s) + " s");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // A camera started without this lock (another program's) would answer discovery too: wait
  // for it to go away, within the lock timeout.
  while (gvcp_discovery_answers("127.0.0.1", 0.05)) {
    if (seconds_since(t0) > options.lock_timeout_s)
      return failed_precondition("something else keeps answering GVCP on 127.0.0.1:3956");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::vector<std::string> args = {binary, "-i", "127.0.0.1", "-s", options.serial};
  if (options.gvsp_lost_per_thousand > 0) {
    args.push_back("-r");
    args.push_back(std::to_string(options.gvsp_lost_per_thousand));
  }
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  const int rc = ::posix_spawn(&cam->pid_, binary.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    cam->pid_ = -1;
    return io_error("spawning " + binary + ": " + std::strerror(rc));
  }
  const auto t1 = std::chrono::steady_clock::now();
  while (!gvcp_discovery_answers("127.0.0.1", 0.1)) {
    int status = 0;
    if (::waitpid(cam->pid_, &status, WNOHANG) == cam->pid_) {
      cam->pid_ = -1;
      return io_error(binary + " exited at start (status " + std::to_string(status) + ")");
    }
    if (seconds_since(t1) > options.ready_timeout_s)
      return Status(StatusCode::kDeadlineExceeded,
                    binary + " did not answer GVCP discovery within " +
                        std::to_string(options.ready_timeout_s) + " s");
  }
  return cam;
}

FakeGvCamera::~FakeGvCamera() {
  if (pid_ > 0) {
    ::kill(pid_, SIGTERM);
    int status = 0;
    bool reaped = false;
    for (int i = 0; i < 100 && !reaped; ++i) {  // up to 1 s
      reaped = ::waitpid(pid_, &status, WNOHANG) == pid_;
      if (!reaped) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (!reaped) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
    }
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the flock
}

}  // namespace hc::rig::sim
