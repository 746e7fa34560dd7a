#pragma once
// Branch-free float log2/exp2 for the criterion's inner loops: plain arithmetic on the IEEE-754 bits, so
// the compiler vectorizes them (std::pow does not vectorize without -ffast-math). Relative error of
// fast_pow below 2e-5 over the range the criterion uses (tests/core/criterion_fast_math_test.cpp).
#include <cstdint>
#include <cstring>

namespace vantage::fast {

inline std::uint32_t bits_of(float x) {
  std::uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

inline float float_of(std::uint32_t b) {
  float x;
  std::memcpy(&x, &b, sizeof x);
  return x;
}

// log2(x) for finite x > 0 (normal numbers). Mantissa m in [1, 2) mapped to t = (m - 1) / (m + 1), then the
// odd series of 2 atanh(t) / ln 2, which converges fast for |t| <= 1/3.
inline float log2(float x) {
  const std::uint32_t b = bits_of(x);
  const float exponent = static_cast<float>(static_cast<std::int32_t>((b >> 23) & 0xFFu) - 127);
  const float m = float_of((b & 0x007FFFFFu) | 0x3F800000u);
  const float t = (m - 1.0f) / (m + 1.0f);
  const float t2 = t * t;
  // 2/ln2 * (t + t^3/3 + t^5/5 + t^7/7 + t^9/9)
  const float series = t * (2.885390082f + t2 * (0.961796694f + t2 * (0.577078016f + t2 * (0.412198583f +
                                                                                          t2 * 0.320598898f))));
  return exponent + series;
}

// 2^y, y clamped to [-126, 127]. Integer part into the exponent bits, fraction by a degree-6 polynomial.
inline float exp2(float y) {
  y = y > -126.0f ? y : -126.0f;
  y = y < 127.0f ? y : 127.0f;
  const std::int32_t truncated = static_cast<std::int32_t>(y);
  const std::int32_t i = truncated - (static_cast<float>(truncated) > y ? 1 : 0);  // floor
  const float f = y - static_cast<float>(i);                                      // [0, 1)
  const float p =
      1.0f + f * (0.693147182f + f * (0.240226507f + f * (0.0555041087f + f * (0.00961812911f +
                                                                                f * (0.00133335581f + f * 0.000154035304f)))));
  return p * float_of(static_cast<std::uint32_t>(i + 127) << 23);
}

}  // namespace vantage::fast
