#pragma once
// Four-lane float vectors for the template statistics (ncc.cpp; the matcher's inner loops have their own
// vectors, match_kernel_impl.hpp) (GCC/Clang vector extensions). They lower to
// SSE2 on the x86-64 baseline and to NEON on aarch64: no target-specific intrinsics, no -march flags.
// Float sums are not vectorized by the compiler without -ffast-math (it may not reorder them), so the
// hot loops spell out their lanes with this type instead.
#include <cstring>

namespace vantage {

using Float4 = float __attribute__((vector_size(16)));

inline Float4 splat4(float value) { return Float4{value, value, value, value}; }

// Unaligned load and store (memcpy compiles to one movups / ldr q).
inline Float4 load4(const float* p) {
  Float4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

inline void store4(float* p, Float4 v) { std::memcpy(p, &v, sizeof v); }

inline float sum_lanes(Float4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }

}  // namespace vantage
