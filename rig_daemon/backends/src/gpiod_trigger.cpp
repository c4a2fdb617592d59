// Backend "gpiod": trigger pulses on GPIO output lines through libgpiod 1.6, as a
// devices::Trigger.
//
// Config keys:
//   chip            gpiochip name, number or path (default gpiochip0)
//   lines           line offsets driven together (required), e.g. [17, 27]
//   active_low      invert the outputs (default false)
//   report_falling  also report falling edges (default false)
// A pulse train runs on its own thread with absolute CLOCK_MONOTONIC deadlines
// (clock_nanosleep TIMER_ABSTIME), so timing errors do not accumulate; every edge is stamped with
// CLOCK_MONOTONIC right after the lines were set (host_ns; libgpiod output has no device clock).
#include <gpiod.h>
#include <time.h>

#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>

#include "backend_factories.h"
#include "common/clock.h"

namespace hc::rig {
namespace {

using devices::PulseTrain;
using devices::TriggerEdge;

void sleep_until(std::int64_t t_ns) {
  timespec ts{static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

class GpiodTrigger final : public devices::Trigger {
 public:
  explicit GpiodTrigger(const devices::DeviceContext& ctx) : Trigger(ctx) {}
  ~GpiodTrigger() override {
    stop_thread();
    release();
  }

  bool running() const override { return running_.load(); }
  std::vector<std::uint32_t> lines() const override { return lines_; }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("chip", chip_);
    node.required("lines", lines_);
    node.optional("active_low", active_low_);
    node.optional("report_falling", report_falling_);
    HC_RETURN_IF_ERROR(node.status());
    if (lines_.empty()) return invalid_argument("lines: expected at least one line offset");
    if (lines_.size() > GPIOD_LINE_BULK_MAX_LINES)
      return invalid_argument("lines: at most 64 lines");
    return {};
  }

  Status on_activate() override {
    chip_handle_ = ::gpiod_chip_open_lookup(chip_.c_str());
    if (chip_handle_ == nullptr)
      return Status(
          errno == ENOENT || errno == ENODEV ? StatusCode::kNotFound : StatusCode::kUnavailable,
          "trigger '" + name() + "': GPIO chip '" + chip_ + "': " + std::strerror(errno));
    std::vector<unsigned int> offsets(lines_.begin(), lines_.end());
    gpiod_line_bulk_init(&bulk_);
    if (::gpiod_chip_get_lines(chip_handle_, offsets.data(), static_cast<unsigned>(offsets.size()),
                               &bulk_) != 0) {
      Status s =
          invalid_argument("trigger '" + name() + "': lines not on chip '" + chip_ + "' (it has " +
                           std::to_string(::gpiod_chip_num_lines(chip_handle_)) + ")");
      release();
      return s;
    }
    std::vector<int> zeros(offsets.size(), 0);
    gpiod_line_request_config config{"hardcopy-rigd", GPIOD_LINE_REQUEST_DIRECTION_OUTPUT,
                                     active_low_ ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0};
    if (::gpiod_line_request_bulk(&bulk_, &config, zeros.data()) != 0) {
      Status s(StatusCode::kUnavailable,
               "trigger '" + name() + "': requesting lines: " + std::strerror(errno));
      release();
      return s;
    }
    requested_ = true;
    pulse_index_ = 0;
    return {};
  }

  Status on_deactivate() override {
    stop_thread();
    release();
    return {};
  }
  Status on_reset() override {
    stop_thread();
    release();
    return {};
  }

  Status on_start(const PulseTrain& train) override {
    if (running_) return failed_precondition("trigger '" + name() + "': a pulse train runs");
    stop_thread();
    stop_ = false;
    running_ = true;
    thread_ = std::thread([this, train] { run(train); });
    return {};
  }
  Status on_stop() override {
    stop_thread();
    return {};
  }
  Status on_fire() override {
    if (running_) return failed_precondition("trigger '" + name() + "': a pulse train runs");
    return pulse(monotonic_ns(), 1e-3);
  }

  Result<std::size_t> on_read(std::vector<TriggerEdge>& out, devices::Duration timeout) override {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, timeout, [&] { return !edges_.empty(); });
    const std::size_t n = edges_.size();
    out.insert(out.end(), edges_.begin(), edges_.end());
    edges_.clear();
    return n;
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = "GPIO lines (libgpiod)";
    std::string l;
    for (auto x : lines_) {
      if (!l.empty()) l.push_back(',');
      l.append(std::to_string(x));
    }
    info.details = {{"chip", chip_}, {"lines", l}};
  }

 private:
  Status set_all(int value) {
    std::vector<int> values(lines_.size(), value);
    if (::gpiod_line_set_value_bulk(&bulk_, values.data()) != 0)
      return Status(StatusCode::kUnavailable,
                    "trigger '" + name() + "': setting lines: " + std::strerror(errno));
    return {};
  }

  // One pulse starting at t_ns (absolute, CLOCK_MONOTONIC).
  Status pulse(std::int64_t t_ns, double width_s) {
    sleep_until(t_ns);
    HC_RETURN_IF_ERROR(set_all(1));
    const std::int64_t rise = monotonic_ns();
    const std::uint64_t index = pulse_index_++;
    push_edges(index, true, rise);
    sleep_until(t_ns + static_cast<std::int64_t>(width_s * 1e9));
    HC_RETURN_IF_ERROR(set_all(0));
    if (report_falling_) push_edges(index, false, monotonic_ns());
    return {};
  }

  void push_edges(std::uint64_t index, bool rising, std::int64_t t) {
    {
      std::lock_guard lock(mutex_);
      for (std::uint32_t line : lines_) {
        TriggerEdge e;
        e.index = index;
        e.line = line;
        e.rising = rising;
        e.host_ns = clock().is_simulated() ? clock().now_ns() : t;
        e.device_counter = index;
        edges_.push_back(e);
      }
    }
    cv_.notify_all();
  }

  void run(PulseTrain train) {
    const std::int64_t t0 = monotonic_ns() + 1'000'000;  // first pulse 1 ms from now
    for (std::uint64_t k = 0; (train.count == 0 || k < train.count) && !stop_; ++k) {
      const auto t = t0 + static_cast<std::int64_t>(static_cast<double>(k) * 1e9 / train.rate_hz);
      if (!pulse(t, train.pulse_width_s).ok()) break;
    }
    running_ = false;
  }

  void stop_thread() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    running_ = false;
  }

  void release() {
    if (requested_) ::gpiod_line_release_bulk(&bulk_);
    requested_ = false;
    if (chip_handle_ != nullptr) ::gpiod_chip_close(chip_handle_);
    chip_handle_ = nullptr;
  }

  std::string chip_ = "gpiochip0";
  std::vector<std::uint32_t> lines_;
  bool active_low_ = false;
  bool report_falling_ = false;
  gpiod_chip* chip_handle_ = nullptr;
  gpiod_line_bulk bulk_{};
  bool requested_ = false;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> running_{false};
  std::uint64_t pulse_index_ = 0;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<TriggerEdge> edges_;
};

}  // namespace

Result<std::unique_ptr<devices::Trigger>> make_gpiod_trigger(const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::Trigger>(new GpiodTrigger(ctx));
}

}  // namespace hc::rig
