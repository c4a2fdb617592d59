// Wire protocol: CRC-32C and COBS against published vectors, golden frames from an independent
// implementation, round trips of every message type, and every malformed-input path.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "firmware_host/protocol/cobs.h"
#include "firmware_host/protocol/crc32c.h"
#include "firmware_host/protocol/messages.h"

namespace hc::fw {
namespace {

using Bytes = std::vector<std::uint8_t>;

std::uint32_t crc_of(const Bytes& b) { return crc32c(b.data(), b.size()); }

TEST(Crc32c, StandardCheckValue) {
  // CRC RevEng catalogue, CRC-32/ISCSI: check = 0xE3069283 over ASCII "123456789".
  const char* text = "123456789";
  EXPECT_EQ(crc32c(reinterpret_cast<const std::uint8_t*>(text), 9), 0xE3069283u);
  EXPECT_EQ(kCrc32cCheckValue, 0xE3069283u);
}

TEST(Crc32c, Rfc3720Vectors) {
  // RFC 3720 (iSCSI) appendix B.4, CRC-32C examples (CRC bytes listed there least significant
  // first).
  EXPECT_EQ(crc_of(Bytes(32, 0x00)), 0x8A9136AAu);
  EXPECT_EQ(crc_of(Bytes(32, 0xFF)), 0x62A8AB43u);
  Bytes inc(32);
  for (int i = 0; i < 32; ++i) inc[i] = static_cast<std::uint8_t>(i);
  EXPECT_EQ(crc_of(inc), 0x46DD794Eu);
}

TEST(Crc32c, IncrementalEqualsWhole) {
  const Bytes data = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  for (std::size_t split = 0; split <= data.size(); ++split) {
    const std::uint32_t head = crc32c(data.data(), split);
    EXPECT_EQ(crc32c(data.data() + split, data.size() - split, head), 0xE3069283u) << split;
  }
}

Bytes cobs(const Bytes& in) {
  Bytes out(cobs_max_encoded_size(in.size()));
  const std::size_t n = cobs_encode(in.data(), in.size(), out.data(), out.size());
  out.resize(n);
  return out;
}

Bytes uncobs(const Bytes& in, bool* ok) {
  Bytes out(in.size() + 1);
  const std::size_t n = cobs_decode(in.data(), in.size(), out.data(), out.size());
  *ok = n != kCobsError;
  out.resize(*ok ? n : 0);
  return out;
}

Bytes range_bytes(int first, int last) {  // inclusive
  Bytes b;
  for (int v = first; v <= last; ++v) b.push_back(static_cast<std::uint8_t>(v));
  return b;
}

TEST(Cobs, PublishedExamples) {
  // The examples table of Wikipedia's "Consistent Overhead Byte Stuffing" article (encoded column
  // without its trailing 0x00 delimiter), which follows Cheshire & Baker 1999.
  struct Case {
    Bytes raw, encoded;
  };
  Bytes e254 = {0xFF};
  const Bytes r254 = range_bytes(0x01, 0xFE);
  e254.insert(e254.end(), r254.begin(), r254.end());
  Bytes r255a = range_bytes(0x00, 0xFE);
  Bytes e255a = {0x01, 0xFF};
  e255a.insert(e255a.end(), r254.begin(), r254.end());
  Bytes r255b = range_bytes(0x01, 0xFF);
  Bytes e255b = e254;
  e255b.push_back(0x02);
  e255b.push_back(0xFF);
  Bytes r255c = range_bytes(0x02, 0xFF);
  r255c.push_back(0x00);
  Bytes e255c = {0xFF};
  const Bytes r2ff = range_bytes(0x02, 0xFF);
  e255c.insert(e255c.end(), r2ff.begin(), r2ff.end());
  e255c.push_back(0x01);
  e255c.push_back(0x01);
  Bytes r255d = range_bytes(0x03, 0xFF);
  r255d.push_back(0x00);
  r255d.push_back(0x01);
  Bytes e255d = {0xFE};
  const Bytes r3ff = range_bytes(0x03, 0xFF);
  e255d.insert(e255d.end(), r3ff.begin(), r3ff.end());
  e255d.push_back(0x02);
  e255d.push_back(0x01);
  const std::vector<Case> cases = {
      {{0x00}, {0x01, 0x01}},
      {{0x00, 0x00}, {0x01, 0x01, 0x01}},
      {{0x00, 0x11, 0x00}, {0x01, 0x02, 0x11, 0x01}},
      {{0x11, 0x22, 0x00, 0x33}, {0x03, 0x11, 0x22, 0x02, 0x33}},
      {{0x11, 0x22, 0x33, 0x44}, {0x05, 0x11, 0x22, 0x33, 0x44}},
      {{0x11, 0x00, 0x00, 0x00}, {0x02, 0x11, 0x01, 0x01, 0x01}},
      {r254, e254},
      {r255a, e255a},
      {r255b, e255b},
      {r255c, e255c},
      {r255d, e255d},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    EXPECT_EQ(cobs(cases[i].raw), cases[i].encoded) << "case " << i;
    bool ok = false;
    EXPECT_EQ(uncobs(cases[i].encoded, &ok), cases[i].raw) << "case " << i;
    EXPECT_TRUE(ok) << "case " << i;
  }
}

TEST(Cobs, RandomRoundTripHasNoZerosAndRespectsBound) {
  std::mt19937 rng(42);
  for (std::size_t n = 0; n < 700; ++n) {
    Bytes raw(n);
    const int zero_pct = static_cast<int>(n % 4) * 25;  // 0 %, 25 %, 50 %, 75 % zero bytes
    for (auto& b : raw)
      b = static_cast<int>(rng() % 100) < zero_pct ? 0 : static_cast<std::uint8_t>(1 + rng() % 255);
    const Bytes enc = cobs(raw);
    ASSERT_FALSE(enc.empty());
    EXPECT_LE(enc.size(), cobs_max_encoded_size(n));
    for (std::uint8_t b : enc) ASSERT_NE(b, 0);
    bool ok = false;
    EXPECT_EQ(uncobs(enc, &ok), raw) << n;
    EXPECT_TRUE(ok);
  }
}

TEST(Cobs, MalformedInputIsRejected) {
  bool ok = true;
  uncobs({}, &ok);
  EXPECT_FALSE(ok) << "empty";
  uncobs({0x03, 0x11, 0x00}, &ok);
  EXPECT_FALSE(ok) << "zero inside";
  uncobs({0x00}, &ok);
  EXPECT_FALSE(ok) << "zero code";
  uncobs({0x05, 0x11, 0x22}, &ok);
  EXPECT_FALSE(ok) << "code past end";
  // Output capacity too small.
  const Bytes enc = {0x05, 0x11, 0x22, 0x33, 0x44};
  std::uint8_t out[3];
  EXPECT_EQ(cobs_decode(enc.data(), enc.size(), out, sizeof out), kCobsError);
  std::uint8_t small[4];
  const std::uint8_t raw[4] = {1, 2, 3, 4};
  EXPECT_EQ(cobs_encode(raw, 4, small, sizeof small), 0u);
}

Bytes frame_of(const Message& m) {
  Bytes out(kMaxFrameSize);
  const std::size_t n = encode_frame(m, out.data(), out.size());
  out.resize(n);
  return out;
}

TEST(Frame, GoldenBytesFromIndependentImplementation) {
  // Expected bytes computed by a separate bit-serial CRC-32C and COBS written in Python (from the
  // definitions in crc32c.h / cobs.h), not by this code.
  Message hello = make_message(MessageType::kHello, 0x0102);
  hello.hello.protocol_version = 1;
  EXPECT_EQ(frame_of(hello),
            (Bytes{0x06, 0x01, 0x02, 0x01, 0x02, 0x01, 0x05, 0x09, 0xA8, 0xB0, 0x49, 0x00}));
  Message edge = make_message(MessageType::kTriggerEdge, 7);
  edge.edge.edge_index = 3;
  edge.edge.timestamp_us = 1'000'000;
  edge.edge.lines_mask = 5;
  edge.edge.lateness_us = 2;
  EXPECT_EQ(frame_of(edge),
            (Bytes{0x03, 0x84, 0x07, 0x03, 0x0F, 0x03, 0x01, 0x01, 0x04, 0x40, 0x42, 0x0F, 0x01,
                   0x01, 0x01, 0x01, 0x03, 0x05, 0x02, 0x05, 0xD8, 0x6C, 0x59, 0xB9, 0x00}));
}

// One message of every type with every field set to a distinct non-default value.
std::vector<Message> all_messages() {
  std::vector<Message> v;
  Message m = make_message(MessageType::kHello, 1);
  m.hello.protocol_version = 0xBEEF;
  v.push_back(m);
  m = make_message(MessageType::kConfigureTrigger, 2);
  m.configure = {33'333, 1'000, 0x05, 0x03, 90, 250};
  v.push_back(m);
  m = make_message(MessageType::kStart, 3);
  m.start.start_delay_us = 0xDEADBEEF;
  v.push_back(m);
  v.push_back(make_message(MessageType::kStop, 0xFFFF));
  m = make_message(MessageType::kHelloReply, 5);
  m.hello_reply = {1, 2, 3, 4, 5, 6, 12, 256};
  v.push_back(m);
  m = make_message(MessageType::kAck, 6);
  m.ack = {0x1234, MessageType::kStart};
  v.push_back(m);
  m = make_message(MessageType::kNack, 7);
  m.nack = {0x4321, MessageType::kConfigureTrigger, NackReason::kInvalidConfig, 3};
  v.push_back(m);
  m = make_message(MessageType::kTriggerEdge, 8);
  m.edge = {0xFFFFFFFE, 0x0123456789ABCDEFull, 0x80, 0xFFFF};
  v.push_back(m);
  m = make_message(MessageType::kAdcSample, 9);
  m.sample = {77, 0xFEDCBA9876543210ull, 7, 4095};
  v.push_back(m);
  m = make_message(MessageType::kHeartbeat, 10);
  m.heartbeat = {123456789012ull, 17, 256, 99, 1000, SequencerState::kDone};
  v.push_back(m);
  m = make_message(MessageType::kError, 11);
  m.error = {ErrorCode::kAdcTimeout, 0xCAFEF00D, 42};
  v.push_back(m);
  return v;
}

void expect_same(const Message& a, const Message& b) {
  // Messages are plain data: compare the meaningful member via a re-encode.
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(frame_of(a), frame_of(b));
}

TEST(Frame, RoundTripEveryType) {
  for (const Message& m : all_messages()) {
    const Bytes f = frame_of(m);
    ASSERT_FALSE(f.empty()) << to_string(m.type);
    ASSERT_LE(f.size(), kMaxFrameSize);
    EXPECT_EQ(f.back(), 0);
    for (std::size_t i = 0; i + 1 < f.size(); ++i) ASSERT_NE(f[i], 0);
    Message out;
    ASSERT_EQ(decode_frame(f.data(), f.size() - 1, &out), DecodeError::kOk) << to_string(m.type);
    expect_same(m, out);
  }
  // Field-level spot checks (a re-encode comparison alone would hide a symmetric bug).
  const std::vector<Message> v = all_messages();
  Message out;
  Bytes f = frame_of(v[1]);
  ASSERT_EQ(decode_frame(f.data(), f.size() - 1, &out), DecodeError::kOk);
  EXPECT_EQ(out.configure.period_us, 33'333u);
  EXPECT_EQ(out.configure.pulse_width_us, 1'000u);
  EXPECT_EQ(out.configure.lines_mask, 0x05);
  EXPECT_EQ(out.configure.adc_channels_mask, 0x03);
  EXPECT_EQ(out.configure.count, 90u);
  EXPECT_EQ(out.configure.heartbeat_period_ms, 250);
  f = frame_of(v[8]);
  ASSERT_EQ(decode_frame(f.data(), f.size() - 1, &out), DecodeError::kOk);
  EXPECT_EQ(out.sample.timestamp_us, 0xFEDCBA9876543210ull);
  EXPECT_EQ(out.sample.raw, 4095);
  EXPECT_EQ(out.sample.channel, 7);
  f = frame_of(v[9]);
  ASSERT_EQ(decode_frame(f.data(), f.size() - 1, &out), DecodeError::kOk);
  EXPECT_EQ(out.heartbeat.uptime_us, 123456789012ull);
  EXPECT_EQ(out.heartbeat.state, SequencerState::kDone);
}

TEST(Frame, EncodeRejectsSmallBufferAndUnknownType) {
  Message m = make_message(MessageType::kHeartbeat, 1);
  std::uint8_t buf[kMaxFrameSize];
  EXPECT_EQ(encode_frame(m, buf, 10), 0u);
  Message bad = make_message(static_cast<MessageType>(0x42), 1);
  EXPECT_EQ(encode_frame(bad, buf, sizeof buf), 0u);
  EXPECT_EQ(encode_packet(bad, buf, sizeof buf), 0u);
}

// Builds a packet with arbitrary header fields and a correct CRC, to reach the checks behind it.
Bytes raw_packet(std::uint8_t type, std::uint8_t len_field, const Bytes& payload) {
  Bytes p = {type, 0x01, 0x00, len_field};
  p.insert(p.end(), payload.begin(), payload.end());
  const std::uint32_t c = crc32c(p.data(), p.size());
  for (int i = 0; i < 4; ++i) p.push_back(static_cast<std::uint8_t>(c >> (8 * i)));
  return p;
}

DecodeError decode_raw(const Bytes& packet, Message* out) {
  return decode_packet(packet.data(), packet.size(), out);
}

TEST(Frame, EveryMalformedPacketIsNamed) {
  Message sentinel = make_message(MessageType::kStop, 0xAAAA);
  Message out = sentinel;
  EXPECT_EQ(decode_raw({0x04, 0x00, 0x00}, &out), DecodeError::kTooShort);
  EXPECT_EQ(decode_raw(Bytes(kMaxPacketSize + 1, 1), &out), DecodeError::kTooLong);
  Bytes good = raw_packet(0x04, 0, {});
  good[1] ^= 1;  // seq changed, CRC not
  EXPECT_EQ(decode_raw(good, &out), DecodeError::kCrc);
  EXPECT_EQ(decode_raw(raw_packet(0x04, 1, {}), &out), DecodeError::kLength);
  EXPECT_EQ(decode_raw(raw_packet(0x42, 0, {}), &out), DecodeError::kUnknownType);
  EXPECT_EQ(decode_raw(raw_packet(0x00, 0, {}), &out), DecodeError::kUnknownType);
  EXPECT_EQ(decode_raw(raw_packet(0x04, 1, {0x00}), &out), DecodeError::kPayloadSize);
  EXPECT_EQ(decode_raw(raw_packet(0x01, 1, {0x01}), &out), DecodeError::kPayloadSize);
  // Undefined enum values.
  EXPECT_EQ(decode_raw(raw_packet(0x82, 3, {0, 0, 0x42}), &out), DecodeError::kBadField);
  EXPECT_EQ(decode_raw(raw_packet(0x83, 5, {0, 0, 0x02, 0x00, 0}), &out), DecodeError::kBadField);
  EXPECT_EQ(decode_raw(raw_packet(0x83, 5, {0, 0, 0x02, 0x06, 0}), &out), DecodeError::kBadField);
  Bytes hb(21, 0);
  hb[20] = 4;  // state
  EXPECT_EQ(decode_raw(raw_packet(0x86, 21, hb), &out), DecodeError::kBadField);
  Bytes err(14, 0);
  EXPECT_EQ(decode_raw(raw_packet(0x87, 14, err), &out), DecodeError::kBadField);  // code 0
  err[0] = 6;
  EXPECT_EQ(decode_raw(raw_packet(0x87, 14, err), &out), DecodeError::kBadField);
  // Nothing was half-written on any failure.
  EXPECT_EQ(out.type, MessageType::kStop);
  EXPECT_EQ(out.seq, 0xAAAA);
  // Frame-level failures.
  EXPECT_EQ(decode_frame(nullptr, 0, &out), DecodeError::kCobs);
  const Bytes zero_inside = {0x02, 0x00, 0x01};
  EXPECT_EQ(decode_frame(zero_inside.data(), zero_inside.size(), &out), DecodeError::kCobs);
  const Bytes long_frame(kMaxFrameSize, 0x01);
  EXPECT_EQ(decode_frame(long_frame.data(), long_frame.size(), &out), DecodeError::kTooLong);
  // Every code has a name.
  for (std::size_t e = 0; e < kNumDecodeErrors; ++e)
    EXPECT_STRNE(to_string(static_cast<DecodeError>(e)), "unknown decode error");
}

TEST(Frame, EveryTruncationAndSingleBitFlipIsDetected) {
  // CRC-32C detects every 1-bit error; a truncated frame fails the COBS, length or CRC check.
  for (const Message& m : all_messages()) {
    const Bytes f = frame_of(m);
    const std::size_t n = f.size() - 1;  // without the delimiter
    Message out;
    for (std::size_t cut = 0; cut < n; ++cut)
      EXPECT_NE(decode_frame(f.data(), cut, &out), DecodeError::kOk) << to_string(m.type) << cut;
    for (std::size_t bit = 0; bit < n * 8; ++bit) {
      Bytes g(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(n));
      g[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
      EXPECT_NE(decode_frame(g.data(), g.size(), &out), DecodeError::kOk)
          << to_string(m.type) << " bit " << bit;
    }
  }
}

TEST(Frame, EveryTwoBitFlipInAPacketIsDetected) {
  // CRC-32C has Hamming distance >= 6 far beyond our 41-byte packets (Koopman, "32-bit cyclic
  // redundancy codes for Internet applications", DSN 2002), so every 2-bit error is caught.
  const Message m = all_messages()[9];  // heartbeat, the longest payload
  Bytes p(kMaxPacketSize);
  p.resize(encode_packet(m, p.data(), p.size()));
  Message out;
  int checked = 0;
  for (std::size_t a = 0; a < p.size() * 8; ++a)
    for (std::size_t b = a + 1; b < p.size() * 8; ++b) {
      Bytes g = p;
      g[a / 8] ^= static_cast<std::uint8_t>(1u << (a % 8));
      g[b / 8] ^= static_cast<std::uint8_t>(1u << (b % 8));
      ASSERT_NE(decode_packet(g.data(), g.size(), &out), DecodeError::kOk) << a << "," << b;
      ++checked;
    }
  EXPECT_EQ(checked, 232 * 231 / 2);  // 29-byte packet = 232 bits
}

std::vector<Message> drain(StreamDecoder& d, const Bytes& stream, std::size_t chunk,
                           std::vector<DecodeError>* errors = nullptr) {
  std::vector<Message> got;
  for (std::size_t off = 0; off < stream.size(); off += chunk) {
    const std::uint8_t* p = stream.data() + off;
    const std::uint8_t* end = stream.data() + std::min(stream.size(), off + chunk);
    Message m;
    DecodeError e;
    for (;;) {
      const auto r = d.next(&p, end, &m, &e);
      if (r == StreamDecoder::Result::kNeedMore) break;
      if (r == StreamDecoder::Result::kMessage)
        got.push_back(m);
      else if (errors)
        errors->push_back(e);
    }
    EXPECT_EQ(p, end);
  }
  return got;
}

TEST(StreamDecoder, SplitsAnyChunking) {
  Bytes stream;
  const std::vector<Message> msgs = all_messages();
  for (const Message& m : msgs) {
    const Bytes f = frame_of(m);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  for (std::size_t chunk :
       {std::size_t{1}, std::size_t{2}, std::size_t{7}, std::size_t{64}, stream.size()}) {
    StreamDecoder d;
    const std::vector<Message> got = drain(d, stream, chunk);
    ASSERT_EQ(got.size(), msgs.size()) << chunk;
    for (std::size_t i = 0; i < got.size(); ++i) expect_same(got[i], msgs[i]);
    EXPECT_EQ(d.frames_ok(), msgs.size());
    EXPECT_EQ(d.frames_bad(), 0u);
    EXPECT_EQ(d.bytes_discarded(), 0u);
  }
}

TEST(StreamDecoder, ResynchronisesAfterGarbageAndCountsIt) {
  const std::vector<Message> msgs = all_messages();
  Bytes stream = {0x13, 0x37, 0x42};  // garbage before the first delimiter
  stream.push_back(0x00);
  const Bytes a = frame_of(msgs[0]);
  stream.insert(stream.end(), a.begin(), a.end());
  // Corrupt a frame mid-stream: it is lost, the next one is not.
  Bytes b = frame_of(msgs[7]);
  b[5] ^= 0x10;
  stream.insert(stream.end(), b.begin(), b.end());
  const Bytes c = frame_of(msgs[8]);
  stream.insert(stream.end(), c.begin(), c.end());
  // An over-long run of garbage without delimiters.
  stream.insert(stream.end(), 500, 0x55);
  stream.push_back(0x00);
  stream.push_back(0x00);  // empty frame: ignored
  const Bytes d_frame = frame_of(msgs[9]);
  stream.insert(stream.end(), d_frame.begin(), d_frame.end());

  StreamDecoder d;
  std::vector<DecodeError> errors;
  const std::vector<Message> got = drain(d, stream, 5, &errors);
  ASSERT_EQ(got.size(), 3u);
  expect_same(got[0], msgs[0]);
  expect_same(got[1], msgs[8]);
  expect_same(got[2], msgs[9]);
  ASSERT_EQ(errors.size(), 3u);
  EXPECT_NE(errors[0], DecodeError::kOk);  // the 3 garbage bytes
  EXPECT_NE(errors[1], DecodeError::kOk);  // the corrupted frame
  EXPECT_EQ(errors[2], DecodeError::kTooLong);
  EXPECT_EQ(d.frames_bad(), 3u);
  EXPECT_EQ(d.errors(DecodeError::kTooLong), 1u);
  // 3 + 1 garbage bytes, the corrupted frame, 500 + 1 over-long bytes.
  EXPECT_EQ(d.bytes_discarded(), 4u + b.size() + 501u);
}

TEST(StreamDecoder, RandomGarbageNeverLosesADelimitedFrame) {
  // Garbage bursts (which may contain 0x00) between frames: a frame preceded by a delimiter is
  // always recovered; the garbage is counted, never delivered as a message (2^-32 odds aside).
  std::mt19937 rng(7);
  const std::vector<Message> msgs = all_messages();
  Bytes stream;
  std::size_t expected = 0;
  for (int i = 0; i < 400; ++i) {
    const std::size_t junk = rng() % 80;
    for (std::size_t k = 0; k < junk; ++k) stream.push_back(static_cast<std::uint8_t>(rng()));
    stream.push_back(0x00);
    const Bytes f = frame_of(msgs[rng() % msgs.size()]);
    stream.insert(stream.end(), f.begin(), f.end());
    ++expected;
  }
  StreamDecoder d;
  const std::vector<Message> got = drain(d, stream, 13);
  EXPECT_EQ(got.size(), expected);
  EXPECT_GT(d.frames_bad(), 300u);
}

}  // namespace
}  // namespace hc::fw
