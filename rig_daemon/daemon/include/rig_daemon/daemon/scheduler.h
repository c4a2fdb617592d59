// The scheduler: runs one plan on the rig and records it. One thread runs a control cycle of
// RigConfig::control_period_s: read every device without blocking, record what arrived, associate
// frames and force samples with trigger edges, check safety (over-force, stalled F/T stream,
// estop) and stop the arm in the same cycle when a check trips, then advance the protocol.
//
// Automated protocol (thesis 5.6): home the arm if needed, tare the F/T sensor, then for every
// location and force level: move above the location, press along the direction in `steps` steps
// whose target forces rise linearly to the level (each step advances the probe until the measured
// force reaches the target, using the local stiffness seen so far), settle, fire the trigger
// (frames_per_step pulses) and wait for every camera's frame and the force samples of each edge,
// then retract. Before anything moves it refuses to start (a safety stop of kind start_check)
// while the arm is in fault or the force is above start_max_force_n; a step whose force is not
// reached within max_depth_m fails the session (after retracting). After an over-force or
// workspace stop the probe is retracted to the press's start pose, slowly, watching the force;
// every stop is recorded on the arm's command channel with the arm's state after it. Hand-held
// protocol (thesis 4.4): a pulse train at the plan's rate for its duration; every edge fires the
// cameras and latches an FSR reading.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "rig_daemon/daemon/association.h"
#include "rig_daemon/daemon/plan.h"
#include "rig_daemon/daemon/recorder.h"
#include "rig_daemon/daemon/rig.h"
#include "rig_daemon/daemon/safety.h"

namespace hc::rig {

enum class SessionState {
  kIdle,
  kStarting,
  kRunning,
  kPaused,
  kFinished,
  kStopped,
  kAborted,
  kFailed
};
std::string_view to_string(SessionState state);

struct SessionOptions {
  std::filesystem::path path;  // the MCAP file to create
  Plan plan;
  std::string software_version;
  // Progress and safety events (called on the session thread; must not block).
  std::function<void(std::string_view event, const Json& fields)> on_event;
  Recorder::Options recorder;
};

class Session {
 public:
  // Checks the plan against the rig (device names and kinds, workspace, max force) without
  // touching devices.
  static Status validate(const Rig& rig, const Plan& plan);

  Session(Rig& rig, SessionOptions options);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Runs the plan to its end on the calling thread and returns the session summary (also when the
  // session was stopped or aborted by a safety trip: see "state" and "reason"). An error means
  // nothing usable was recorded (the file could not be created, a device would not start).
  Result<Json> run();

  // Thread-safe controls.
  void pause();
  void resume();
  void stop();
  // Stops the arm at once from the calling thread and makes the session abort within one cycle.
  void estop();

  SessionState state() const { return state_.load(); }
  // A snapshot: state, done/total triggers, step, force, association, trips.
  Json progress() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<SessionState> state_{SessionState::kIdle};
};

}  // namespace hc::rig
