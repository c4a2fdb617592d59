// One firmware board serves two rig devices — the trigger (edges) and the FSR (ADC samples) — often
// from different threads. SharedFirmwareDevice wraps a FirmwareDevice with a mutex and
// demultiplexes its events into separate queues, so the trigger backend reads edges and the FSR
// backend reads samples without stealing each other's events. acquire() hands every caller naming
// the same device string ("sim", "usb:1209:0001:SERIAL", ...) the same open board.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/status.h"
#include "firmware_host/driver/firmware_device.h"

namespace hc::fw {

class SharedFirmwareDevice {
 public:
  // Per-stream queue bound; beyond it the oldest events are discarded and counted (a consumer that
  // never reads must not grow memory without bound).
  static constexpr std::size_t kMaxQueuedEvents = 1 << 20;

  // The shared board for options.device, opened (with `options`) on first use; later callers get
  // the same object and their options are ignored. Closed when the last holder releases it.
  static Result<std::shared_ptr<SharedFirmwareDevice>> acquire(const OpenOptions& options);
  // A private board (not registered for sharing), e.g. for tests that need independent simulators.
  static Result<std::shared_ptr<SharedFirmwareDevice>> create(const OpenOptions& options);
  ~SharedFirmwareDevice();

  DeviceInfo info() const;
  Status configure_trigger(const TriggerConfig& config);
  Status start(std::uint32_t start_delay_us = 0);
  Status stop();

  // Append queued events of one kind, waiting up to `timeout` for at least one. While waiting the
  // board is polled in short slices so other threads can use it meanwhile.
  Result<std::size_t> read_edges(std::vector<TriggerEdgeEvent>& out,
                                 std::chrono::microseconds timeout);
  Result<std::size_t> read_samples(std::vector<AdcSampleEvent>& out,
                                   std::chrono::microseconds timeout);
  // Device error reports received so far (and not yet taken).
  std::vector<DeviceErrorEvent> take_errors();
  std::optional<HeartbeatStatus> last_heartbeat() const;
  LinkStats link_stats() const;
  // Events discarded because a queue exceeded kMaxQueuedEvents.
  std::uint64_t queue_overflows() const;
  std::int64_t device_to_host_ns(std::uint64_t device_time_us) const;

  // Runs `f(FirmwareDevice&)` under the lock (fault injection through simulator(), diagnostics).
  template <typename F>
  auto with_device(F&& f) {
    std::lock_guard<std::mutex> lock(mutex_);
    return f(*device_);
  }

 private:
  explicit SharedFirmwareDevice(std::unique_ptr<FirmwareDevice> device);
  // Polls the board once for up to `slice` and sorts the events into the queues. Lock held.
  Status pump(std::chrono::microseconds slice);
  template <typename T>
  Result<std::size_t> read_queue(std::deque<T>& queue, std::vector<T>& out,
                                 std::chrono::microseconds timeout);

  mutable std::mutex mutex_;
  std::unique_ptr<FirmwareDevice> device_;
  std::deque<TriggerEdgeEvent> edges_;
  std::deque<AdcSampleEvent> samples_;
  std::vector<DeviceErrorEvent> errors_;
  std::uint64_t overflows_ = 0;
  Status link_status_;  // first link failure, sticky
};

}  // namespace hc::fw
