// CRC-32C (Castagnoli): the checksum of every firmware frame. Freestanding (no heap, no OS), so the
// microcontroller core and the host driver share it.
//
// Parameters (Rocksoft model, "CRC-32/ISCSI" in the CRC RevEng catalogue): width 32, polynomial
// 0x1EDC6F41 (reflected 0x82F63B78), init 0xFFFFFFFF, refin/refout true, xorout 0xFFFFFFFF;
// check value over the ASCII bytes "123456789" is 0xE3069283.
// Why CRC-32C and not CRC-16/CCITT: for frames up to 64 bytes it detects every burst error up to
// 32 bits and all 1-3 bit errors (Hamming distance 4+ at these lengths), at the cost of a 1 KiB
// table in flash, which any USB-capable microcontroller has. Hand-written (not a library) because
// the core must build without any host library.
#pragma once

#include <cstddef>
#include <cstdint>

namespace hc::fw {

inline constexpr std::uint32_t kCrc32cCheckValue = 0xE3069283u;  // CRC of "123456789"

// Continues a CRC-32C over `size` bytes. Start with crc = 0 (the init/xorout are applied inside),
// so crc32c(b, n2, crc32c(a, n1)) == crc32c(a ++ b).
std::uint32_t crc32c(const std::uint8_t* data, std::size_t size, std::uint32_t crc = 0);

}  // namespace hc::fw
