#include "rig_daemon/backends/rdt.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <optional>

namespace hc::rig::rdt {
namespace {

// Byte order by hand (not htonl): the codec works on spans of bytes of any alignment, and the
// fuzzer feeds it arbitrary buffers.
std::uint16_t get_u16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((static_cast<unsigned>(p[0]) << 8) | p[1]);
}
std::uint32_t get_u32(const std::uint8_t* p) {
  return (static_cast<std::uint32_t>(p[0]) << 24) | (static_cast<std::uint32_t>(p[1]) << 16) |
         (static_cast<std::uint32_t>(p[2]) << 8) | static_cast<std::uint32_t>(p[3]);
}
void put_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 8);
  p[1] = static_cast<std::uint8_t>(v);
}
void put_u32(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 24);
  p[1] = static_cast<std::uint8_t>(v >> 16);
  p[2] = static_cast<std::uint8_t>(v >> 8);
  p[3] = static_cast<std::uint8_t>(v);
}

constexpr double kNewtonsPerPoundForce = 4.4482216152605;  // 0.45359237 kg x 9.80665 m/s^2
constexpr double kMetresPerInch = 0.0254;
constexpr double kMetresPerFoot = 0.3048;

// The text of the first <tag>...</tag> element, trimmed; nullopt when absent.
std::optional<std::string_view> element_text(std::string_view xml, std::string_view tag) {
  // Built with append(): g++ 12 warns (-Wrestrict, a known false positive) on "<" + string + ">".
  std::string open("<");
  open.append(tag).append(">");
  std::string close("</");
  close.append(tag).append(">");
  const std::size_t a = xml.find(open);
  if (a == std::string_view::npos) return std::nullopt;
  const std::size_t start = a + open.size();
  const std::size_t b = xml.find(close, start);
  if (b == std::string_view::npos) return std::nullopt;
  std::string_view text = xml.substr(start, b - start);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front())))
    text.remove_prefix(1);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back())))
    text.remove_suffix(1);
  return text;
}

std::int32_t saturate_round(double v) {
  if (std::isnan(v)) return 0;
  const double r = std::round(v);
  if (r >= static_cast<double>(std::numeric_limits<std::int32_t>::max()))
    return std::numeric_limits<std::int32_t>::max();
  if (r <= static_cast<double>(std::numeric_limits<std::int32_t>::min()))
    return std::numeric_limits<std::int32_t>::min();
  return static_cast<std::int32_t>(r);
}

}  // namespace

bool is_known_command(std::uint16_t code) {
  switch (static_cast<Command>(code)) {
    case Command::kStop:
    case Command::kStartRealtime:
    case Command::kStartBuffered:
    case Command::kStartMultiUnit:
    case Command::kResetThresholdLatch:
    case Command::kSetSoftwareBias:
      return true;
  }
  return false;
}

std::string_view command_name(std::uint16_t code) {
  switch (static_cast<Command>(code)) {
    case Command::kStop:
      return "stop";
    case Command::kStartRealtime:
      return "start real-time streaming";
    case Command::kStartBuffered:
      return "start buffered streaming";
    case Command::kStartMultiUnit:
      return "start multi-unit streaming";
    case Command::kResetThresholdLatch:
      return "reset threshold latch";
    case Command::kSetSoftwareBias:
      return "set software bias";
  }
  return "unknown";
}

std::array<std::uint8_t, kRequestBytes> encode_request(const Request& request) {
  std::array<std::uint8_t, kRequestBytes> out{};
  put_u16(out.data(), kCommandHeader);
  put_u16(out.data() + 2, request.command);
  put_u32(out.data() + 4, request.sample_count);
  return out;
}

Result<Request> decode_request(std::span<const std::uint8_t> bytes) {
  if (bytes.size() != kRequestBytes)
    return invalid_argument("RDT request: expected 8 bytes, got " + std::to_string(bytes.size()));
  const std::uint16_t header = get_u16(bytes.data());
  if (header != kCommandHeader)
    return invalid_argument("RDT request: header is " + std::to_string(header) +
                            ", expected 0x1234 (4660)");
  Request r;
  r.command = get_u16(bytes.data() + 2);
  r.sample_count = get_u32(bytes.data() + 4);
  if ((r.command & 0x8000u) != 0)
    return unsupported("RDT request: extended command " + std::to_string(r.command) +
                       " (with destination address) is not supported");
  if (!is_known_command(r.command))
    return invalid_argument("RDT request: unknown command " + std::to_string(r.command));
  return r;
}

