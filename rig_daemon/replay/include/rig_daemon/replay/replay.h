// Replay: a recorded session (MCAP, laid out as rig_daemon/session/topics.h describes)
// served through the same device interfaces by the "replay" backends, so the daemon, the scheduler
// and the tests cannot tell a replay from a capture.
//
// Determinism: replayed items carry exactly what was recorded (host_ns = the message's log_time,
// counters, device stamps, payload), so re-recording a replay reproduces the same messages. Only
// the pacing follows the device's Clock: the item recorded at log time T becomes available at
//   anchor + (T - session start) / speed
// on the clock, where anchor is the clock time of the first activate() of any replay device of the
// session. With a SimulatedClock in auto-advance mode a replay runs as fast as the CPU allows.
//
// Each replay device reads the channel whose metadata says device = its `source` (default: its own
// name) and whose kind matches; a missing stream is kNotFound at configure().
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "rig_daemon/devices/clock.h"
#include "rig_daemon/devices/device.h"
#include "rig_daemon/devices/registry.h"

namespace hc::devices {

class ReplaySession {
 public:
  struct Options {
    double speed = 1.0;  // > 0; 10 = ten times faster than recorded
    Status validate() const;
  };

  // One recorded device stream.
  struct Stream {
    std::string device;
    DeviceKind kind = DeviceKind::kCamera;
    std::string backend;  // the backend that recorded it
    std::string topic;
    std::uint16_t channel_id = 0;
    std::string schema;  // schema name, e.g. "hardcopy.WrenchSample", "foxglove.RawImage"
    std::uint64_t messages = 0;
  };

  // One recorded message (copied out of the file).
  struct Message {
    std::int64_t log_time_ns = 0;
    std::int64_t publish_time_ns = 0;
    std::uint32_t sequence = 0;
    std::vector<std::uint8_t> data;
  };

  // Opens the session and lists its device streams (channels whose metadata names a device and
  // kind; "/<device>/command" arm channels are the commands, not the state stream). Errors: the
  // reader's (not found, not MCAP, bad CRC ...).
  static Result<std::shared_ptr<ReplaySession>> open(const std::filesystem::path& path,
                                                     const Options& options);
  static Result<std::shared_ptr<ReplaySession>> open(const std::filesystem::path& path);
  ~ReplaySession();

  const std::vector<Stream>& streams() const { return streams_; }
  // The stream of `device` of `kind`, or null.
  const Stream* find(std::string_view device, DeviceKind kind) const;
  // Earliest and latest log_time of the device streams, ns.
  std::int64_t start_ns() const { return start_ns_; }
  std::int64_t end_ns() const { return end_ns_; }

  // Messages of `stream` with from_ns <= log_time < to_ns in log-time order; `visit` returns false
  // to stop early.
  Status read(const Stream& stream, std::int64_t from_ns, std::int64_t to_ns,
              const std::function<bool(const Message&)>& visit) const;

  // Pacing (see the file comment). anchor() fixes the anchor at clock.now_ns() on its first call.
  void anchor(const Clock& clock);
  // Clock time at which the item recorded at `recorded_ns` becomes available (anchor first).
  std::int64_t due_clock_ns(std::int64_t recorded_ns) const;
  // The latest recorded time that is available at clock time `clock_ns`.
  std::int64_t recorded_ns_at(std::int64_t clock_ns) const;

 private:
  class Impl;
  ReplaySession() = default;
  std::unique_ptr<Impl> impl_;
  Options options_;
  std::vector<Stream> streams_;
  std::int64_t start_ns_ = 0;
  std::int64_t end_ns_ = 0;
  mutable std::mutex mutex_;
  std::optional<std::int64_t> anchor_ns_;
};

// Registers "replay" for every device kind, each device serving its stream of `session`.
// kInvalidArgument if `session` is null or a kind already has a "replay" backend.
Status register_replay_backends(BackendRegistry& registry, std::shared_ptr<ReplaySession> session);

}  // namespace hc::devices
