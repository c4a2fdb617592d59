// Shared pieces of the "sim" backends (sim_*.cpp, one device kind per file; sim_devices.cpp
// registers them): the simulated world's parts every device uses, the read loop of a stream and the
// factory. Not a public header: the public interface is sim_backends.h (register_sim_backends).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "rig_daemon/simulation/sim_backends.h"
#include "rig_daemon/simulation/sim_world.h"

namespace hc::devices::sim_backend {

using sim::Fault;
using sim::World;

// Items per read(): bounds memory when a reader lags.
inline constexpr std::size_t kMaxBatch = 4096;

inline std::int64_t seconds_to_ns(double s) {
  return static_cast<std::int64_t>(std::llround(s * 1e9));
}

// Reads/writes fail while a disconnect fault covers `t`.
inline Status check_connected(const World& world, const std::string& name, std::int64_t t) {
  if (auto f = world.fault(name, Fault::Kind::kDisconnect, t))
    return Status(StatusCode::kUnavailable, "simulated device '" + name + "' disconnected");
  return {};
}

// What every simulated device shares: the world, seeded generators, a device clock offset and the
// fault checks of one item at time t.
class SimParts {
 public:
  SimParts(const DeviceContext& ctx, std::shared_ptr<World> world)
      : world_(std::move(world)),
        name_(ctx.name),
        noise_(world_->device_seed(ctx.name)),
        faults_(world_->device_seed(ctx.name + "/faults")) {
    // A device clock that started at a random moment before the host's (ns).
    device_offset_ns_ =
        static_cast<std::int64_t>(world_->device_seed(ctx.name + "/clock") % 1'000'000'000'000ULL);
  }

  World& world() const { return *world_; }
  double gauss() { return normal_(noise_); }
  std::int64_t device_stamp(std::int64_t t) const { return t + device_offset_ns_; }

  // Whether the item due at t is lost to a stall or dropout (consumes one fault draw either way,
  // so that dropouts do not shift the noise sequence).
  bool lost(std::int64_t t) {
    const double u = uniform_(faults_);
    if (world_->fault(name_, Fault::Kind::kStall, t)) return true;
    if (auto f = world_->fault(name_, Fault::Kind::kDropout, t)) return u < f->probability;
    return false;
  }
  std::int64_t delay_ns(std::int64_t t) const {
    auto f = world_->fault(name_, Fault::Kind::kDelay, t);
    return f ? seconds_to_ns(std::max(0.0, f->magnitude)) : 0;
  }
  double spike_n(std::int64_t t) const {
    auto f = world_->fault(name_, Fault::Kind::kSpike, t);
    return f ? f->magnitude : 0.0;
  }
  Status connected(std::int64_t t) const { return check_connected(*world_, name_, t); }

 private:
  std::shared_ptr<World> world_;
  std::string name_;
  std::mt19937_64 noise_;
  std::mt19937_64 faults_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::int64_t device_offset_ns_ = 0;
};

// The loop every periodic or event-driven stream shares. `next_due()` is the time the next item
// becomes available (nullopt: none scheduled yet); `emit(out)` produces (or loses) that item and
// returns false if it was lost.
template <typename Self, typename Item>
Result<std::size_t> stream_read(Self& self, SimParts& parts, std::vector<Item>& out,
                                Duration timeout) {
  Clock& clock = parts.world().clock();
  const std::int64_t deadline = clock.now_ns() + std::max<std::int64_t>(0, timeout.count());
  const std::size_t before = out.size();
  while (true) {
    const std::int64_t now = clock.now_ns();
    HC_RETURN_IF_ERROR(parts.connected(now));
    std::optional<std::int64_t> due;
    while (out.size() - before < kMaxBatch && (due = self.next_due()) && *due <= now)
      self.emit(out);
    if (out.size() > before) return out.size() - before;
    if (now >= deadline) return std::size_t{0};
    // Wait for the next item (or a little, when none is scheduled: a trigger may start).
    const std::int64_t wake = due ? std::min(*due, deadline) : std::min(now + 1'000'000, deadline);
    clock.sleep_until_ns(std::max(wake, now + 1));
  }
}

template <typename D, typename Impl>
DeviceFactory<D> sim_factory(std::shared_ptr<World> world) {
  return [world](const DeviceContext& ctx) -> Result<std::unique_ptr<D>> {
    return std::unique_ptr<D>(std::make_unique<Impl>(ctx, world));
  };
}

// The factories of the device kinds (sim_<kind>.cpp).
DeviceFactory<Camera> camera_factory(std::shared_ptr<World> world);
DeviceFactory<Trigger> trigger_factory(std::shared_ptr<World> world);
DeviceFactory<Fsr> fsr_factory(std::shared_ptr<World> world);
DeviceFactory<ForceTorque> force_torque_factory(std::shared_ptr<World> world);
DeviceFactory<Arm> arm_factory(std::shared_ptr<World> world);

}  // namespace hc::devices::sim_backend