void encode_record(const Record& record, std::span<std::uint8_t, kRecordBytes> out) {
  std::uint8_t* p = out.data();
  put_u32(p, record.rdt_sequence);
  put_u32(p + 4, record.ft_sequence);
  put_u32(p + 8, record.status);
  for (std::size_t i = 0; i < 6; ++i)
    put_u32(p + 12 + 4 * i, static_cast<std::uint32_t>(record.counts[i]));
}

std::vector<std::uint8_t> encode_records(std::span<const Record> records) {
  std::vector<std::uint8_t> out(records.size() * kRecordBytes);
  for (std::size_t i = 0; i < records.size(); ++i)
    encode_record(records[i], std::span<std::uint8_t, kRecordBytes>(out.data() + i * kRecordBytes,
                                                                    kRecordBytes));
  return out;
}

Result<std::vector<Record>> decode_records(std::span<const std::uint8_t> bytes) {
  if (bytes.empty()) return invalid_argument("RDT packet: empty datagram");
  if (bytes.size() % kRecordBytes != 0)
    return invalid_argument("RDT packet: " + std::to_string(bytes.size()) +
                            " bytes is not a whole number of 36-byte records");
  const std::size_t n = bytes.size() / kRecordBytes;
  if (n > kMaxRecordsPerPacket)
    return invalid_argument("RDT packet: " + std::to_string(n) + " records, at most " +
                            std::to_string(kMaxRecordsPerPacket) + " fit in a datagram");
  std::vector<Record> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* p = bytes.data() + i * kRecordBytes;
    Record& r = out[i];
    r.rdt_sequence = get_u32(p);
    r.ft_sequence = get_u32(p + 4);
    r.status = get_u32(p + 8);
    for (std::size_t k = 0; k < 6; ++k)
      r.counts[k] = static_cast<std::int32_t>(get_u32(p + 12 + 4 * k));
  }
  return out;
}

Result<double> newtons_per_force_unit(std::string_view unit) {
  if (unit == "N") return 1.0;
  if (unit == "kN") return 1e3;
  if (unit == "lbf") return kNewtonsPerPoundForce;
  return invalid_argument("unknown force unit '" + std::string(unit) + "' (expected N, kN or lbf)");
}

Result<double> newton_metres_per_torque_unit(std::string_view unit) {
  if (unit == "Nm" || unit == "N-m") return 1.0;
  if (unit == "Nmm" || unit == "N-mm") return 1e-3;
  if (unit == "kNm" || unit == "kN-m") return 1e3;
  if (unit == "lbfin" || unit == "lbf-in") return kNewtonsPerPoundForce * kMetresPerInch;
  if (unit == "lbfft" || unit == "lbf-ft") return kNewtonsPerPoundForce * kMetresPerFoot;
  return invalid_argument("unknown torque unit '" + std::string(unit) +
                          "' (expected Nm, Nmm, kNm, lbfin or lbfft)");
}

Status validate(const Calibration& c) {
  if (!(std::isfinite(c.counts_per_force) && c.counts_per_force > 0))
    return invalid_argument("counts_per_force: expected a number > 0, got " +
                            std::to_string(c.counts_per_force));
  if (!(std::isfinite(c.counts_per_torque) && c.counts_per_torque > 0))
    return invalid_argument("counts_per_torque: expected a number > 0, got " +
                            std::to_string(c.counts_per_torque));
  if (auto f = newtons_per_force_unit(c.force_unit); !f.ok()) return f.status();
  if (auto t = newton_metres_per_torque_unit(c.torque_unit); !t.ok()) return t.status();
  return {};
}

