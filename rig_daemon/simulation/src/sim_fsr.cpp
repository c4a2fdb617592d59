// The "sim" FSR: the world's contact force through the FSR's power-law response.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_devices_internal.h"

namespace hc::devices::sim_backend {

namespace {

class SimFsr final : public Fsr {
 public:
  SimFsr(const DeviceContext& ctx, std::shared_ptr<World> world)
      : Fsr(ctx), parts_(ctx, std::move(world)) {}

  FsrCalibration calibration() const override { return cal_; }
  double sample_rate_hz() const override { return triggered_ ? 0.0 : rate_hz_; }

  // Time of item k_ (a period, or the rising edge k_ plus the ADC conversion delay).
  std::optional<std::int64_t> item_time() const {
    if (!triggered_) return t0_ + seconds_to_ns(static_cast<double>(k_) / rate_hz_);
    const auto edge = parts_.world().rising_edge_ns(k_, parts_.world().clock().now_ns());
    if (!edge) return std::nullopt;
    return *edge + conversion_ns_;
  }
  std::optional<std::int64_t> next_due() const {
    const auto t = item_time();
    if (!t) return std::nullopt;
    return *t + parts_.delay_ns(*t);
  }
  void emit(std::vector<FsrSample>& out) {
    const std::int64_t t = *item_time();
    const std::uint64_t k = k_++;
    const double noise = parts_.gauss();
    if (parts_.lost(t)) {
      count_lost(1);
      return;
    }
    const double force = std::max(0.0, parts_.world().true_force_n(t) + parts_.spike_n(t));
    const double creep = 1.0 + creep_per_s_ * static_cast<double>(t - t0_) * 1e-9;
    const double raw = cal_.to_raw(force * gain_ * creep) + noise_raw_ * noise;
    FsrSample s;
    s.raw = static_cast<std::uint32_t>(std::clamp(std::round(raw), 0.0, cal_.full_scale));
    s.force_n = cal_.to_newtons(s.raw);
    s.channel = channel_;
    s.sequence = triggered_ ? k - first_edge_ : k - 1;
    const std::int64_t delay = parts_.delay_ns(t);
    s.host_ns = t + delay;
    s.device_stamp_ns = parts_.device_stamp(t);
    if (triggered_) s.trigger_index = k;
    if (delay > late_ns_) count_late(1);
    out.push_back(s);
  }

 protected:
  Status on_configure(ConfigNode node) override {
    std::string sampling = "periodic";
    node.optional("sampling", sampling, {"periodic", "triggered"});
    triggered_ = sampling == "triggered";
    node.optional("rate_hz", rate_hz_, Bounds{0.0, 100000.0, true, false});
    node.optional("channel", channel_);
    node.optional("noise_raw", noise_raw_, Bounds::non_negative());
    node.optional("gain", gain_, Bounds::positive());
    node.optional("creep_per_s", creep_per_s_);
    double conversion_s = 20e-6;
    node.optional("conversion_s", conversion_s, Bounds::non_negative());
    conversion_ns_ = seconds_to_ns(conversion_s);
    double late_s = 0.005;
    node.optional("late_after_s", late_s, Bounds::positive());
    late_ns_ = seconds_to_ns(late_s);
    read_calibration(node, &cal_);
    return node.status();
  }
  Status on_activate() override {
    const std::int64_t now = parts_.world().clock().now_ns();
    HC_RETURN_IF_ERROR(parts_.connected(now));
    t0_ = now;
    // Triggered: follow the edges from the next one on; periodic: first sample one period in.
    k_ = triggered_ ? parts_.world().pulses_by(now) : 1;
    first_edge_ = k_;
    return {};
  }
  Status on_deactivate() override { return {}; }
  Status on_reset() override { return parts_.connected(parts_.world().clock().now_ns()); }
  Result<std::size_t> on_read(std::vector<FsrSample>& out, Duration timeout) override {
    return stream_read(*this, parts_, out, timeout);
  }
  void describe(DeviceInfo& info) const override {
    info.model = "simulated FSR";
    info.details = {{"sampling", triggered_ ? "triggered" : "periodic"},
                    {"rate_hz", std::to_string(rate_hz_)}};
  }

 private:
  SimParts parts_;
  FsrCalibration cal_;
  bool triggered_ = false;
  double rate_hz_ = 1000.0;
  std::uint32_t channel_ = 0;
  double noise_raw_ = 2.0;
  double gain_ = 1.0;
  double creep_per_s_ = 0.0;
  std::int64_t conversion_ns_ = 20'000;
  std::int64_t late_ns_ = 5'000'000;
  std::int64_t t0_ = 0;
  std::uint64_t k_ = 1;
  std::uint64_t first_edge_ = 0;
};

}  // namespace

DeviceFactory<Fsr> fsr_factory(std::shared_ptr<World> world) {
  return sim_factory<Fsr, SimFsr>(std::move(world));
}

}  // namespace hc::devices::sim_backend
