#include "sim_hal/shading.hpp"

#include <algorithm>
#include <cmath>

namespace vantage::sim {

namespace {

constexpr std::uint32_t kTableBits = 16;
constexpr std::uint32_t kTableMask = (1u << kTableBits) - 1u;

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

inline float smooth(float t) { return t * t * (3.0f - 2.0f * t); }

}  // namespace

SolidTexture::SolidTexture(const AlbedoConfig& config)
    : config_(config), inv_feature_size_(static_cast<float>(1.0 / config.texture_feature_size)), table_(1u << kTableBits) {
  for (std::uint32_t i = 0; i < table_.size(); ++i) {
    const std::uint64_t h = splitmix64(0xA1B2C3D4ull + i);
    table_[i] = static_cast<float>(static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0)) * 2.0f - 1.0f;
  }
}

float SolidTexture::noise(float x, float y, float z) const {
  const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const float tx = smooth(x - fx), ty = smooth(y - fy), tz = smooth(z - fz);
  const std::uint32_t ix = static_cast<std::uint32_t>(static_cast<std::int32_t>(fx));
  const std::uint32_t iy = static_cast<std::uint32_t>(static_cast<std::int32_t>(fy));
  const std::uint32_t iz = static_cast<std::uint32_t>(static_cast<std::int32_t>(fz));
  const std::uint32_t hx0 = ix * 73856093u, hx1 = hx0 + 73856093u;
  const std::uint32_t hy0 = iy * 19349663u, hy1 = hy0 + 19349663u;
  const std::uint32_t hz0 = iz * 83492791u, hz1 = hz0 + 83492791u;
  auto at = [this](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    std::uint32_t h = a ^ b ^ c;
    h ^= h >> 15;
    h *= 0x2C1B3C6Du;
    h ^= h >> 12;
    return table_[h & kTableMask];
  };
  const float c000 = at(hx0, hy0, hz0), c100 = at(hx1, hy0, hz0);
  const float c010 = at(hx0, hy1, hz0), c110 = at(hx1, hy1, hz0);
  const float c001 = at(hx0, hy0, hz1), c101 = at(hx1, hy0, hz1);
  const float c011 = at(hx0, hy1, hz1), c111 = at(hx1, hy1, hz1);
  const float x00 = c000 + tx * (c100 - c000), x10 = c010 + tx * (c110 - c010);
  const float x01 = c001 + tx * (c101 - c001), x11 = c011 + tx * (c111 - c011);
  const float y0 = x00 + ty * (x10 - x00), y1 = x01 + ty * (x11 - x01);
  return y0 + tz * (y1 - y0);
}

float SolidTexture::albedo(float x, float y, float z) const {
  const float constant = static_cast<float>(config_.constant);
  if (config_.mode == AlbedoMode::kConstant) return constant;
  const float s = inv_feature_size_;
  // Fine octave dominates (patch-scale texture for matching); the coarse one breaks up repetition.
  const float n = noise(x * s, y * s, z * s);
  // Value noise rarely reaches +-1; stretch it so the contrast setting means roughly what it says.
  const float a = constant + static_cast<float>(config_.texture_contrast) * std::clamp(1.5f * n, -1.0f, 1.0f);
  return std::clamp(a, 0.0f, 1.0f);
}

float hashed_gaussian(std::uint32_t seed, std::uint64_t stream, std::uint64_t index) {
  const std::uint64_t h = splitmix64(splitmix64(splitmix64(seed) ^ stream) ^ index);
  // Box-Muller on two 32-bit uniforms; u1 in (0, 1] so the log is finite.
  const double u1 = (static_cast<double>(h >> 32) + 1.0) * (1.0 / 4294967296.0);
  const double u2 = static_cast<double>(h & 0xFFFFFFFFull) * (1.0 / 4294967296.0);
  return static_cast<float>(std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2));
}

}  // namespace vantage::sim
