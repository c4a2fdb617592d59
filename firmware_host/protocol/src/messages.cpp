#include "firmware_host/protocol/messages.h"

#include "firmware_host/protocol/cobs.h"
#include "firmware_host/protocol/crc32c.h"

namespace hc::fw {
namespace {

// Little-endian field writer/reader over a bounded buffer (bounds are guaranteed by the fixed
// payload sizes checked before use).
class Writer {
 public:
  explicit Writer(std::uint8_t* p) : p_(p) {}
  void u8(std::uint8_t v) { *p_++ = v; }
  void u16(std::uint16_t v) {
    u8(static_cast<std::uint8_t>(v));
    u8(static_cast<std::uint8_t>(v >> 8));
  }
  void u32(std::uint32_t v) {
    u16(static_cast<std::uint16_t>(v));
    u16(static_cast<std::uint16_t>(v >> 16));
  }
  void u64(std::uint64_t v) {
    u32(static_cast<std::uint32_t>(v));
    u32(static_cast<std::uint32_t>(v >> 32));
  }
  std::uint8_t* pos() const { return p_; }

 private:
  std::uint8_t* p_;
};

class Reader {
 public:
  explicit Reader(const std::uint8_t* p) : p_(p) {}
  std::uint8_t u8() { return *p_++; }
  std::uint16_t u16() {
    const std::uint16_t lo = u8();
    return static_cast<std::uint16_t>(lo | (static_cast<std::uint16_t>(u8()) << 8));
  }
  std::uint32_t u32() {
    const std::uint32_t lo = u16();
    return lo | (static_cast<std::uint32_t>(u16()) << 16);
  }
  std::uint64_t u64() {
    const std::uint64_t lo = u32();
    return lo | (static_cast<std::uint64_t>(u32()) << 32);
  }

