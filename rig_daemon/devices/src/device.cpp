#include "rig_daemon/devices/device.h"

#include <string>

#include "rig_daemon/devices/arm.h"
#include "rig_daemon/devices/camera.h"
#include "rig_daemon/devices/force_torque.h"
#include "rig_daemon/devices/fsr.h"
#include "rig_daemon/devices/trigger.h"

namespace hc::devices {

std::string_view to_string(DeviceKind kind) {
  switch (kind) {
    case DeviceKind::kCamera:
      return "camera";
    case DeviceKind::kTrigger:
      return "trigger";
    case DeviceKind::kFsr:
      return "fsr";
    case DeviceKind::kForceTorque:
      return "force_torque";
    case DeviceKind::kArm:
      return "arm";
  }
  return "unknown";
}

std::optional<DeviceKind> device_kind_from_string(std::string_view name) {
  for (DeviceKind kind : kAllDeviceKinds)
    if (to_string(kind) == name) return kind;
  return std::nullopt;
}

std::string_view to_string(DeviceState state) {
  switch (state) {
    case DeviceState::kUnconfigured:
      return "unconfigured";
    case DeviceState::kInactive:
      return "inactive";
    case DeviceState::kActive:
      return "active";
    case DeviceState::kError:
      return "error";
  }
  return "unknown";
}

Device::Device(DeviceContext context) : context_(std::move(context)) {
  if (!context_.clock) context_.clock = monotonic_clock();
}

Device::~Device() = default;

Status Device::error() const {
  std::lock_guard lock(error_mutex_);
  return state_.load() == DeviceState::kError ? error_ : Status{};
}

DeviceStats Device::stats() const {
  DeviceStats s;
  s.received = received_.load();
  s.lost = lost_.load();
  s.late = late_.load();
  s.incomplete = incomplete_.load();
  s.errors = errors_.load();
  s.last_host_ns = last_host_ns_.load();
  return s;
}

DeviceInfo Device::info() const {
  DeviceInfo out;
  out.name = name();
  out.kind = kind();
  out.backend = backend();
  out.state = state();
  describe(out);
  return out;
}

namespace {
// Failures of the device or its link (as opposed to a refused request): these enter kError.
bool is_device_failure(const Status& s) {
  switch (s.code()) {
    case StatusCode::kIoError:
    case StatusCode::kUnavailable:
    case StatusCode::kDeadlineExceeded:
    case StatusCode::kInternal:
      return true;
    default:
      return false;
  }
}

Status wrong_state(const Device& d, std::string_view operation) {
  return failed_precondition(std::string(to_string(d.kind())) + " '" + d.name() + "': cannot " +
                             std::string(operation) + " in state " +
                             std::string(to_string(d.state())));
}
}  // namespace

Status Device::configure(ConfigNode node) {
  const DeviceState s = state_.load();
  if (s == DeviceState::kError) return error();
  if (s == DeviceState::kActive) return wrong_state(*this, "configure");
  Status status = on_configure(node);
  if (status.ok()) status = node.status();
  if (!status.ok()) {
    configured_ = false;
    state_ = DeviceState::kUnconfigured;
    return status;
  }
  configured_ = true;
  state_ = DeviceState::kInactive;
  return {};
}

Status Device::activate() {
  const DeviceState s = state_.load();
  if (s == DeviceState::kError) return error();
  if (s != DeviceState::kInactive) return wrong_state(*this, "activate");
  Status status = on_activate();
  if (!status.ok()) {
    if (state_.load() == DeviceState::kError) return error();  // the backend already failed
    return fail(
        status.with_context(std::string(to_string(kind())) + " '" + name() + "': activate"));
  }
  state_ = DeviceState::kActive;
  return {};
}

Status Device::deactivate() {
  const DeviceState s = state_.load();
  if (s == DeviceState::kError) {
    (void)on_deactivate();  // release what we can; the error stays
    return {};
  }
  if (s != DeviceState::kActive) return wrong_state(*this, "deactivate");
  Status status = on_deactivate();
  if (!status.ok()) return fail(status);
  state_ = DeviceState::kInactive;
  return {};
}

Status Device::reset() {
  const DeviceState s = state_.load();
  if (s != DeviceState::kError) return {};
  HC_RETURN_IF_ERROR(on_reset());
  {
    std::lock_guard lock(error_mutex_);
    error_ = Status{};
  }
  state_ = configured_ ? DeviceState::kInactive : DeviceState::kUnconfigured;
  return {};
}

Status Device::cleanup() {
  const DeviceState s = state_.load();
  if (s == DeviceState::kUnconfigured) return {};
  if (s != DeviceState::kInactive) return wrong_state(*this, "cleanup");
  HC_RETURN_IF_ERROR(on_cleanup());
  configured_ = false;
  state_ = DeviceState::kUnconfigured;
  return {};
}

Status Device::fail(Status status) {
  if (status.ok()) status = internal_error("device failed with an OK status");
  {
    std::lock_guard lock(error_mutex_);
    if (state_.load() == DeviceState::kError) return error_;  // keep the first cause
    error_ = status;
    state_ = DeviceState::kError;
  }
  errors_.fetch_add(1);
  return status;
}

Status Device::check_active(std::string_view operation) const {
  const DeviceState s = state_.load();
  if (s == DeviceState::kActive) return {};
  if (s == DeviceState::kError) return error();
  return wrong_state(*this, operation);
}

Status Device::check_configured(std::string_view operation) const {
  const DeviceState s = state_.load();
  if (s == DeviceState::kActive || s == DeviceState::kInactive) return {};
  if (s == DeviceState::kError) return error();
  return wrong_state(*this, operation);
}

void Device::count_received(std::uint64_t n, std::int64_t last_host_ns) {
  if (n == 0) return;
  received_.fetch_add(n);
  last_host_ns_.store(last_host_ns);
}

Status configure_from_yaml(Device& device, std::string_view yaml, std::string_view name) {
  HC_ASSIGN_OR_RETURN(Config config, parse_config(yaml, name));
  Status configured;
  Status read = read_config(config, [&](ConfigNode root) {
    std::string ignored;
    root.optional("kind", ignored);
    root.optional("backend", ignored);
    configured = device.configure(root);
    return Status{};
  });
  if (!configured.ok()) return configured;
  if (!read.ok()) {
    // Unknown keys are found after configure() ran: undo it so the device is not half-configured.
    if (device.state() == DeviceState::kInactive) (void)device.cleanup();
    return read;
  }
  return {};
}

// ---- Kind interfaces: state checks and counting around the backend hooks ----

namespace {
template <typename T>
std::int64_t last_ns(const std::vector<T>& out) {
  return out.empty() ? -1 : out.back().host_ns;
}
}  // namespace

Result<std::size_t> Camera::read(std::vector<Frame>& out, Duration timeout) {
  HC_RETURN_IF_ERROR(check_active("read"));
  Result<std::size_t> n = on_read(out, timeout);
  if (!n.ok()) return fail(n.status());
  count_received(*n, last_ns(out));
  return n;
}

Status Camera::software_trigger() {
  HC_RETURN_IF_ERROR(check_active("software_trigger"));
  Status s = on_software_trigger();
  return is_device_failure(s) ? fail(s) : s;
}

Status Camera::on_software_trigger() {
  return unsupported("camera '" + name() + "' (backend " + backend() + ") has no software trigger");
}

std::string_view to_string(TriggerMode mode) {
  switch (mode) {
    case TriggerMode::kFreeRun:
      return "free_run";
    case TriggerMode::kSoftware:
      return "software";
    case TriggerMode::kHardware:
      return "hardware";
  }
  return "unknown";
}

std::optional<TriggerMode> trigger_mode_from_string(std::string_view name) {
  for (TriggerMode m : {TriggerMode::kFreeRun, TriggerMode::kSoftware, TriggerMode::kHardware})
    if (to_string(m) == name) return m;
  return std::nullopt;
}

Status validate(const PulseTrain& train) {
  if (!(train.rate_hz > 0.0) || !(train.rate_hz <= 1e6))
    return invalid_argument("pulse train: rate_hz must be in (0, 1e6], got " +
                            std::to_string(train.rate_hz));
  if (!(train.pulse_width_s > 0.0) || !(train.pulse_width_s < 1.0 / train.rate_hz))
    return invalid_argument("pulse train: pulse_width_s must be in (0, 1/rate_hz) = (0, " +
                            std::to_string(1.0 / train.rate_hz) + "), got " +
                            std::to_string(train.pulse_width_s));
  return {};
}

Status Trigger::start(const PulseTrain& train) {
  HC_RETURN_IF_ERROR(check_active("start"));
  HC_RETURN_IF_ERROR(validate(train));
  if (running()) return failed_precondition("trigger '" + name() + "': a pulse train is running");
  Status s = on_start(train);
  return is_device_failure(s) ? fail(s) : s;
}

Status Trigger::stop() {
  HC_RETURN_IF_ERROR(check_active("stop"));
  Status s = on_stop();
  return is_device_failure(s) ? fail(s) : s;
}

Status Trigger::fire() {
  HC_RETURN_IF_ERROR(check_active("fire"));
  if (running()) return failed_precondition("trigger '" + name() + "': a pulse train is running");
  Status s = on_fire();
  return is_device_failure(s) ? fail(s) : s;
}

Result<std::size_t> Trigger::read(std::vector<TriggerEdge>& out, Duration timeout) {
  HC_RETURN_IF_ERROR(check_active("read"));
  Result<std::size_t> n = on_read(out, timeout);
  if (!n.ok()) return fail(n.status());
  count_received(*n, last_ns(out));
  return n;
}

void Fsr::read_calibration(ConfigNode& node, FsrCalibration* calibration) {
  if (std::optional<ConfigNode> c = node.find("calibration")) {
    c->optional("full_scale", calibration->full_scale, Bounds::positive());
    c->optional("threshold", calibration->threshold, Bounds{0.0, 1.0, false, true});
    c->optional("scale_n", calibration->scale_n, Bounds::positive());
    c->optional("exponent", calibration->exponent, Bounds::positive());
  }
}

Result<std::size_t> Fsr::read(std::vector<FsrSample>& out, Duration timeout) {
  HC_RETURN_IF_ERROR(check_active("read"));
  Result<std::size_t> n = on_read(out, timeout);
  if (!n.ok()) return fail(n.status());
  count_received(*n, last_ns(out));
  return n;
}

Result<std::size_t> ForceTorque::read(std::vector<WrenchSample>& out, Duration timeout) {
  HC_RETURN_IF_ERROR(check_active("read"));
  Result<std::size_t> n = on_read(out, timeout);
  if (!n.ok()) return fail(n.status());
  count_received(*n, last_ns(out));
  return n;
}

Status ForceTorque::bias() {
  HC_RETURN_IF_ERROR(check_active("bias"));
  Status s = on_bias();
  return is_device_failure(s) ? fail(s) : s;
}

Status ForceTorque::clear_bias() {
  HC_RETURN_IF_ERROR(check_configured("clear_bias"));
  return on_clear_bias();
}

Status Arm::write(const ArmCommand& command) {
  HC_RETURN_IF_ERROR(check_active("write"));
  if (command.type == ArmCommand::Type::kStop) return stop();
  if (command.type == ArmCommand::Type::kMoveTo && !limits().contains(command.target))
    return invalid_argument("arm '" + name() + "': target outside the workspace");
  Status s = on_write(command);
  return is_device_failure(s) ? fail(s) : s;
}

Result<ArmState> Arm::read() {
  HC_RETURN_IF_ERROR(check_active("read"));
  Result<ArmState> state = on_read();
  if (!state.ok()) return fail(state.status());
  count_received(1, state->host_ns);
  return state;
}

Status Arm::stop() {
  // Works in kError too: stopping must always be possible when the backend can talk to the arm.
  const DeviceState s = state();
  if (s == DeviceState::kUnconfigured)
    return failed_precondition("arm '" + name() + "': cannot stop before configure");
  return on_stop();
}

}  // namespace hc::devices
