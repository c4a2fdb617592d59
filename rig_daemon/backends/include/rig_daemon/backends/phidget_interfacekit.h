// Phidget InterfaceKit 8/8/8 (model 1018; USB 0x06C2:0x0045): the HID input report of firmware
// 900-999, as parsed by libphidget21's cphidgetinterfacekit.c (LGPL-3; layout summarised in
// ../shared/data/protocols/RIG_PROTOCOL_FACTS.md), and a libusb reader for it.
//
// Report layout:
//   byte 0     bits 7-6 packet counter (mod 4; a jump means lost reports), bit 5 over-current,
//              bit 4 ratiometric echo, bits 3-0 overrun flags (bit k: one overrun byte follows
//              for sensors 2k and 2k+1)
//   byte 1     digital inputs, inverted (bit i clear = input i on)
//   byte 2     digital output echo
//   then       one byte per set overrun flag: high nibble sensor 2k, low nibble 2k+1 (samples the
//              board dropped)
//   then       4 count bytes: high nibble sensor 2m, low nibble 2m+1 (samples in this report)
//   then       12-bit samples, interleaved by sample index j over sensors with count > j, packed
//              1.5 bytes each: even ones b[x] | (b[x+1] & 0xF0) << 4 (x += 2), odd ones
//              b[x] | (b[x-1] & 0x0F) << 8 (x += 1).
//   Sensor value (0..1000) = round(raw x 1.001 / 4.095), clamped to 1000.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "common/status.h"

namespace hc::rig::phidget {

inline constexpr std::uint16_t kVendorId = 0x06C2;
inline constexpr std::uint16_t kInterfaceKit888ProductId = 0x0045;
inline constexpr int kSensors = 8;
inline constexpr int kMaxSamplesPerReport = 16;  // IFKIT_MAX_DATA_PER_PACKET
inline constexpr double kReportPeriodS = 0.008;  // one report every 8 ms

struct InterfaceKitReport {
  std::uint8_t packet_counter = 0;  // 0..3
  bool overcurrent = false;
  bool ratiometric = false;
  std::array<bool, 8> inputs{};  // true = on (the wire bit is inverted)
  std::array<bool, 8> outputs{};
  std::array<std::uint8_t, kSensors> overruns{};           // samples dropped on the board
  std::array<std::vector<std::uint16_t>, kSensors> raw{};  // 12-bit samples, oldest first
};

// Decodes one input report. kInvalidArgument (nothing returned) when the report is shorter than
// its header, counts and samples say, or a sensor claims more than 16 samples.
Result<InterfaceKitReport> decode_report(std::span<const std::uint8_t> bytes);
// The inverse, for tests and simulators: fails when a sensor has more than 15 samples (a nibble)
// or a sample exceeds 12 bits. Overrun bytes are written for pairs with a non-zero count.
Result<std::vector<std::uint8_t>> encode_report(const InterfaceKitReport& report);
// round(raw x 1.001 / 4.095) clamped to 0..1000 (raw above 4095 is clamped to 4095 first).
std::uint32_t sensor_value(std::uint32_t raw12);

// Counts reports lost from the 2-bit packet counter (a jump of k means k - 1 lost; a report
// never seen again after 4 lost is invisible, so this is a lower bound).
class PacketCounter {
 public:
  // Returns the number of reports lost before this one.
  std::uint32_t update(std::uint8_t counter);
  void reset() { have_ = false; }

 private:
  bool have_ = false;
  std::uint8_t last_ = 0;
};

// The board over libusb: opens the first InterfaceKit 8/8/8 (or the one with `serial`), detaches
// the kernel's usbhid driver, claims interface 0 and reads input reports from its interrupt IN
// endpoint.
class InterfaceKitUsb {
 public:
  // kNotFound when no such board is connected, kUnavailable when it cannot be opened/claimed
  // (permissions: a udev rule for 06c2:0045 is needed).
  static Result<std::unique_ptr<InterfaceKitUsb>> open(const std::string& serial = {});
  ~InterfaceKitUsb();
  InterfaceKitUsb(const InterfaceKitUsb&) = delete;
  InterfaceKitUsb& operator=(const InterfaceKitUsb&) = delete;

  // Reads one report (up to `timeout_ms`); an empty vector on timeout.
  Result<std::vector<std::uint8_t>> read_report(int timeout_ms);
  const std::string& serial() const { return serial_; }

 private:
  InterfaceKitUsb() = default;
  void* context_ = nullptr;  // libusb_context*
  void* handle_ = nullptr;   // libusb_device_handle*
  std::uint8_t endpoint_ = 0x81;
  int report_bytes_ = 64;
  bool reattach_ = false;
  std::string serial_;
};

}  // namespace hc::rig::phidget
