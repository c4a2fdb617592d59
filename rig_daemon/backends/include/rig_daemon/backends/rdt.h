// ATI Net F/T "Raw Data Transfer" (RDT) protocol: the UDP wire format (request and response
// records), the sensor's calibration (counts per force / torque unit) and the conversion of counts
// to SI. Layouts are those of ../shared/data/protocols/RDT_PROTOCOL_NOTES.md (ATI manual 9620-05
// pp. 73-76, cross-checked against ros-drivers/ati_netft_ros_driver netft_rdt_driver.cpp).
// Everything on the wire is big-endian.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace hc::rig::rdt {

inline constexpr std::uint16_t kDefaultPort = 49152;  // RDT_PORT (UDP)
inline constexpr std::uint16_t kCommandHeader = 0x1234;
inline constexpr std::size_t kRequestBytes = 8;  // u16 header, u16 command, u32 count
inline constexpr std::size_t kRecordBytes = 36;  // 3 x u32 + 6 x i32
inline constexpr double kMaxRateHz = 7000.0;     // Net F/T maximum RDT output rate
// A UDP datagram carries at most this many records (buffered mode); bounds decode work.
inline constexpr std::size_t kMaxRecordsPerPacket = 1800;  // 1800 x 36 B < 65507 B (UDP max)

enum class Command : std::uint16_t {
  kStop = 0x0000,
  kStartRealtime = 0x0002,   // one record per packet
  kStartBuffered = 0x0003,   // several records per packet
  kStartMultiUnit = 0x0004,  // not implemented by our client; decoded for completeness
  kResetThresholdLatch = 0x0041,
  kSetSoftwareBias = 0x0042,
};

// True for the six command codes of the manual.
bool is_known_command(std::uint16_t code);
std::string_view command_name(std::uint16_t code);

struct Request {
  std::uint16_t command = 0;
  std::uint32_t sample_count = 0;  // 0 = stream until stopped
  bool operator==(const Request&) const = default;
};

std::array<std::uint8_t, kRequestBytes> encode_request(const Request& request);

// Decodes a request as a strict device would. Fails (kInvalidArgument) when the size is not 8
// bytes, the header is not 0x1234, or the command is unknown. The "extended" form (command with bit
// 15 set, destination appended) is rejected as kUnsupported.
Result<Request> decode_request(std::span<const std::uint8_t> bytes);

struct Record {
  std::uint32_t rdt_sequence = 0;        // per packet, starts at 1 for each request
  std::uint32_t ft_sequence = 0;         // internal sample counter (7000/s since power-up)
  std::uint32_t status = 0;              // 0 = OK, otherwise a latched error code
  std::array<std::int32_t, 6> counts{};  // Fx Fy Fz Tx Ty Tz
  bool operator==(const Record&) const = default;
};

// Writes kRecordBytes bytes at `out`.
void encode_record(const Record& record, std::span<std::uint8_t, kRecordBytes> out);
std::vector<std::uint8_t> encode_records(std::span<const Record> records);

// Decodes one datagram: one record (real-time) or several (buffered). Fails (kInvalidArgument) on
// an empty datagram, a size that is not a multiple of 36 bytes, or more than kMaxRecordsPerPacket.
// Nothing is returned on failure.
Result<std::vector<Record>> decode_records(std::span<const std::uint8_t> bytes);

// Calibration: how many counts make one force unit and one torque unit, and what the units are.
struct Calibration {
  double counts_per_force = 1e6;   // counts per `force_unit`
  double counts_per_torque = 1e6;  // counts per `torque_unit`
  std::string force_unit = "N";    // N, kN, lbf
  std::string torque_unit = "Nm";  // Nm, Nmm, kNm, lbfin, lbfft
  bool operator==(const Calibration&) const = default;
};

// Newtons per `unit`: "N" 1, "kN" 1e3, "lbf" 4.4482216152605 (exact, from the avoirdupois pound
// 0.45359237 kg x standard gravity 9.80665 m/s^2). kInvalidArgument for anything else.
Result<double> newtons_per_force_unit(std::string_view unit);
// Newton-metres per `unit`: "Nm"/"N-m" 1, "Nmm"/"N-mm" 1e-3, "kNm" 1e3, "lbfin" 0.112984829027617
// (lbf x 0.0254 m), "lbfft" 1.3558179483314 (lbf x 0.3048 m). kInvalidArgument otherwise.
Result<double> newton_metres_per_torque_unit(std::string_view unit);

// Checks counts > 0 (finite) and known units.
Status validate(const Calibration& calibration);

// Parses the calibration from the sensor's HTTP document netftapi2.xml (elements cfgcpf, cfgcpt,
// scfgfu, scfgtu). Fails naming the missing or malformed element.
Result<Calibration> parse_calibration_xml(std::string_view xml);
// The matching fragment (what our simulator serves).
std::string calibration_xml(const Calibration& calibration);

// One wrench in SI: force N, torque N m, in the sensor frame.
struct Wrench {
  std::array<double, 3> force_n{};
  std::array<double, 3> torque_nm{};
};

// counts / counts_per_unit x unit-to-SI. Precondition: validate(calibration).ok().
Wrench to_si(const std::array<std::int32_t, 6>& counts, const Calibration& calibration);
// Inverse (rounded to the nearest count, saturated to int32): what a sensor would send.
std::array<std::int32_t, 6> to_counts(const Wrench& wrench, const Calibration& calibration);

// Tracks rdt_sequence over a stream. Like the ROS driver, diff = int32(seq - last) with wrap-around
// at 2^32 and diff - 1 packets counted lost; unlike it, a late packet that fills a gap among the
// last 64 sequences is kept (kLate) and taken off lost(), so reordering loses nothing. A repeat of
// a sequence already seen is kDuplicate; one older than the window is kStale (both dropped).
class SequenceTracker {
 public:
  enum class Verdict { kFirst, kInOrder, kLate, kDuplicate, kStale };
  static constexpr std::uint32_t kWindow = 64;

  Verdict update(std::uint32_t sequence);
  // Forgets the last sequence (a new request restarts rdt_sequence at 1); counters are kept.
  void reset() { have_last_ = false; }
  // Gaps not filled so far (may still shrink when late packets arrive).
  std::uint64_t lost() const { return lost_; }
  // Gaps older than the window: they can no longer be filled, so this only grows (what a device
  // reports as lost while streaming; lost() - settled_lost() is settled when the stream ends).
  std::uint64_t settled_lost() const { return settled_lost_; }
  std::uint64_t late() const { return late_; }
  std::uint64_t duplicates() const { return duplicates_; }
  std::uint64_t stale() const { return stale_; }

 private:
  bool have_last_ = false;
  std::uint32_t last_ = 0;
  std::uint64_t seen_ = 0;  // bit k: last_ - k was received
  std::uint32_t fill_ = 0;  // bits of seen_ that stand for sequences since the first one
  std::uint64_t settled_lost_ = 0;
  std::uint64_t lost_ = 0;
  std::uint64_t late_ = 0;
  std::uint64_t duplicates_ = 0;
  std::uint64_t stale_ = 0;
};

}  // namespace hc::rig::rdt
