// Host driver for the trigger/FSR firmware: ONE API over two transports — USB bulk endpoints
// through libusb (real hardware) and the in-process simulator (firmware_host/simulator, running the
// same portable core). Consumers (rig_daemon trigger and FSR backends) cannot tell them apart
// except by info().transport.
//
// Typical use:
//   hc::fw::OpenOptions opts;                 // opts.device = "sim" (default) or
//   "usb[:VID:PID[:SERIAL]]" HC_ASSIGN_OR_RETURN(auto dev, hc::fw::FirmwareDevice::open(opts)); //
//   does the Hello handshake hc::fw::TriggerConfig cfg; cfg.period_us = 33'333; cfg.count = 90; //
//   30 Hz, 3 s HC_RETURN_IF_ERROR(dev->configure_trigger(cfg)); HC_RETURN_IF_ERROR(dev->start());
//   std::vector<hc::fw::Event> events;
//   while (...) { HC_ASSIGN_OR_RETURN(std::size_t n, dev->poll(events, 10ms)); ... }
//   HC_RETURN_IF_ERROR(dev->stop());
//
// Times: every event carries the firmware's own timestamp (µs since firmware boot), the host
// monotonic time (ns, CLOCK_MONOTONIC / std::chrono::steady_clock) at which the driver received it,
// and that firmware timestamp mapped onto the host monotonic clock (ns) by a minimum-delay offset
// estimate — use host_time_ns to associate edges with frames and samples from other devices.
// With the simulator in SimClock::kVirtual, the "host clock" is virtual too (host_epoch_ns +
// virtual µs), so tests are deterministic; see SimClock.
//
// Threading: a FirmwareDevice is not thread-safe; use it from one thread, or share one board
// between a trigger and an FSR consumer through SharedFirmwareDevice (shared_device.h).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/status.h"
#include "firmware_host/protocol/messages.h"
#include "firmware_host/simulator/simulator.h"

