// libFuzzer target for the firmware wire protocol and the core's command handling. Arbitrary bytes
// are (1) decoded as one frame, (2) streamed through the StreamDecoder in uneven chunks, and
// (3) sent to the simulated firmware as host->device traffic while it runs. Invariants: whatever
// decodes re-encodes to a frame that decodes to the same bytes; the decoder's counters add up; the
// firmware never crashes, never drives lines the config does not name, and keeps its ring bounded.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "firmware_host/core/firmware.h"
#include "firmware_host/protocol/messages.h"
#include "firmware_host/simulator/simulator.h"

namespace {

using namespace hc::fw;

void check_reencode(const Message& m) {
  std::uint8_t frame[kMaxFrameSize];
  const std::size_t n = encode_frame(m, frame, sizeof frame);
  if (n == 0 || n > kMaxFrameSize || frame[n - 1] != 0) __builtin_trap();
  Message again;
  if (decode_frame(frame, n - 1, &again) != DecodeError::kOk) __builtin_trap();
  std::uint8_t frame2[kMaxFrameSize];
  const std::size_t n2 = encode_frame(again, frame2, sizeof frame2);
  if (n2 != n) __builtin_trap();
  for (std::size_t i = 0; i < n; ++i)
    if (frame[i] != frame2[i]) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // (1) One frame.
  Message m;
  if (decode_frame(data, size, &m) == DecodeError::kOk) check_reencode(m);
  if (decode_packet(data, size, &m) == DecodeError::kOk) check_reencode(m);

  // (2) The stream decoder, fed in chunks whose sizes come from the data itself.
  StreamDecoder decoder;
  std::size_t delivered = 0, errors = 0, off = 0;
  while (off < size) {
    const std::size_t chunk = 1 + data[off] % 17;
    const std::uint8_t* p = data + off;
    const std::uint8_t* end = data + std::min(size, off + chunk);
    DecodeError e;
    for (;;) {
      const auto r = decoder.next(&p, end, &m, &e);
      if (r == StreamDecoder::Result::kNeedMore) break;
      if (r == StreamDecoder::Result::kMessage) {
        ++delivered;
        check_reencode(m);
      } else {
        if (e == DecodeError::kOk) __builtin_trap();
        ++errors;
      }
    }
    if (p != end) __builtin_trap();
    off += chunk;
  }
  if (decoder.frames_ok() != delivered || decoder.frames_bad() != errors) __builtin_trap();
  if (decoder.bytes_discarded() > size) __builtin_trap();

  // (3) The firmware core receiving the bytes as commands while running (bounded virtual time).
  SimulatorOptions opts;
  opts.num_trigger_lines = 2;
  opts.adc_source = [](std::uint8_t channel, std::uint64_t t_us) {
    return 0.001 * static_cast<double>((t_us + channel) % 3000);
  };
  Simulator sim(opts);
  constexpr std::size_t kSlice = 32;
  const std::size_t sim_size = std::min<std::size_t>(size, 4096);  // keeps each run short
  for (std::size_t pos = 0; pos < sim_size; pos += kSlice) {
    sim.host_write(data + pos, std::min(kSlice, sim_size - pos));
    sim.advance_by(2'000);
    std::uint8_t sink[4096];
    while (sim.host_read(sink, sizeof sink) != 0) {
    }
  }
  sim.advance_by(20'000);
  const Firmware& fw = sim.firmware();
  if (fw.buffer_fill() > kEventCapacity) __builtin_trap();
  for (const GpioEdge& e : sim.gpio_edges())
    if (e.line >= opts.num_trigger_lines) __builtin_trap();
  return 0;
}
