#pragma once
// CRC-16/MCRF4XX (MAVLink's "X.25" checksum): poly 0x1021 reflected, init 0xFFFF, no final xor.
#include <cstddef>
#include <cstdint>

namespace vantage::hal::mavlink {

constexpr std::uint16_t kCrcInit = 0xFFFF;

inline std::uint16_t crc16_accumulate(std::uint8_t byte, std::uint16_t crc) {
  std::uint8_t tmp = static_cast<std::uint8_t>(byte ^ static_cast<std::uint8_t>(crc & 0xFF));
  tmp = static_cast<std::uint8_t>(tmp ^ static_cast<std::uint8_t>(tmp << 4));
  return static_cast<std::uint16_t>((crc >> 8) ^ (static_cast<std::uint16_t>(tmp) << 8) ^
                                    (static_cast<std::uint16_t>(tmp) << 3) ^ (tmp >> 4));
}

inline std::uint16_t crc16(const std::uint8_t* data, std::size_t length, std::uint16_t crc = kCrcInit) {
  for (std::size_t i = 0; i < length; ++i) crc = crc16_accumulate(data[i], crc);
  return crc;
}

}  // namespace vantage::hal::mavlink
