// Backend "netft": an ATI Net F/T through NetFtClient, as a devices::ForceTorque.
//
// Config keys: those of NetFtOptions (host, port, calibration_source, http_port, counts_per_force,
// counts_per_torque, force_unit, torque_unit, start_attempts, start_timeout_s, buffered,
// receive_buffer_bytes) plus
//   rate_hz           the RDT output rate set on the sensor (informational; default 7000)
//   internal_rate_hz  ft_sequence rate, for device_stamp_ns (Net F/T 7000, Axia 7912)
//   bias              "host" (default: counts stay raw, SI values minus the tared counts) or
//                     "device" (RDT command 0x42: the sensor subtracts; counts are then biased)
//   stall_timeout_s   no record for this long while active: resend start (up to 3 x 0.1 s);
//                     if the sensor still sends nothing, read() fails with kUnavailable (the
//                     device enters kError; reset() + activate() reconnects). Default 0.5 s.
#include <memory>

#include "backend_factories.h"
#include "rig_daemon/backends/netft_client.h"

namespace hc::rig {
namespace {

using devices::DeviceContext;
using devices::Duration;
using devices::WrenchSample;

class NetFtForceTorque final : public devices::ForceTorque {
 public:
  explicit NetFtForceTorque(const DeviceContext& ctx) : ForceTorque(ctx) {}

  devices::WrenchCalibration calibration() const override {
    const rdt::Calibration& c = client_ ? client_->calibration() : options_.calibration;
    devices::WrenchCalibration w;
    auto fu = rdt::newtons_per_force_unit(c.force_unit);
    auto tu = rdt::newton_metres_per_torque_unit(c.torque_unit);
    w.counts_per_n = c.counts_per_force / (fu.ok() ? *fu : 1.0);
    w.counts_per_nm = c.counts_per_torque / (tu.ok() ? *tu : 1.0);
    return w;
  }
  double sample_rate_hz() const override { return rate_hz_; }

 protected:
  Status on_configure(ConfigNode node) override {
    NetFtOptions o;
    Status s = o.read(node);
    node.optional("rate_hz", rate_hz_, Bounds{0.0, rdt::kMaxRateHz, true, false});
    node.optional("internal_rate_hz", internal_rate_hz_, Bounds::positive());
    node.optional("bias", bias_mode_, {"host", "device"});
    node.optional("stall_timeout_s", stall_timeout_s_, Bounds::between(0.01, 60));
    HC_RETURN_IF_ERROR(node.status());
    HC_RETURN_IF_ERROR(s);
    HC_RETURN_IF_ERROR(o.validate());
    options_ = o;
    return {};
  }

  Status on_activate() override {
    HC_ASSIGN_OR_RETURN(client_, NetFtClient::open(options_));
    Status s = client_->start();
    if (!s.ok()) {
      client_.reset();
      return Status(StatusCode::kUnavailable, s.message());
    }
    last_data_ns_ = now_ns();
    sequence_offset_ = next_sequence_;
    return {};
  }

  Status on_deactivate() override {
    if (client_) {
      (void)client_->stop();  // best effort: the sensor may be gone
      absorb_stats(/*final=*/true);
      client_.reset();
    }
    return {};
  }

  Status on_reset() override {
    client_.reset();  // reopened by activate()
    return {};
  }

  Result<std::size_t> on_read(std::vector<WrenchSample>& out, Duration timeout) override {
    std::vector<FtSample> got;
    auto n = client_->receive(got, timeout);
    const std::size_t appended = convert(got, out);
    absorb_stats();
    if (!n.ok() && n.status().code() != StatusCode::kUnavailable) {
      if (appended > 0) return appended;  // deliver what arrived; the error shows next time
      return n.status().with_context("force-torque '" + name() + "'");
    }
    if (appended > 0) {
      last_data_ns_ = now_ns();
      return appended;
    }
    const double silent_s = static_cast<double>(now_ns() - last_data_ns_) * 1e-9;
    if (silent_s < stall_timeout_s_) return std::size_t{0};
    // A stalled stream: resend start, as the ROS driver does for lost start packets.
    ++restarts_;
    Status s = restart();
    if (s.ok()) {
      last_data_ns_ = now_ns();
      return convert_pending(out);
    }
    return Status(StatusCode::kUnavailable,
                  "force-torque '" + name() + "': no RDT record for " + std::to_string(silent_s) +
                      " s and no answer to a restart (" + s.message() + ")");
  }

