#include "mtcal/drivers/crc.h"

#include <array>

namespace mtcal::drivers {
namespace {

// Byte-wise table of the polynomial 0x1021 (MSB first): one lookup per byte instead of
// eight shift/xor steps; the CRC ran on every frame at both ends and dominated profiles.
constexpr std::array<std::uint16_t, 256> makeTable() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned byte = 0; byte < 256; ++byte) {
    auto crc = static_cast<std::uint16_t>(byte << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021) : static_cast<std::uint16_t>(crc << 1);
    }
    table[byte] = crc;
  }
  return table;
}
constexpr auto kTable = makeTable();

}  // namespace

std::uint16_t crc16Ccitt(std::span<const std::uint8_t> data, std::uint16_t crc) {
  for (std::uint8_t byte : data) {
    crc = static_cast<std::uint16_t>((crc << 8) ^ kTable[static_cast<std::uint8_t>((crc >> 8) ^ byte)]);
  }
  return crc;
}

}  // namespace mtcal::drivers