namespace hc::fw {

// USB identity of the firmware: pid.codes' open-source vendor ID 0x1209 with its test product ID
// 0x0001 (https://pid.codes/1209/0001/ — for development; a production board gets its own PID).
inline constexpr std::uint16_t kUsbVendorId = 0x1209;
inline constexpr std::uint16_t kUsbProductId = 0x0001;
inline constexpr std::uint8_t kUsbInterface = 0;
inline constexpr std::uint8_t kUsbEndpointOut = 0x01;  // bulk OUT (host -> device)
inline constexpr std::uint8_t kUsbEndpointIn = 0x81;   // bulk IN (device -> host)

// Host monotonic clock in ns (std::chrono::steady_clock).
std::int64_t host_monotonic_ns();

// How the simulator's time advances.
enum class SimClock {
  kRealTime,  // virtual time follows the host's steady clock (poll() sleeps like real hardware)
  kVirtual,   // virtual time advances only inside driver calls: poll(timeout) runs the simulator
              // for `timeout` of virtual time at once (no sleeping) — deterministic and fast
};

struct OpenOptions {
  // "sim"                          in-process simulator (options in `sim`)
  // "usb"                          first device with kUsbVendorId:kUsbProductId
  // "usb:VVVV:PPPP"                first device with that hex vendor:product ID
  // "usb:VVVV:PPPP:SERIAL"         the device whose serial-number string is SERIAL
  std::string device = "sim";
  std::chrono::milliseconds command_timeout{500};  // wait for Ack/HelloReply
  SimulatorOptions sim;                            // used when device == "sim"
  SimClock sim_clock = SimClock::kVirtual;
  Status validate() const;
};

// Pulse train parameters (mirror of the wire message, with validation on the host side).
struct TriggerConfig {
  std::uint32_t period_us = 33'333;       // rising edge to rising edge
  std::uint32_t pulse_width_us = 1'000;   // high time, < period_us
  std::uint8_t lines_mask = 0x01;         // which trigger outputs pulse (bit i = line i)
  std::uint8_t adc_channels_mask = 0x01;  // which ADC channels are sampled at each rising edge
  std::uint32_t count = 0;                // pulses; 0 = continuous until stop()
  std::uint16_t heartbeat_period_ms = 100;
  // Checks the ranges the firmware accepts (period >= kMinPeriodUs, 0 < width < period, masks
  // within the device's lines/channels when `info` is given).
  Status validate(const HelloReply* info = nullptr) const;
};

// Limits the firmware enforces (also checked host-side).
inline constexpr std::uint32_t kMinPeriodUs = 100;  // 10 kHz
inline constexpr std::uint16_t kMinHeartbeatPeriodMs = 10;

struct DeviceInfo {
  HelloReply hello;       // protocol/firmware versions, line/channel counts, ADC bits, ring size
  std::string transport;  // "sim" or "usb 1209:0001 serial=... bus=1 address=4"
};

// A rising trigger edge (all lines in lines_mask went high together).
struct TriggerEdgeEvent {
  std::uint32_t edge_index = 0;  // 0-based within the train started by start()
  std::uint64_t device_time_us = 0;
  std::uint8_t lines_mask = 0;
  std::uint16_t lateness_us = 0;  // firmware-measured delay after the scheduled time
  std::int64_t host_rx_ns = 0;    // host monotonic time the driver received it
  std::int64_t host_time_ns = 0;  // device_time_us mapped to the host monotonic clock
};

// An ADC reading taken at a trigger edge (edge_index associates it with the TriggerEdgeEvent).
struct AdcSampleEvent {
  std::uint32_t edge_index = 0;
  std::uint8_t channel = 0;
  std::uint16_t raw = 0;  // 0 .. 2^adc_bits - 1
  std::uint64_t device_time_us = 0;
  std::int64_t host_rx_ns = 0;
  std::int64_t host_time_ns = 0;
};

struct HeartbeatStatus {
  Heartbeat heartbeat;  // uptime, ring fill/capacity, dropped events, edges, state
  std::int64_t host_rx_ns = 0;
};

struct DeviceErrorEvent {
  ErrorReport report;  // code, detail, device timestamp
  std::int64_t host_rx_ns = 0;
  std::string message() const;  // e.g. "overrun: 12 events dropped"
};

struct Event {
  enum class Kind { kTriggerEdge, kAdcSample, kHeartbeat, kError };
  Kind kind = Kind::kTriggerEdge;
  TriggerEdgeEvent edge;      // kind == kTriggerEdge
  AdcSampleEvent sample;      // kind == kAdcSample
  HeartbeatStatus heartbeat;  // kind == kHeartbeat
  DeviceErrorEvent error;     // kind == kError
};

// Link health as seen by the driver.
struct LinkStats {
  std::uint64_t bytes_in = 0;
  std::uint64_t bytes_out = 0;
  std::uint64_t frames_in = 0;  // decoded device frames
  std::uint64_t frames_out = 0;
  std::uint64_t frames_corrupt = 0;   // dropped by the stream decoder (CRC, COBS, length, ...)
  std::uint64_t bytes_discarded = 0;  // garbage skipped while resynchronising
  std::uint64_t frames_lost = 0;      // gaps in the device's sequence numbers
  std::uint64_t device_errors = 0;    // ErrorReport messages received
};

// Byte pipe under the driver. Implementations: libusb bulk endpoints, the in-process simulator.
class Transport {
 public:
  virtual ~Transport() = default;
  virtual Status write(const std::uint8_t* data, std::size_t size) = 0;
  // Reads up to `cap` bytes, waiting at most `timeout`; 0 bytes on timeout is not an error.
  virtual Result<std::size_t> read(std::uint8_t* out, std::size_t cap,
                                   std::chrono::microseconds timeout) = 0;
  // The transport's notion of host monotonic time in ns (virtual for the virtual-clock simulator).
  virtual std::int64_t now_ns() const = 0;
  virtual std::string describe() const = 0;
};

// A parsed "usb[:VVVV:PPPP[:SERIAL]]" device spec.
struct UsbDeviceSpec {
  std::uint16_t vendor_id = kUsbVendorId;
  std::uint16_t product_id = kUsbProductId;
  std::string serial;  // empty = any
};
// InvalidArgument naming the problem when `spec` is not of that form.
Result<UsbDeviceSpec> parse_usb_spec(const std::string& spec);

// Opens a libusb bulk transport. NotFound when no matching device is attached; Unavailable when
// libusb cannot initialise or the device cannot be claimed. `spec` as OpenOptions::device.
Result<std::unique_ptr<Transport>> open_usb_transport(const std::string& spec);

class FirmwareDevice {
 public:
  // Opens the transport named by options.device and performs the Hello handshake. Errors:
  // InvalidArgument (bad spec), NotFound (no such USB device), Unavailable (libusb/claim failure),
  // DeadlineExceeded (no HelloReply), FailedPrecondition (protocol version mismatch).
  static Result<std::unique_ptr<FirmwareDevice>> open(const OpenOptions& options);
  // For tests and custom links: runs the handshake over an already-open transport.
  static Result<std::unique_ptr<FirmwareDevice>> open(std::unique_ptr<Transport> transport,
                                                      const OpenOptions& options);
  ~FirmwareDevice();
  FirmwareDevice(const FirmwareDevice&) = delete;
  FirmwareDevice& operator=(const FirmwareDevice&) = delete;