 private:
  const std::uint8_t* p_;
};

bool valid_nack_reason(std::uint8_t v) { return v >= 1 && v <= 5; }
bool valid_error_code(std::uint16_t v) { return v >= 1 && v <= 5; }
bool valid_state(std::uint8_t v) { return v <= 3; }

void write_payload(const Message& m, Writer& w) {
  switch (m.type) {
    case MessageType::kHello:
      w.u16(m.hello.protocol_version);
      break;
    case MessageType::kConfigureTrigger:
      w.u32(m.configure.period_us);
      w.u32(m.configure.pulse_width_us);
      w.u8(m.configure.lines_mask);
      w.u8(m.configure.adc_channels_mask);
      w.u32(m.configure.count);
      w.u16(m.configure.heartbeat_period_ms);
      break;
    case MessageType::kStart:
      w.u32(m.start.start_delay_us);
      break;
    case MessageType::kStop:
      break;
    case MessageType::kHelloReply:
      w.u16(m.hello_reply.protocol_version);
      w.u8(m.hello_reply.firmware_major);
      w.u8(m.hello_reply.firmware_minor);
      w.u8(m.hello_reply.firmware_patch);
      w.u8(m.hello_reply.num_trigger_lines);
      w.u8(m.hello_reply.num_adc_channels);
      w.u8(m.hello_reply.adc_bits);
      w.u16(m.hello_reply.event_capacity);
      break;
    case MessageType::kAck:
      w.u16(m.ack.acked_seq);
      w.u8(static_cast<std::uint8_t>(m.ack.acked_type));
      break;
    case MessageType::kNack:
      w.u16(m.nack.acked_seq);
      w.u8(static_cast<std::uint8_t>(m.nack.acked_type));
      w.u8(static_cast<std::uint8_t>(m.nack.reason));
      w.u8(m.nack.detail);
      break;
    case MessageType::kTriggerEdge:
      w.u32(m.edge.edge_index);
      w.u64(m.edge.timestamp_us);
      w.u8(m.edge.lines_mask);
      w.u16(m.edge.lateness_us);
      break;
    case MessageType::kAdcSample:
      w.u32(m.sample.edge_index);
      w.u64(m.sample.timestamp_us);
      w.u8(m.sample.channel);
      w.u16(m.sample.raw);
      break;
    case MessageType::kHeartbeat:
      w.u64(m.heartbeat.uptime_us);
      w.u16(m.heartbeat.buffer_fill);
      w.u16(m.heartbeat.buffer_capacity);
      w.u32(m.heartbeat.dropped_events);
      w.u32(m.heartbeat.edges_emitted);
      w.u8(static_cast<std::uint8_t>(m.heartbeat.state));
      break;
    case MessageType::kError:
      w.u16(static_cast<std::uint16_t>(m.error.code));
      w.u32(m.error.detail);
      w.u64(m.error.timestamp_us);
      break;
  }
}

// Parses the payload into `m` (type already set). Returns kBadField for undefined enum values.
DecodeError read_payload(Reader& r, Message& m) {
  switch (m.type) {
    case MessageType::kHello:
      m.hello.protocol_version = r.u16();
      break;
    case MessageType::kConfigureTrigger:
      m.configure.period_us = r.u32();
      m.configure.pulse_width_us = r.u32();
      m.configure.lines_mask = r.u8();
      m.configure.adc_channels_mask = r.u8();
      m.configure.count = r.u32();
      m.configure.heartbeat_period_ms = r.u16();
      break;
    case MessageType::kStart:
      m.start.start_delay_us = r.u32();
      break;
    case MessageType::kStop:
      break;
    case MessageType::kHelloReply:
      m.hello_reply.protocol_version = r.u16();
      m.hello_reply.firmware_major = r.u8();
      m.hello_reply.firmware_minor = r.u8();
      m.hello_reply.firmware_patch = r.u8();
      m.hello_reply.num_trigger_lines = r.u8();
      m.hello_reply.num_adc_channels = r.u8();
      m.hello_reply.adc_bits = r.u8();
      m.hello_reply.event_capacity = r.u16();
      break;
    case MessageType::kAck: {
      m.ack.acked_seq = r.u16();
      const std::uint8_t t = r.u8();
      if (!is_known_type(t)) return DecodeError::kBadField;
      m.ack.acked_type = static_cast<MessageType>(t);
      break;
    }
    case MessageType::kNack: {
      m.nack.acked_seq = r.u16();
      const std::uint8_t t = r.u8();
      const std::uint8_t reason = r.u8();
      if (!is_known_type(t) || !valid_nack_reason(reason)) return DecodeError::kBadField;
      m.nack.acked_type = static_cast<MessageType>(t);
      m.nack.reason = static_cast<NackReason>(reason);
      m.nack.detail = r.u8();
      break;
    }
    case MessageType::kTriggerEdge:
      m.edge.edge_index = r.u32();
      m.edge.timestamp_us = r.u64();
      m.edge.lines_mask = r.u8();
      m.edge.lateness_us = r.u16();
      break;
    case MessageType::kAdcSample:
      m.sample.edge_index = r.u32();
      m.sample.timestamp_us = r.u64();
      m.sample.channel = r.u8();
      m.sample.raw = r.u16();
      break;
    case MessageType::kHeartbeat: {
      m.heartbeat.uptime_us = r.u64();
      m.heartbeat.buffer_fill = r.u16();
      m.heartbeat.buffer_capacity = r.u16();
      m.heartbeat.dropped_events = r.u32();
      m.heartbeat.edges_emitted = r.u32();
      const std::uint8_t s = r.u8();
      if (!valid_state(s)) return DecodeError::kBadField;
      m.heartbeat.state = static_cast<SequencerState>(s);
      break;
    }
    case MessageType::kError: {
      const std::uint16_t code = r.u16();
      if (!valid_error_code(code)) return DecodeError::kBadField;
      m.error.code = static_cast<ErrorCode>(code);
      m.error.detail = r.u32();
      m.error.timestamp_us = r.u64();
      break;
    }
  }
  return DecodeError::kOk;
}

}  // namespace

bool is_known_type(std::uint8_t type) {
  return (type >= 0x01 && type <= 0x04) || (type >= 0x81 && type <= 0x87);
}

std::size_t payload_size(MessageType type) {
  switch (type) {
    case MessageType::kHello:
      return 2;
    case MessageType::kConfigureTrigger:
      return 16;
    case MessageType::kStart:
      return 4;
    case MessageType::kStop:
      return 0;
    case MessageType::kHelloReply:
      return 10;
    case MessageType::kAck:
      return 3;
    case MessageType::kNack:
      return 5;
    case MessageType::kTriggerEdge:
      return 15;
    case MessageType::kAdcSample:
      return 15;
    case MessageType::kHeartbeat:
      return 21;
    case MessageType::kError:
      return 14;
  }
  return 0;
}

const char* to_string(DecodeError error) {
  switch (error) {
    case DecodeError::kOk:
      return "ok";
    case DecodeError::kTooLong:
      return "frame too long";
    case DecodeError::kCobs:
      return "invalid COBS encoding";
    case DecodeError::kTooShort:
      return "packet too short";
    case DecodeError::kCrc:
      return "CRC mismatch";
    case DecodeError::kLength:
      return "length field disagrees with packet size";
    case DecodeError::kUnknownType:
      return "unknown message type";
    case DecodeError::kPayloadSize:
      return "wrong payload size for type";
    case DecodeError::kBadField:
      return "undefined enum value in payload";
  }
  return "unknown decode error";
}

const char* to_string(MessageType type) {
  switch (type) {
    case MessageType::kHello:
      return "Hello";
    case MessageType::kConfigureTrigger:
      return "ConfigureTrigger";
    case MessageType::kStart:
      return "Start";
    case MessageType::kStop:
      return "Stop";
    case MessageType::kHelloReply:
      return "HelloReply";
    case MessageType::kAck:
      return "Ack";
    case MessageType::kNack:
      return "Nack";
    case MessageType::kTriggerEdge:
      return "TriggerEdge";
    case MessageType::kAdcSample:
      return "AdcSample";
    case MessageType::kHeartbeat:
      return "Heartbeat";
    case MessageType::kError:
      return "Error";
  }
  return "unknown";
}

const char* to_string(NackReason reason) {
  switch (reason) {
    case NackReason::kBadVersion:
      return "unsupported protocol version";
    case NackReason::kInvalidConfig:
      return "invalid trigger configuration";
    case NackReason::kNotConfigured:
      return "not configured";
    case NackReason::kBusy:
      return "busy (sequencer running)";
    case NackReason::kUnexpected:
      return "unexpected message type";
  }
  return "unknown reason";
}

const char* to_string(ErrorCode code) {
  switch (code) {
    case ErrorCode::kOverrun:
      return "overrun";
    case ErrorCode::kLateEdge:
      return "late edge";
    case ErrorCode::kHostFrameBad:
      return "bad host frame";
    case ErrorCode::kTxOverflow:
      return "USB transmit overflow";
    case ErrorCode::kAdcTimeout:
      return "ADC timeout";
  }
  return "unknown error";
}

const char* to_string(SequencerState state) {
  switch (state) {
    case SequencerState::kIdle:
      return "idle";
    case SequencerState::kConfigured:
      return "configured";
    case SequencerState::kRunning:
      return "running";
    case SequencerState::kDone:
      return "done";
  }
  return "unknown";
}

Message make_message(MessageType type, std::uint16_t seq) {
  Message m;
  m.type = type;
  m.seq = seq;
  return m;
}

std::size_t encode_packet(const Message& msg, std::uint8_t* out, std::size_t cap) {
  if (!is_known_type(static_cast<std::uint8_t>(msg.type))) return 0;
  const std::size_t len = payload_size(msg.type);
  const std::size_t total = kPacketHeaderSize + len + kPacketCrcSize;
  if (cap < total) return 0;
  Writer w(out);
  w.u8(static_cast<std::uint8_t>(msg.type));
  w.u16(msg.seq);
  w.u8(static_cast<std::uint8_t>(len));
  write_payload(msg, w);
  w.u32(crc32c(out, kPacketHeaderSize + len));
  return total;
}

DecodeError decode_packet(const std::uint8_t* packet, std::size_t size, Message* out) {
  if (size < kPacketHeaderSize + kPacketCrcSize) return DecodeError::kTooShort;
  if (size > kMaxPacketSize) return DecodeError::kTooLong;
  const std::size_t body = size - kPacketCrcSize;
  Reader crc_reader(packet + body);
  if (crc_reader.u32() != crc32c(packet, body)) return DecodeError::kCrc;
  Reader r(packet);
  const std::uint8_t type = r.u8();
  const std::uint16_t seq = r.u16();
  const std::uint8_t len = r.u8();
  if (len != body - kPacketHeaderSize) return DecodeError::kLength;
  if (!is_known_type(type)) return DecodeError::kUnknownType;
  Message m;
  m.type = static_cast<MessageType>(type);
  m.seq = seq;
  if (len != payload_size(m.type)) return DecodeError::kPayloadSize;
  if (const DecodeError e = read_payload(r, m); e != DecodeError::kOk) return e;
  *out = m;
  return DecodeError::kOk;
}

std::size_t encode_frame(const Message& msg, std::uint8_t* out, std::size_t cap) {
  std::uint8_t packet[kMaxPacketSize];
  const std::size_t n = encode_packet(msg, packet, sizeof packet);
  if (n == 0 || cap < cobs_max_encoded_size(n) + 1) return 0;
  const std::size_t encoded = cobs_encode(packet, n, out, cap - 1);
  if (encoded == 0) return 0;
  out[encoded] = 0;
  return encoded + 1;
}

DecodeError decode_frame(const std::uint8_t* data, std::size_t size, Message* out) {
  if (size > kMaxFrameSize - 1) return DecodeError::kTooLong;
  std::uint8_t packet[kMaxFrameSize];
  const std::size_t n = cobs_decode(data, size, packet, sizeof packet);
  if (n == kCobsError) return DecodeError::kCobs;
  return decode_packet(packet, n, out);
}

StreamDecoder::Result StreamDecoder::next(const std::uint8_t** cursor, const std::uint8_t* end,
                                          Message* out, DecodeError* error) {
  const std::uint8_t* p = *cursor;
  while (p != end) {
    const std::uint8_t byte = *p++;
    if (byte != 0) {
      if (overflow_) {
        ++bytes_discarded_;
      } else if (fill_ == sizeof buffer_ - 1) {  // room for a frame of kMaxFrameSize - 1 bytes
        overflow_ = true;
        bytes_discarded_ += fill_ + 1;
        fill_ = 0;
      } else {
        buffer_[fill_++] = byte;
      }
      continue;
    }
    // Delimiter: one frame (or an over-long run, or nothing) ends here.
    if (overflow_) {
      overflow_ = false;
      ++bytes_discarded_;  // the delimiter, as for any dropped frame
      *cursor = p;
      ++frames_bad_;
      ++errors_[static_cast<std::size_t>(DecodeError::kTooLong)];
      *error = DecodeError::kTooLong;
      return Result::kError;
    }
    if (fill_ == 0) continue;  // empty frame: a flush, not an error
    const std::size_t n = fill_;
    fill_ = 0;
    const DecodeError e = decode_frame(buffer_, n, out);
    *cursor = p;
    if (e == DecodeError::kOk) {
      ++frames_ok_;
      return Result::kMessage;
    }
    ++frames_bad_;
    ++errors_[static_cast<std::size_t>(e)];
    bytes_discarded_ += n + 1;
    *error = e;
    return Result::kError;
  }
  *cursor = p;
  return Result::kNeedMore;
}

void StreamDecoder::reset() {
  fill_ = 0;
  overflow_ = false;
}

}  // namespace hc::fw
