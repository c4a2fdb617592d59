// The lifecycle every device shares, whatever its kind and backend (after ros2_control's hardware
// components):
//
//   kUnconfigured --configure(node)--> kInactive --activate()--> kActive --deactivate()-->
//   kInactive kInactive --cleanup()--> kUnconfigured
//         any state --(a failure in activate/read/write)--> kError --reset()--> kInactive
//
// * configure() reads the device's own map of the rig config (keys `kind` and `backend` are the
//   daemon's; the backend reads the rest) and opens nothing that streams. It may be called again
//   from kInactive to reconfigure. On failure the device stays/returns kUnconfigured and the
//   Status names the key at fault.
// * activate() opens/starts the stream; read()/write() work only in kActive.
// * Calling an operation in the wrong state returns kFailedPrecondition and changes nothing;
//   in kError every operation except reset()/deactivate() returns the error that caused it.
// * deactivate() stops streaming; in kError it releases what it can and the device stays kError.
// * A failure of the device or its link (kIoError, kUnavailable, kDeadlineExceeded, kInternal) in
//   activate/read/write enters kError; a refused request (kInvalidArgument, kFailedPrecondition,
//   kUnsupported: a target outside the workspace, a move before homing) does not.
//
// Streaming reads append to a vector: `read(out, timeout)` blocks until at least one item is
// available or `timeout` passed (on the device's Clock; with a SimulatedClock in auto-advance
// mode the wait is simulated time), appends every available item in order and returns how many it
// appended (0 = timed out; not an error).
//
// Threads: lifecycle calls and read/write come from one thread at a time; state(), error(),
// stats() and info() may be called from any thread (and Arm::stop(), see arm.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/config.h"
#include "common/status.h"
#include "rig_daemon/devices/clock.h"

namespace hc::devices {

enum class DeviceKind : std::uint8_t { kCamera, kTrigger, kFsr, kForceTorque, kArm };
inline constexpr DeviceKind kAllDeviceKinds[] = {DeviceKind::kCamera, DeviceKind::kTrigger,
                                                 DeviceKind::kFsr, DeviceKind::kForceTorque,
                                                 DeviceKind::kArm};
// "camera", "trigger", "fsr", "force_torque", "arm" (the `kind` values of the rig config).
std::string_view to_string(DeviceKind kind);
std::optional<DeviceKind> device_kind_from_string(std::string_view name);

enum class DeviceState : std::uint8_t { kUnconfigured, kInactive, kActive, kError };
// "unconfigured", "inactive", "active", "error".
std::string_view to_string(DeviceState state);

// Counters since construction (they survive deactivate/activate; reset() keeps them too).
struct DeviceStats {
  std::uint64_t received = 0;      // items delivered by read() (frames, edges, samples, states)
  std::uint64_t lost = 0;          // items the device sent or should have sent that never arrived
                                   // (sequence gaps, dropped packets, missed periods)
  std::uint64_t late = 0;          // items that arrived later than the backend's lateness bound
  std::uint64_t incomplete = 0;    // frames delivered with missing bytes
  std::uint64_t errors = 0;        // times the device entered kError
  std::int64_t last_host_ns = -1;  // host_ns of the last delivered item; -1 before the first
};

// What `rigctl devices` shows.
struct DeviceInfo {
  std::string name;
  DeviceKind kind = DeviceKind::kCamera;
  std::string backend;
  DeviceState state = DeviceState::kUnconfigured;
  std::string model;   // e.g. "Basler piA1600-35gm", "simulated"
  std::string serial;  // empty when unknown
  std::vector<std::pair<std::string, std::string>> details;  // backend-specific, in display order
};

// What a backend factory gets.
struct DeviceContext {
  std::string name;              // device name from the rig config ("cam0", "ft")
  std::string backend;           // backend name ("sim", "aravis", "replay", ...)
  std::shared_ptr<Clock> clock;  // host monotonic time (never null; set by the caller)
};

class Device {
 public:
  explicit Device(DeviceContext context);
  virtual ~Device();
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  virtual DeviceKind kind() const = 0;
  const std::string& name() const { return context_.name; }
  const std::string& backend() const { return context_.backend; }
  Clock& clock() const { return *context_.clock; }
  const DeviceContext& context() const { return context_; }

  DeviceState state() const { return state_.load(); }
  // The Status that put the device in kError; OK in every other state.
  Status error() const;
  DeviceStats stats() const;
  // Name, kind, backend, state, plus what describe() adds.
  DeviceInfo info() const;

  Status configure(ConfigNode node);
  Status activate();
  Status deactivate();
  // From kError: on_reset() (close and reopen what the backend needs), then kInactive, keeping the
  // configuration; from kInactive/kUnconfigured: no-op. Fails (staying kError) if on_reset fails.
  Status reset();
  // kInactive → kUnconfigured (forgets the configuration; on_cleanup()). No-op when unconfigured.
  Status cleanup();

 protected:
  // Backend hooks; the base class has already checked the state.
  virtual Status on_configure(ConfigNode node) = 0;
  virtual Status on_activate() = 0;
  virtual Status on_deactivate() = 0;
  virtual Status on_reset() { return {}; }
  virtual Status on_cleanup() { return {}; }
  // Fills model/serial/details.
  virtual void describe(DeviceInfo& /*info*/) const {}

  // Enters kError with `status` (must not be OK) and returns it, for `return fail(...)`.
  Status fail(Status status);
  // OK in kActive; the stored error in kError; kFailedPrecondition naming `operation` otherwise.
  Status check_active(std::string_view operation) const;
  // OK when configured (kInactive or kActive); the stored error in kError; else
  // kFailedPrecondition.
  Status check_configured(std::string_view operation) const;

  void count_received(std::uint64_t n, std::int64_t last_host_ns);
  void count_lost(std::uint64_t n) { lost_.fetch_add(n); }
  void count_late(std::uint64_t n) { late_.fetch_add(n); }
  void count_incomplete(std::uint64_t n) { incomplete_.fetch_add(n); }

 private:
  DeviceContext context_;
  std::atomic<DeviceState> state_{DeviceState::kUnconfigured};
  bool configured_ = false;  // a successful configure() happened (kError → reset → kInactive)
  mutable std::mutex error_mutex_;
  Status error_;
  std::atomic<std::uint64_t> received_{0};
  std::atomic<std::uint64_t> lost_{0};
  std::atomic<std::uint64_t> late_{0};
  std::atomic<std::uint64_t> incomplete_{0};
  std::atomic<std::uint64_t> errors_{0};
  std::atomic<std::int64_t> last_host_ns_{-1};
};

// Parses `yaml` (the device's own map) and configures `device` with it, reporting unknown keys as
// the daemon would (keys `kind` and `backend` are accepted and ignored). For tests and tools.
Status configure_from_yaml(Device& device, std::string_view yaml, std::string_view name = "config");

}  // namespace hc::devices
