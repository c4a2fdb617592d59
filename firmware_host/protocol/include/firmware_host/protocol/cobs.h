// Consistent Overhead Byte Stuffing (Cheshire & Baker, IEEE/ACM Trans. Networking 7(2), 1999):
// removes every 0x00 from a packet so 0x00 can delimit frames on the byte stream; a receiver that
// sees garbage resynchronises at the next 0x00. Overhead is at most 1 byte per 254 plus 1.
// Freestanding (no heap): written by hand because the firmware core links no library.
#pragma once

#include <cstddef>
#include <cstdint>

namespace hc::fw {

// Largest COBS encoding of `n` input bytes (without the 0x00 delimiter).
constexpr std::size_t cobs_max_encoded_size(std::size_t n) { return n + n / 254 + 1; }

// Encodes `size` bytes into `out` (capacity `cap`); no delimiter is appended. Returns the encoded
// length, or 0 when `cap` < cobs_max_encoded_size(size).
std::size_t cobs_encode(const std::uint8_t* data, std::size_t size, std::uint8_t* out,
                        std::size_t cap);

// Decodes one COBS block (without its delimiter) into `out`. Returns the decoded length, or
// SIZE_MAX when the input is not valid COBS (a 0x00 inside, a code byte pointing past the end) or
// `cap` is too small. An empty input decodes to nothing (returns SIZE_MAX: no valid block is
// empty).
std::size_t cobs_decode(const std::uint8_t* data, std::size_t size, std::uint8_t* out,
                        std::size_t cap);

inline constexpr std::size_t kCobsError = static_cast<std::size_t>(-1);

}  // namespace hc::fw