Result<Calibration> parse_calibration_xml(std::string_view xml) {
  Calibration c;
  auto number = [&](std::string_view tag, double& out) -> Status {
    auto text = element_text(xml, tag);
    if (!text) return invalid_argument("netftapi2.xml: missing <" + std::string(tag) + ">");
    const std::string s(*text);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v) || v <= 0)
      return invalid_argument("netftapi2.xml: <" + std::string(tag) +
                              ">: expected a number > 0, got '" + s + "'");
    out = v;
    return {};
  };
  HC_RETURN_IF_ERROR(number("cfgcpf", c.counts_per_force));
  HC_RETURN_IF_ERROR(number("cfgcpt", c.counts_per_torque));
  auto fu = element_text(xml, "scfgfu");
  auto tu = element_text(xml, "scfgtu");
  if (!fu) return invalid_argument("netftapi2.xml: missing <scfgfu>");
  if (!tu) return invalid_argument("netftapi2.xml: missing <scfgtu>");
  c.force_unit = std::string(*fu);
  c.torque_unit = std::string(*tu);
  if (Status s = validate(c); !s.ok()) return s.with_context("netftapi2.xml");
  return c;
}

std::string calibration_xml(const Calibration& c) {
  auto integer = [](double v) {
    // Counts per unit are integers on real sensors; keep fractions if a config has them.
    if (v == std::floor(v) && v < 1e15) return std::to_string(static_cast<long long>(v));
    return std::to_string(v);
  };
  return "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<netft>\n<cfgcpf>" +
         integer(c.counts_per_force) + "</cfgcpf>\n<cfgcpt>" + integer(c.counts_per_torque) +
         "</cfgcpt>\n<scfgfu>" + c.force_unit + "</scfgfu>\n<scfgtu>" + c.torque_unit +
         "</scfgtu>\n</netft>\n";
}

Wrench to_si(const std::array<std::int32_t, 6>& counts, const Calibration& c) {
  const double fu = newtons_per_force_unit(c.force_unit).value();
  const double tu = newton_metres_per_torque_unit(c.torque_unit).value();
  Wrench w;
  for (std::size_t i = 0; i < 3; ++i) {
    w.force_n[i] = counts[i] / c.counts_per_force * fu;
    w.torque_nm[i] = counts[3 + i] / c.counts_per_torque * tu;
  }
  return w;
}

std::array<std::int32_t, 6> to_counts(const Wrench& w, const Calibration& c) {
  const double fu = newtons_per_force_unit(c.force_unit).value();
  const double tu = newton_metres_per_torque_unit(c.torque_unit).value();
  std::array<std::int32_t, 6> out{};
  for (std::size_t i = 0; i < 3; ++i) {
    out[i] = saturate_round(w.force_n[i] / fu * c.counts_per_force);
    out[3 + i] = saturate_round(w.torque_nm[i] / tu * c.counts_per_torque);
  }
  return out;
}

SequenceTracker::Verdict SequenceTracker::update(std::uint32_t sequence) {
  if (!have_last_) {
    have_last_ = true;
    last_ = sequence;
    seen_ = 1;
    fill_ = 1;
    return Verdict::kFirst;
  }
  const auto diff = static_cast<std::int32_t>(sequence - last_);
  if (diff >= 1) {
    lost_ += static_cast<std::uint64_t>(diff - 1);
    // Old bits k >= 64 - diff fall out of the window: their zeros are settled losses; so are the
    // new gap slots that would land beyond the window at once.
    const auto d = static_cast<std::uint32_t>(diff);
    const std::uint32_t first_out = d >= kWindow ? 0 : kWindow - d;
    if (fill_ > first_out) {
      const std::uint32_t n = fill_ - first_out;
      const std::uint64_t mask = (n >= 64 ? ~std::uint64_t{0} : ((std::uint64_t{1} << n) - 1))
                                 << first_out;
      settled_lost_ += n - static_cast<std::uint32_t>(std::popcount(seen_ & mask));
    }
    if (d > kWindow) settled_lost_ += d - kWindow;
    fill_ = std::min(kWindow, fill_ + d);
    seen_ = diff >= 64 ? 1 : (seen_ << diff) | 1;
    last_ = sequence;
    return Verdict::kInOrder;
  }
  const std::uint64_t age = static_cast<std::uint64_t>(-static_cast<std::int64_t>(diff));
  if (age >= kWindow) {
    ++stale_;
    return Verdict::kStale;
  }
  const std::uint64_t bit = std::uint64_t{1} << age;
  if ((seen_ & bit) != 0) {
    ++duplicates_;
    return Verdict::kDuplicate;
  }
  seen_ |= bit;
  if (lost_ > 0) --lost_;
  ++late_;
  return Verdict::kLate;
}

}  // namespace hc::rig::rdt
