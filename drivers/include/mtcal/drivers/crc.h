#pragma once
#include <cstdint>
#include <span>

namespace mtcal::drivers {
/// CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR.
/// Check value: crc16Ccitt("123456789") == 0x29B1.
std::uint16_t crc16Ccitt(std::span<const std::uint8_t> data, std::uint16_t crc = 0xFFFF);
}  // namespace mtcal::drivers