  const DeviceInfo& info() const { return info_; }

  // Sends ConfigureTrigger and waits for the Ack. InvalidArgument when the config is invalid
  // (checked locally, or the device's Nack), FailedPrecondition when the device is running,
  // DeadlineExceeded without an answer. Events that arrive meanwhile are kept for poll().
  Status configure_trigger(const TriggerConfig& config);
  // Starts the configured train (first edge start_delay_us after the device handles Start).
  Status start(std::uint32_t start_delay_us = 0);
  // Stops the train (lines go low). Idempotent.
  Status stop();

  // Appends received events to `out` in arrival order (edges, samples, heartbeats, errors), waiting
  // up to `timeout` for at least one. Returns how many were appended (0 on timeout). An error
  // Status means the link failed (device unplugged); the device must then be reopened.
  Result<std::size_t> poll(std::vector<Event>& out, std::chrono::microseconds timeout);

  std::optional<HeartbeatStatus> last_heartbeat() const { return last_heartbeat_; }
  LinkStats link_stats() const;
  // The simulator behind a "sim" device (fault injection, recorded GPIO edges); nullptr for USB.
  Simulator* simulator() { return simulator_; }

  // The transport's host clock (ns): steady_clock, or the virtual clock of a kVirtual simulator.
  std::int64_t now_ns() const { return transport_ ? transport_->now_ns() : host_monotonic_ns(); }

  // Converts a firmware timestamp to host monotonic ns with the current offset estimate.
  std::int64_t device_to_host_ns(std::uint64_t device_time_us) const;

  // Sends Stop (best effort) and releases the transport. Called by the destructor.
  void close();

 private:
  FirmwareDevice() = default;
  Status handshake();
  Status send(Message msg);
  Status command(Message msg, std::chrono::microseconds timeout);
  Status read_some(std::chrono::microseconds timeout);
  void handle(const Message& msg, std::int64_t rx_ns);
  void update_offset(std::uint64_t device_time_us, std::int64_t rx_ns);

  std::unique_ptr<Transport> transport_;
  Simulator* simulator_ = nullptr;
  OpenOptions options_;
  DeviceInfo info_;
  StreamDecoder decoder_;
  std::vector<Event> pending_;
  std::optional<HeartbeatStatus> last_heartbeat_;
  LinkStats stats_;
  std::uint16_t next_seq_ = 1;
  std::optional<std::uint16_t> last_device_seq_;
  // Answer to the command in flight.
  std::optional<Message> reply_;
  std::uint16_t awaiting_seq_ = 0;
  MessageType awaiting_type_ = MessageType::kHello;
  bool awaiting_ = false;
  // Min-delay clock offset (host_ns - device_us * 1000) over two rolling windows of
  // kOffsetWindowNs.
  std::int64_t offset_ns_ = 0;
  bool have_offset_ = false;
  std::int64_t window_start_ns_ = 0;
  std::int64_t window_min_ = 0;
  std::int64_t prev_window_min_ = 0;
  bool have_prev_window_ = false;
  bool open_ = false;
};

}  // namespace hc::fw
