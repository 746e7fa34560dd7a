#pragma once
// Branch-free float log2/exp2 for the criterion's inner loops: plain arithmetic on the IEEE-754 bits, so
// the compiler vectorizes them (std::pow does not vectorize without -ffast-math). exp2(h log2(x)) is
// within 2.5e-4 of pow(x, h) (tests/core/criterion_fast_math_test.cpp): the criterion ranks views, and
// the low degrees keep its inner loop short.
#include <cstdint>
#include <cstring>

namespace vantage::fast {

// Always inlined: should a translation unit ever include this with other ISA flags (-mavx2), no
// out-of-line copy of it can be picked by the linker for baseline callers.
#if defined(__GNUC__)
#define VANTAGE_FAST_INLINE inline __attribute__((always_inline))
#else
#define VANTAGE_FAST_INLINE inline
#endif

// The polynomials' coefficients, shared with the vector kernels (block_kernel_impl.hpp) so that every
// build computes the same values.
inline constexpr float kLog2C0 = 1.44164738f;
inline constexpr float kLog2C1 = -0.724952837f;
inline constexpr float kLog2C2 = 0.518620416f;
inline constexpr float kLog2C3 = -0.330077216f;
inline constexpr float kExp2C1 = 0.693121034f;
inline constexpr float kExp2C2 = 0.242237317f;
inline constexpr float kExp2C3 = 0.0559220356f;

VANTAGE_FAST_INLINE std::uint32_t bits_of(float x) {
  std::uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

VANTAGE_FAST_INLINE float float_of(std::uint32_t b) {
  float x;
  std::memcpy(&x, &b, sizeof x);
  return x;
}

// log2(x) for finite x > 0 (normal numbers): x = m 2^e with m reduced to [sqrt(1/2), sqrt(2)), then
// log2(m) = t p(t), t = m - 1, a degree-4 least-squares fit on Chebyshev nodes (|error| < 1.2e-4). No
// division, so it costs a few multiply-adds per lane.
VANTAGE_FAST_INLINE float log2(float x) {
  const std::uint32_t b = bits_of(x);
  float exponent = static_cast<float>(static_cast<std::int32_t>((b >> 23) & 0xFFu) - 127);
  float m = float_of((b & 0x007FFFFFu) | 0x3F800000u);  // [1, 2)
  const bool high = m > 1.41421356f;
  m = high ? 0.5f * m : m;
  exponent = high ? exponent + 1.0f : exponent;
  const float t = m - 1.0f;
  const float p = kLog2C0 + t * (kLog2C1 + t * (kLog2C2 + t * kLog2C3));
  return exponent + t * p;
}

// 2^y, y clamped to [-126, 127]: the nearest integer i into the exponent bits, the fraction f in
// [-0.5, 0.5] by 1 + f p(f), a degree-3 fit (relative error < 1.1e-4).
VANTAGE_FAST_INLINE float exp2(float y) {
  y = y > -126.0f ? y : -126.0f;
  y = y < 127.0f ? y : 127.0f;
  const float shifted = y + 0.5f;
  const std::int32_t truncated = static_cast<std::int32_t>(shifted);
  const std::int32_t i = truncated - (static_cast<float>(truncated) > shifted ? 1 : 0);  // floor(y + 0.5)
  const float f = y - static_cast<float>(i);
  const float p = 1.0f + f * (kExp2C1 + f * (kExp2C2 + f * kExp2C3));
  return p * float_of(static_cast<std::uint32_t>(i + 127) << 23);
}

}  // namespace vantage::fast
