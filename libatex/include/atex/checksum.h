// CRC32C (Castagnoli), the checksum of the .atex container (format_spec/atex.md §1).
//
// Polynomial 0x1EDC6F41 (reflected 0x82F63B78), initial value and final XOR
// 0xFFFFFFFF: the iSCSI / ext4 variant. Crc32c("123456789") == 0xE3069283.
// Uses the SSE4.2 crc32 instruction when the CPU has it, a table otherwise; both
// give the same values.
#pragma once

#include <cstddef>
#include <cstdint>

namespace atex {

// CRC32C of `size` bytes at `data` (data may be null when size is 0).
uint32_t Crc32c(const void* data, size_t size);

// Continues a CRC: Crc32cExtend(Crc32c(a), b) == Crc32c(a ++ b), and
// Crc32cExtend(0, x) == Crc32c(x).
uint32_t Crc32cExtend(uint32_t crc, const void* data, size_t size);

}  // namespace atex
