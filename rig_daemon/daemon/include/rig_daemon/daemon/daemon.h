// rigd's core: the rig, at most one running session (on a thread of its own), and the answers to
// the control protocol's commands. The executable (rig_daemon/rigd) only parses arguments, builds
// a Daemon and serves it on the control socket.
#pragma once

#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/daemon/control_protocol.h"
#include "rig_daemon/daemon/rig.h"
#include "rig_daemon/daemon/scheduler.h"

namespace hc::rig {

class Daemon {
 public:
  struct Options {
    RigConfig config;
    std::shared_ptr<devices::Clock> clock;  // null: host monotonic clock
    // Serve this recorded session's streams instead of the config's devices.
    std::filesystem::path replay;
    double replay_speed = 1.0;
    std::string software_version = "unknown";
    // Events (progress, safety, finished) for subscribers; called from the session thread.
    std::function<void(std::string_view event, const Json& fields)> on_event;
    // Called once when a `shutdown` request arrives.
    std::function<void()> on_shutdown;
  };
  static Result<std::unique_ptr<Daemon>> create(Options options);
  ~Daemon();  // stops a running session (stop, not estop) and waits for it

  // The control protocol: answers one request (thread-safe).
  Json handle(const Request& request, Status& error);

  Json status() const;
  Json devices() const;
  // Validates the plan against the rig and starts it; returns {"session": path}.
  Result<Json> start(const Plan& plan);
  Status pause();
  Status resume();
  Status stop();
  // Always works: stops the arm now (also with no session running) and aborts the session.
  // Like a session's safety trip it leaves the rig in a safety stop: start is refused until
  // reset().
  Json estop();
  // Clears the safety stop: resets devices left in error and clears an arm fault (refused while a
  // session runs; the stop stays when the arm is still in fault). The next automated capture
  // still checks the force before it moves anything.
  Result<Json> reset();
  // The safety stop in force (kind, message, since), or null.
  Json safety_stop() const;
  // Waits until no session runs (true) or the timeout passes (false).
  bool wait_idle(int timeout_ms);
  // The summary of the last finished session (null before the first).
  Json last_summary() const;
  Rig& rig() { return *rig_; }

 private:
  explicit Daemon(Options options) : options_(std::move(options)) {}
  std::filesystem::path next_session_path(const Plan& plan) const;

  Options options_;
  std::unique_ptr<Rig> rig_;
  mutable std::mutex mutex_;
  std::condition_variable idle_cv_;
  std::unique_ptr<Session> session_;
  std::thread thread_;
  bool running_ = false;
  Json last_summary_;
  Json safety_stop_;  // null, or why starts are refused until reset()
  std::uint64_t sessions_started_ = 0;
};

}  // namespace hc::rig
