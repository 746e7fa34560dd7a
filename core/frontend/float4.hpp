#pragma once
// Four-lane float vectors (GCC/Clang vector extensions) for the front end's small loops: template
// statistics, template warps (the matcher's inner loops have their own, match_kernel_impl.hpp). They
// lower to SSE2 on the x86-64 baseline and to NEON on aarch64: no target-specific intrinsics, no -march
// flags.
// Float sums are not vectorized by the compiler without -ffast-math (it may not reorder them), so the
// hot loops spell out their lanes with this type instead.
#include <cstdint>
#include <cstring>

namespace vantage {

using Float4 = float __attribute__((vector_size(16)));
using Int4 = std::int32_t __attribute__((vector_size(16)));  // comparison results and pixel offsets

inline Float4 splat4(float value) { return Float4{value, value, value, value}; }

// Unaligned load and store (memcpy compiles to one movups / ldr q).
inline Float4 load4(const float* p) {
  Float4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

inline void store4(float* p, Float4 v) { std::memcpy(p, &v, sizeof v); }

inline float sum_lanes(Float4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }

// dst[i] = src[i] for i < 16: a fixed-size conversion the compiler vectorizes (widen, convert).
inline void bytes_to_floats16(const std::uint8_t* src, float* dst) {
  std::uint8_t chunk[16];
  std::memcpy(chunk, src, sizeof chunk);
  for (int k = 0; k < 16; ++k) dst[k] = static_cast<float>(chunk[k]);
}

// dst[i] = src[i] for i < n, for i < dst_n (a multiple of 16) whole 16-byte chunks: those past n hold
// further readable bytes of src when at least 16 remain in the `readable` bytes from src, else zeros.
// Either way every dst value is finite.
inline void bytes_to_floats(const std::uint8_t* src, std::int32_t n, std::int32_t readable, float* dst,
                            std::int32_t dst_n) {
  for (std::int32_t i = 0; i < dst_n; i += 16) {
    if (i + 16 <= readable) {
      bytes_to_floats16(src + i, dst + i);
      continue;
    }
    std::uint8_t chunk[16] = {};
    if (i < n) std::memcpy(chunk, src + i, static_cast<std::size_t>(n - i < 16 ? n - i : 16));
    bytes_to_floats16(chunk, dst + i);
  }
}

}  // namespace vantage
