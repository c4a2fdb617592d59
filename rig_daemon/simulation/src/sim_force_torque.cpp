// The "sim" force-torque sensor: the world's contact wrench with noise, bias and faults.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_devices_internal.h"

namespace hc::devices::sim_backend {

namespace {

class SimForceTorque final : public ForceTorque {
 public:
  SimForceTorque(const DeviceContext& ctx, std::shared_ptr<World> world)
      : ForceTorque(ctx), parts_(ctx, std::move(world)) {}

  WrenchCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return rate_hz_; }

  std::optional<std::int64_t> next_due() const {
    const std::int64_t t = t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
    return t + parts_.delay_ns(t);
  }
  void emit(std::vector<WrenchSample>& out) {
    const std::int64_t t = t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
    const std::uint64_t k = k_++;
    // Draw the noise first so that a lost sample does not shift later samples' noise.
    std::array<double, 6> noise{};
    for (double& n : noise) n = parts_.gauss();
    if (parts_.lost(t)) {
      count_lost(1);
      return;
    }
    const double force = parts_.world().true_force_n(t) + parts_.spike_n(t);
    const double drift = drift_n_per_s_ * static_cast<double>(t - t0_) * 1e-9 + offset_n_;
    std::array<double, 6> value{
        noise_n_ * noise[0],  noise_n_ * noise[1],  force + drift + noise_n_ * noise[2],
        noise_nm_ * noise[3], noise_nm_ * noise[4], noise_nm_ * noise[5]};
    WrenchSample s;
    for (int i = 0; i < 6; ++i) {
      const double cpu = i < 3 ? cal_.counts_per_n : cal_.counts_per_nm;
      const double c = std::clamp(std::round(value[i] * cpu),
                                  static_cast<double>(std::numeric_limits<std::int32_t>::min()),
                                  static_cast<double>(std::numeric_limits<std::int32_t>::max()));
      s.counts[i] = static_cast<std::int32_t>(c);
      last_counts_[i] = s.counts[i];
      const double si = (static_cast<double>(s.counts[i]) - bias_[i]) / cpu;
      if (i < 3)
        s.force_n[i] = si;
      else
        s.torque_nm[i - 3] = si;
    }
    s.rdt_sequence = static_cast<std::uint32_t>(k);
    s.ft_sequence = static_cast<std::uint32_t>(k + ft_offset_);
    s.sequence = k - 1;
    const std::int64_t delay = parts_.delay_ns(t);
    s.host_ns = t + delay;
    s.device_stamp_ns = parts_.device_stamp(t);
    if (delay > late_ns_) count_late(1);
    out.push_back(s);
  }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("rate_hz", rate_hz_, Bounds{0.0, 7000.0, true, false});
    node.optional("noise_n", noise_n_, Bounds::non_negative());
    node.optional("noise_nm", noise_nm_, Bounds::non_negative());
    node.optional("drift_n_per_s", drift_n_per_s_);
    node.optional("offset_n", offset_n_);
    node.optional("counts_per_n", cal_.counts_per_n, Bounds::positive());
    node.optional("counts_per_nm", cal_.counts_per_nm, Bounds::positive());
    double late_s = 0.005;
    node.optional("late_after_s", late_s, Bounds::positive());
    late_ns_ = seconds_to_ns(late_s);
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    t0_ = now;
    k_ = 1;
    ft_offset_ = parts_.world().device_seed(name() + "/ft") % 100000;
    return {};
  }
  Status on_deactivate() override { return {}; }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Result<std::size_t> on_read(std::vector<WrenchSample>& out, Duration timeout) override {
    return stream_read(*this, parts_, out, timeout);
  }
  Status on_bias() override {
    for (int i = 0; i < 6; ++i) bias_[i] = static_cast<double>(last_counts_[i]);
    return {};
  }
  Status on_clear_bias() override {
    bias_.fill(0.0);
    return {};
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated ATI Net F/T";
    info.details = {{"rate_hz", std::to_string(rate_hz_)},
                    {"noise_n", std::to_string(noise_n_)},
                    {"drift_n_per_s", std::to_string(drift_n_per_s_)}};
  }

 private:
  SimParts parts_;
  WrenchCalibration cal_;
  double rate_hz_ = 1000.0;
  double noise_n_ = 1.0 / 24.0;  // Nano25 resolution (thesis 5.6: 1/24 N)
  double noise_nm_ = 1.0 / 1320.0;
  double drift_n_per_s_ = 0.002;
  double offset_n_ = 0.0;
  std::int64_t late_ns_ = 5'000'000;
  std::int64_t t0_ = 0;
  std::uint64_t k_ = 1;
  std::uint64_t ft_offset_ = 0;
  std::array<std::int32_t, 6> last_counts_{};
  std::array<double, 6> bias_{};
};

}  // namespace

DeviceFactory<ForceTorque> force_torque_factory(std::shared_ptr<World> world) {
  return sim_factory<ForceTorque, SimForceTorque>(std::move(world));
}

}  // namespace hc::devices::sim_backend
