#include "firmware_host/driver/shared_device.h"

#include <algorithm>
#include <map>
#include <thread>

namespace hc::fw {
namespace {

using std::chrono::microseconds;

// Longest time one reader holds the board while waiting, so the other reader is never blocked long.
constexpr microseconds kPumpSlice{2'000};
constexpr std::size_t kMaxQueuedErrors = 10'000;

std::mutex& registry_mutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, std::weak_ptr<SharedFirmwareDevice>>& registry() {
  static std::map<std::string, std::weak_ptr<SharedFirmwareDevice>> r;
  return r;
}

}  // namespace

SharedFirmwareDevice::SharedFirmwareDevice(std::unique_ptr<FirmwareDevice> device)
    : device_(std::move(device)) {}

SharedFirmwareDevice::~SharedFirmwareDevice() = default;

Result<std::shared_ptr<SharedFirmwareDevice>> SharedFirmwareDevice::create(
    const OpenOptions& options) {
  HC_ASSIGN_OR_RETURN(std::unique_ptr<FirmwareDevice> dev, FirmwareDevice::open(options));
  return std::shared_ptr<SharedFirmwareDevice>(new SharedFirmwareDevice(std::move(dev)));
}

Result<std::shared_ptr<SharedFirmwareDevice>> SharedFirmwareDevice::acquire(
    const OpenOptions& options) {
  std::lock_guard<std::mutex> lock(registry_mutex());
  auto& slot = registry()[options.device];
  if (std::shared_ptr<SharedFirmwareDevice> existing = slot.lock()) return existing;
  HC_ASSIGN_OR_RETURN(std::shared_ptr<SharedFirmwareDevice> made, create(options));
  slot = made;
  return made;
}

DeviceInfo SharedFirmwareDevice::info() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->info();
}

Status SharedFirmwareDevice::configure_trigger(const TriggerConfig& config) {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->configure_trigger(config);
}

Status SharedFirmwareDevice::start(std::uint32_t start_delay_us) {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->start(start_delay_us);
}

Status SharedFirmwareDevice::stop() {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->stop();
}

Status SharedFirmwareDevice::pump(microseconds slice) {
  std::vector<Event> events;
  HC_ASSIGN_OR_RETURN(const std::size_t n, device_->poll(events, slice));
  (void)n;
  for (const Event& e : events) {
    switch (e.kind) {
      case Event::Kind::kTriggerEdge:
        if (edges_.size() == kMaxQueuedEvents) {
          edges_.pop_front();
          ++overflows_;
        }
        edges_.push_back(e.edge);
        break;
      case Event::Kind::kAdcSample:
        if (samples_.size() == kMaxQueuedEvents) {
          samples_.pop_front();
          ++overflows_;
        }
        samples_.push_back(e.sample);
        break;
      case Event::Kind::kError:
        if (errors_.size() < kMaxQueuedErrors)
          errors_.push_back(e.error);
        else
          ++overflows_;
        break;
      case Event::Kind::kHeartbeat:
        break;  // kept by the device as last_heartbeat()
    }
  }
  return {};
}

template <typename T>
Result<std::size_t> SharedFirmwareDevice::read_queue(std::deque<T>& queue, std::vector<T>& out,
                                                     microseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!link_status_.ok()) return link_status_;
  const auto fail = [this](const Status& st) {
    link_status_ = st;
    return st;
  };
  if (Status st = pump(microseconds(0)); !st.ok()) return fail(st);
  const std::int64_t deadline = device_->now_ns() + timeout.count() * 1000;
  while (queue.empty()) {
    const std::int64_t left_ns = deadline - device_->now_ns();
    if (left_ns <= 0) break;
    const microseconds slice =
        std::min(kPumpSlice, microseconds(std::max<std::int64_t>(1, left_ns / 1000)));
    if (Status st = pump(slice); !st.ok()) return fail(st);
    if (queue.empty()) {  // let another reader in between slices
      lock.unlock();
      std::this_thread::yield();
      lock.lock();
    }
  }
  const std::size_t n = queue.size();
  out.insert(out.end(), queue.begin(), queue.end());
  queue.clear();
  return n;
}

Result<std::size_t> SharedFirmwareDevice::read_edges(std::vector<TriggerEdgeEvent>& out,
                                                     microseconds timeout) {
  return read_queue(edges_, out, timeout);
}

Result<std::size_t> SharedFirmwareDevice::read_samples(std::vector<AdcSampleEvent>& out,
                                                       microseconds timeout) {
  return read_queue(samples_, out, timeout);
}

std::vector<DeviceErrorEvent> SharedFirmwareDevice::take_errors() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<DeviceErrorEvent> out;
  out.swap(errors_);
  return out;
}

std::optional<HeartbeatStatus> SharedFirmwareDevice::last_heartbeat() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->last_heartbeat();
}

LinkStats SharedFirmwareDevice::link_stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->link_stats();
}

std::uint64_t SharedFirmwareDevice::queue_overflows() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return overflows_;
}

std::int64_t SharedFirmwareDevice::device_to_host_ns(std::uint64_t device_time_us) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return device_->device_to_host_ns(device_time_us);
}

}  // namespace hc::fw
