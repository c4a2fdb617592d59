// The trigger/FSR firmware's wire protocol (version kProtocolVersion). Freestanding: no heap, no
// exceptions, no OS — the same code encodes on the microcontroller and decodes on the host.
//
// Byte stream on the USB bulk endpoints (both directions):
//   frame  := COBS(packet) 0x00                      (0x00 only ever appears as the delimiter)
//   packet := type:u8 seq:u16 len:u8 payload[len] crc:u32
//   crc    := CRC-32C (see crc32c.h) over type..payload; every integer is little-endian.
// `len` must equal the fixed payload size of `type` (checked), so a packet is self-delimiting even
// before the CRC is checked. `seq` numbers the sender's frames (wrapping u16); the device echoes
// the seq of the command it answers in Ack/Nack, and the host counts gaps in the device's seq as
// lost frames. The host begins with Hello; the device answers HelloReply with its protocol version
// and the host refuses to talk to another major version.
#pragma once

#include <cstddef>
#include <cstdint>

#include "firmware_host/protocol/cobs.h"

namespace hc::fw {

inline constexpr std::uint16_t kProtocolVersion = 1;
inline constexpr std::size_t kPacketHeaderSize = 4;  // type, seq (2), len
inline constexpr std::size_t kPacketCrcSize = 4;
inline constexpr std::size_t kMaxPayloadSize = 32;
inline constexpr std::size_t kMaxPacketSize = kPacketHeaderSize + kMaxPayloadSize + kPacketCrcSize;
// Largest frame on the wire including the 0x00 delimiter.
inline constexpr std::size_t kMaxFrameSize = cobs_max_encoded_size(kMaxPacketSize) + 1;

enum class MessageType : std::uint8_t {
  // host -> device
  kHello = 0x01,
  kConfigureTrigger = 0x02,
  kStart = 0x03,
  kStop = 0x04,
  // device -> host
  kHelloReply = 0x81,
  kAck = 0x82,
  kNack = 0x83,
  kTriggerEdge = 0x84,
  kAdcSample = 0x85,
  kHeartbeat = 0x86,
  kError = 0x87,
};

// Why a command was refused (Nack.reason).
enum class NackReason : std::uint8_t {
  kBadVersion = 1,     // Hello carried a protocol version the firmware does not speak
  kInvalidConfig = 2,  // ConfigureTrigger values out of range (see Nack.detail for the field)
  kNotConfigured = 3,  // Start before a valid ConfigureTrigger
  kBusy = 4,           // ConfigureTrigger while the sequencer runs
  kUnexpected = 5,     // a device->host message type sent to the device
};

// Which ConfigureTrigger field was rejected (Nack.detail when reason == kInvalidConfig).
enum class ConfigField : std::uint8_t {
  kNone = 0,
  kPeriod = 1,
  kPulseWidth = 2,
  kLinesMask = 3,
  kAdcChannelsMask = 4,
  kHeartbeatPeriod = 5,
};

// ErrorReport.code: asynchronous faults the device reports.
enum class ErrorCode : std::uint16_t {
  kOverrun = 1,       // event ring buffer full; detail = events dropped since the last report
  kLateEdge = 2,      // a trigger edge fired late; detail = lateness in µs
  kHostFrameBad = 3,  // a host frame failed to decode; detail = DecodeError value
  kTxOverflow = 4,    // USB IN stalled and a frame was discarded; detail = frames discarded
  kAdcTimeout = 5,    // an ADC conversion never completed; detail = channel
};

// Sequencer state as reported in heartbeats.
enum class SequencerState : std::uint8_t {
  kIdle = 0,  // not configured
  kConfigured = 1,
  kRunning = 2,
  kDone = 3,  // a finite train finished
};

struct Hello {
  std::uint16_t protocol_version = kProtocolVersion;
};

struct HelloReply {
  std::uint16_t protocol_version = kProtocolVersion;
  std::uint8_t firmware_major = 0;
  std::uint8_t firmware_minor = 0;
  std::uint8_t firmware_patch = 0;
  std::uint8_t num_trigger_lines = 0;
  std::uint8_t num_adc_channels = 0;
  std::uint8_t adc_bits = 0;
  std::uint16_t event_capacity = 0;  // ring buffer slots
};

// Pulse train: rising edge k at t0 + k * period_us on every line in lines_mask, falling edge
// pulse_width_us later; the ADC channels in adc_channels_mask are sampled at every rising edge.
struct ConfigureTrigger {
  std::uint32_t period_us = 0;
  std::uint32_t pulse_width_us = 0;
  std::uint8_t lines_mask = 0;
  std::uint8_t adc_channels_mask = 0;
  std::uint32_t count = 0;  // number of pulses; 0 = continuous until Stop
  std::uint16_t heartbeat_period_ms = 0;
};

struct Start {
  std::uint32_t start_delay_us = 0;  // first edge at (time Start is handled) + delay
};

struct Ack {
  std::uint16_t acked_seq = 0;
  MessageType acked_type = MessageType::kHello;
};

struct Nack {
  std::uint16_t acked_seq = 0;
  MessageType acked_type = MessageType::kHello;
  NackReason reason = NackReason::kInvalidConfig;
  std::uint8_t detail = 0;
};

struct TriggerEdge {
  std::uint32_t edge_index = 0;    // 0-based within the current train
  std::uint64_t timestamp_us = 0;  // firmware clock (µs since boot) when the lines went high
  std::uint8_t lines_mask = 0;
  std::uint16_t lateness_us = 0;  // actual - scheduled time (saturated)
};

struct AdcSample {
  std::uint32_t edge_index = 0;    // the trigger edge this sample belongs to
  std::uint64_t timestamp_us = 0;  // firmware clock when the conversion started
  std::uint8_t channel = 0;
  std::uint16_t raw = 0;
};

struct Heartbeat {
  std::uint64_t uptime_us = 0;
  std::uint16_t buffer_fill = 0;
  std::uint16_t buffer_capacity = 0;
  std::uint32_t dropped_events = 0;  // total since boot
  std::uint32_t edges_emitted = 0;   // in the current train
  SequencerState state = SequencerState::kIdle;
};

struct ErrorReport {
  ErrorCode code = ErrorCode::kOverrun;
  std::uint32_t detail = 0;
  std::uint64_t timestamp_us = 0;
};

// One decoded or to-be-encoded message: `type` says which member is meaningful. A plain struct (not
// a union or std::variant) so it is trivially copyable, has no UB on access and needs no RTTI.
struct Message {
  MessageType type = MessageType::kHello;
  std::uint16_t seq = 0;
  Hello hello;
  HelloReply hello_reply;
  ConfigureTrigger configure;
  Start start;
  Ack ack;
  Nack nack;
  TriggerEdge edge;
  AdcSample sample;
  Heartbeat heartbeat;
  ErrorReport error;
};

enum class DecodeError : std::uint8_t {
  kOk = 0,
  kTooLong = 1,      // frame longer than kMaxFrameSize before its delimiter
  kCobs = 2,         // not valid COBS
  kTooShort = 3,     // packet shorter than header + CRC
  kCrc = 4,          // checksum mismatch
  kLength = 5,       // len field disagrees with the packet size
  kUnknownType = 6,  // type byte not in MessageType
  kPayloadSize = 7,  // len is not the fixed payload size of the type
  kBadField = 8,     // an enum field holds an undefined value
};
inline constexpr std::size_t kNumDecodeErrors = 9;

const char* to_string(DecodeError error);
const char* to_string(MessageType type);
const char* to_string(NackReason reason);
const char* to_string(ErrorCode code);
const char* to_string(SequencerState state);
bool is_known_type(std::uint8_t type);
// Fixed payload size of a message type (0 for an unknown type, which is also a valid size).
std::size_t payload_size(MessageType type);

// Writes the packet (header, payload, CRC; not COBS-encoded) for `msg`. Returns its size, or 0 when
// `cap` is too small or msg.type is unknown.
std::size_t encode_packet(const Message& msg, std::uint8_t* out, std::size_t cap);
// Parses a packet (after COBS decoding). On error `out` is left unchanged.
DecodeError decode_packet(const std::uint8_t* packet, std::size_t size, Message* out);

// Writes COBS(packet) followed by the 0x00 delimiter. Returns the frame size, or 0 on failure
// (cap < frame size or unknown type). A buffer of kMaxFrameSize always suffices.
std::size_t encode_frame(const Message& msg, std::uint8_t* out, std::size_t cap);
// Decodes one frame's bytes without the trailing delimiter. On error `out` is left unchanged.
DecodeError decode_frame(const std::uint8_t* data, std::size_t size, Message* out);

// Incremental decoder for a byte stream: buffers bytes up to the next 0x00 delimiter, decodes the
// frame, and resynchronises after garbage (a bad frame costs only the bytes up to the next
// delimiter; an over-long run is discarded up to the next delimiter). Consecutive delimiters
// (empty frames) are ignored, so a sender may emit 0x00 to flush a receiver. No heap.
class StreamDecoder {
 public:
  enum class Result : std::uint8_t { kNeedMore, kMessage, kError };

  // Consumes bytes from [*cursor, end) until one frame completes; advances *cursor past the bytes
  // consumed. kMessage: *out holds the message. kError: *error says why the frame was dropped.
  // kNeedMore: all input consumed, no complete frame.
  Result next(const std::uint8_t** cursor, const std::uint8_t* end, Message* out,
              DecodeError* error);
  // Forgets a partly received frame (e.g. after reopening the link).
  void reset();

  std::uint32_t frames_ok() const { return frames_ok_; }
  std::uint32_t frames_bad() const { return frames_bad_; }
  std::uint32_t errors(DecodeError e) const { return errors_[static_cast<std::size_t>(e)]; }
  std::uint64_t bytes_discarded() const { return bytes_discarded_; }

 private:
  std::uint8_t buffer_[kMaxFrameSize] = {};
  std::size_t fill_ = 0;
  bool overflow_ = false;  // discarding until the next delimiter
  std::uint32_t frames_ok_ = 0;
  std::uint32_t frames_bad_ = 0;
  std::uint32_t errors_[kNumDecodeErrors] = {};
  std::uint64_t bytes_discarded_ = 0;
};

// Convenience builders (host and firmware both use them).
Message make_message(MessageType type, std::uint16_t seq);

}  // namespace hc::fw