  Status on_bias() override {
    if (bias_mode_ == "device") return client_->bias();
    bias_ = last_counts_;
    return {};
  }
  Status on_clear_bias() override {
    bias_.fill(0);
    return {};
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = "ATI Net F/T (RDT)";
    const rdt::Calibration& c = client_ ? client_->calibration() : options_.calibration;
    info.details = {
        {"address", options_.host + ":" + std::to_string(options_.port)},
        {"calibration", options_.calibration_source},
        {"counts_per_force", std::to_string(c.counts_per_force) + " per " + c.force_unit},
        {"counts_per_torque", std::to_string(c.counts_per_torque) + " per " + c.torque_unit},
        {"bias", bias_mode_},
        {"restarts", std::to_string(restarts_)}};
    if (client_) {
      const NetFtStats st = client_->stats();
      info.details.emplace_back("datagrams", std::to_string(st.datagrams));
      info.details.emplace_back("reordered", std::to_string(st.late));
      info.details.emplace_back("malformed", std::to_string(st.malformed));
      info.details.emplace_back("status_errors", std::to_string(st.status_errors));
    }
  }

 private:
  std::int64_t now_ns() const { return clock().now_ns(); }

  Status restart() {
    // Up to 3 x 0.1 s, whatever the configured start handshake: the daemon is waiting.
    NetFtOptions o = options_;
    o.start_attempts = 3;
    o.start_timeout_s = 0.1;
    absorb_stats(/*final=*/true);
    sequence_offset_ = next_sequence_;
    lost_reported_ = 0;
    auto fresh = NetFtClient::open(o);
    if (!fresh.ok()) return fresh.status();
    client_ = std::move(*fresh);
    return client_->start();
  }

  // The records start() received are waiting in the client; fetch them without blocking.
  Result<std::size_t> convert_pending(std::vector<WrenchSample>& out) {
    std::vector<FtSample> got;
    HC_RETURN_IF_ERROR(client_->receive(got, Duration::zero()).status());
    return convert(got, out);
  }

  std::size_t convert(const std::vector<FtSample>& in, std::vector<WrenchSample>& out) {
    const devices::WrenchCalibration cal = calibration();
    for (const FtSample& f : in) {
      WrenchSample w;
      w.counts = f.record.counts;
      for (std::size_t i = 0; i < 3; ++i) {
        w.force_n[i] = (static_cast<double>(f.record.counts[i]) - bias_[i]) / cal.counts_per_n;
        w.torque_nm[i] =
            (static_cast<double>(f.record.counts[3 + i]) - bias_[3 + i]) / cal.counts_per_nm;
      }
      w.rdt_sequence = f.record.rdt_sequence;
      w.ft_sequence = f.record.ft_sequence;
      w.status = f.record.status;
      // rdt_sequence starts at 1 for each start request; sequence keeps counting across restarts.
      w.sequence = sequence_offset_ + (f.record.rdt_sequence - 1u);
      next_sequence_ = std::max(next_sequence_, w.sequence + 1);
      w.host_ns = clock().is_simulated() ? clock().now_ns() : f.host_ns;
      w.device_stamp_ns = static_cast<std::int64_t>(static_cast<double>(f.record.ft_sequence) *
                                                    1e9 / internal_rate_hz_);
      last_counts_ = f.record.counts;
      out.push_back(w);
    }
    return in.size();
  }

  // Reports the client's sequence gaps as lost: while streaming only those too old to be filled
  // by a reordered record (so the counter never has to go back), at the end of a stream all.
  void absorb_stats(bool final = false) {
    if (!client_) return;
    const NetFtStats st = client_->stats();
    const std::uint64_t lost = final ? st.lost : st.settled_lost;
    if (lost > lost_reported_) {
      count_lost(lost - lost_reported_);
      lost_reported_ = lost;
    }
  }

  NetFtOptions options_;
  std::unique_ptr<NetFtClient> client_;
  double rate_hz_ = rdt::kMaxRateHz;
  double internal_rate_hz_ = rdt::kMaxRateHz;
  std::string bias_mode_ = "host";
  double stall_timeout_s_ = 0.5;
  std::array<std::int32_t, 6> last_counts_{};
  std::array<std::int32_t, 6> bias_{};
  std::int64_t last_data_ns_ = 0;
  std::uint64_t sequence_offset_ = 0;
  std::uint64_t next_sequence_ = 0;
  std::uint64_t lost_reported_ = 0;
  std::uint64_t restarts_ = 0;
};

}  // namespace

Result<std::unique_ptr<devices::ForceTorque>> make_netft_force_torque(
    const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::ForceTorque>(new NetFtForceTorque(ctx));
}

}  // namespace hc::rig
