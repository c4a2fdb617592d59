// Backend "phidget": an FSR on one analog input of a Phidget InterfaceKit 8/8/8 over libusb, as a
// devices::Fsr (the thesis's hand-held board).
//
// Config keys:
//   serial       board serial number (default: the first board found)
//   sensor       analog input 0..7 the FSR is wired to (default 0)
//   calibration  {full_scale, threshold, scale_n, exposure}: FsrCalibration on the 0..1000 sensor
//                value (full_scale defaults to 1000)
//   rate_hz      the board's sample rate for that input (default 125: one sample per 8 ms report)
// Reports lost on USB (2-bit packet counter) and samples the board dropped (overrun nibbles) are
// counted lost; sequence numbers skip them.
#include <algorithm>
#include <chrono>

#include "backend_factories.h"
#include "rig_daemon/backends/phidget_interfacekit.h"

namespace hc::rig {
namespace {

class PhidgetFsr final : public devices::Fsr {
 public:
  explicit PhidgetFsr(const devices::DeviceContext& ctx) : Fsr(ctx) {
    calibration_.full_scale = 1000.0;
  }

  devices::FsrCalibration calibration() const override { return calibration_; }
  double sample_rate_hz() const override { return rate_hz_; }

 protected:
  Status on_configure(ConfigNode node) override {
    node.optional("serial", serial_);
    node.optional("sensor", sensor_, Bounds::between(0, phidget::kSensors - 1));
    node.optional("rate_hz", rate_hz_, Bounds{0.0, 1000.0, true, false});
    read_calibration(node, &calibration_);
    return node.status();
  }

  Status on_activate() override {
    HC_ASSIGN_OR_RETURN(usb_, phidget::InterfaceKitUsb::open(serial_));
    counter_.reset();
    return {};
  }
  Status on_deactivate() override {
    usb_.reset();
    return {};
  }
  Status on_reset() override {
    usb_.reset();
    return {};
  }

  Result<std::size_t> on_read(std::vector<devices::FsrSample>& out,
                              devices::Duration timeout) override {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count();
    std::size_t appended = 0;
    int wait_ms = static_cast<int>(std::clamp<std::int64_t>(ms, 1, 60'000));
    while (true) {
      auto report = usb_->read_report(wait_ms);
      if (!report.ok()) {
        if (appended > 0) return appended;
        return report.status().with_context("FSR '" + name() + "'");
      }
      if (report->empty()) return appended;  // timed out
      const std::int64_t now = clock().now_ns();
      auto decoded = phidget::decode_report(*report);
      if (!decoded.ok()) {
        count_lost(1);  // a report we cannot read: its samples are gone
        wait_ms = 1;
        continue;
      }
      const auto& raw = decoded->raw[static_cast<std::size_t>(sensor_)];
      const std::uint32_t lost_reports = counter_.update(decoded->packet_counter);
      // A lost report carried about as many samples as this one.
      const std::uint64_t lost =
          lost_reports * raw.size() + decoded->overruns[static_cast<std::size_t>(sensor_)];
      if (lost > 0) {
        count_lost(lost);
        sequence_ += lost;
      }
      // Samples in a report are evenly spaced over the 8 ms before it arrived.
      const double dt_ns = raw.empty() ? 0.0 : phidget::kReportPeriodS * 1e9 / raw.size();
      for (std::size_t k = 0; k < raw.size(); ++k) {
        devices::FsrSample s;
        s.raw = phidget::sensor_value(raw[k]);
        s.force_n = calibration_.to_newtons(s.raw);
        s.channel = static_cast<std::uint32_t>(sensor_);
        s.sequence = sequence_++;
        s.host_ns =
            now - static_cast<std::int64_t>(dt_ns * static_cast<double>(raw.size() - 1 - k));
        out.push_back(s);
        ++appended;
      }
      wait_ms = 1;  // drain what is queued, then return
    }
  }

  void describe(devices::DeviceInfo& info) const override {
    info.model = "Phidget InterfaceKit 8/8/8 (1018)";
    info.serial = usb_ ? usb_->serial() : serial_;
    info.details = {{"sensor", std::to_string(sensor_)}};
  }

 private:
  std::string serial_;
  int sensor_ = 0;
  double rate_hz_ = 125.0;
  devices::FsrCalibration calibration_;
  std::unique_ptr<phidget::InterfaceKitUsb> usb_;
  phidget::PacketCounter counter_;
  std::uint64_t sequence_ = 0;
};

}  // namespace

Result<std::unique_ptr<devices::Fsr>> make_phidget_fsr(const devices::DeviceContext& ctx) {
  return std::unique_ptr<devices::Fsr>(new PhidgetFsr(ctx));
}

}  // namespace hc::rig
