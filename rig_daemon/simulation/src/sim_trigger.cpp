// The "sim" trigger: pulse trains on the simulated lines, edges on the world's clock.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_devices_internal.h"

namespace hc::devices::sim_backend {

namespace {

class SimTrigger final : public Trigger {
 public:
  SimTrigger(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Trigger(ctx), parts_(ctx, std::move(world)) {}

  bool running() const override {
    return state() == DeviceState::kActive &&
           parts_.world().trigger_running(parts_.world().clock().now_ns());
  }
  std::vector<std::uint32_t> lines() const override { return lines_; }

  std::optional<std::int64_t> next_due() const {
    const auto rise = parts_.world().rising_edge_ns(k_, parts_.world().clock().now_ns());
    if (!rise) return std::nullopt;
    return falling_next_ ? *rise + parts_.world().pulse_width_ns(k_) : *rise;
  }
  void emit(std::vector<TriggerEdge>& out) {
    const std::int64_t t = *next_due();
    const bool rising = !falling_next_;
    const std::uint64_t k = k_;
    if (rising && report_falling_) {
      falling_next_ = true;
    } else {
      falling_next_ = false;
      ++k_;
    }
    if (rising && parts_.lost(t)) {  // a lost edge takes its falling edge with it
      count_lost(lines_.size());
      falling_next_ = false;
      k_ = k + 1;
      return;
    }
    for (std::uint32_t line : lines_) {
      TriggerEdge e;
      e.index = k - first_;
      e.line = line;
      e.rising = rising;
      e.host_ns = t;
      e.device_stamp_ns = parts_.device_stamp(t);
      e.device_counter = k;
      out.push_back(e);
    }
  }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("lines", lines_);
    node.optional("report_falling", report_falling_);
    if (lines_.empty()) node.error("lines", "needs at least one line");
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    k_ = first_ = parts_.world().pulses_by(now);
    falling_next_ = false;
    return {};
  }
  Status on_deactivate() override {
    parts_.world().trigger_stop(parts_.world().clock().now_ns());
    return {};
  }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Status on_start(const PulseTrain& train) override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    return parts_.world().trigger_start(train, now);
  }
  Status on_stop() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    parts_.world().trigger_stop(now);
    return {};
  }
  Status on_fire() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    return parts_.world().trigger_fire(1e-3, now);
  }
  Result<std::size_t> on_read(std::vector<TriggerEdge>& out, Duration timeout) override {
    return stream_read(*this, parts_, out, timeout);
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated trigger lines";
    std::string l;
    for (std::uint32_t line : lines_) {
      if (!l.empty()) l.push_back(',');
      l.append(std::to_string(line));
    }
    info.details = {{"lines", l}};
  }

 private:
  SimParts parts_;
  std::vector<std::uint32_t> lines_{0};
  bool report_falling_ = false;
  std::uint64_t k_ = 0;
  std::uint64_t first_ = 0;
  bool falling_next_ = false;
};

}  // namespace

DeviceFactory<Trigger> trigger_factory(std::shared_ptr<World> world) {
  return sim_factory<Trigger, SimTrigger>(std::move(world));
}

}  // namespace hc::devices::sim_backend
