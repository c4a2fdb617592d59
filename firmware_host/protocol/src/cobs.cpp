#include "firmware_host/protocol/cobs.h"

namespace hc::fw {

std::size_t cobs_encode(const std::uint8_t* data, std::size_t size, std::uint8_t* out,
                        std::size_t cap) {
  if (cap < cobs_max_encoded_size(size)) return 0;
  std::size_t code_at = 0;  // where the current block's code byte goes
  std::size_t w = 1;
  std::uint8_t code = 1;
  for (std::size_t i = 0; i < size; ++i) {
    if (data[i] == 0) {
      out[code_at] = code;
      code_at = w++;
      code = 1;
      continue;
    }
    out[w++] = data[i];
    if (++code == 0xFF) {
      out[code_at] = code;
      code = 1;
      if (i + 1 < size)
        code_at = w++;
      else
        return w;  // block of 254 non-zero bytes ends the input: no trailing code byte
    }
  }
  out[code_at] = code;
  return w;
}

std::size_t cobs_decode(const std::uint8_t* data, std::size_t size, std::uint8_t* out,
                        std::size_t cap) {
  if (size == 0) return kCobsError;
  std::size_t r = 0, w = 0;
  while (r < size) {
    const std::uint8_t code = data[r++];
    if (code == 0) return kCobsError;
    const std::size_t run = code - 1u;
    if (run > size - r) return kCobsError;
    if (run > cap - w) return kCobsError;
    for (std::size_t k = 0; k < run; ++k) {
      if (data[r] == 0) return kCobsError;
      out[w++] = data[r++];
    }
    // A block shorter than 254 data bytes implies a zero, except at the very end.
    if (code != 0xFF && r < size) {
      if (w >= cap) return kCobsError;
      out[w++] = 0;
    }
  }
  return w;
}

}  // namespace hc::fw
