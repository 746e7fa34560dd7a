#pragma once
// The general (multi-pixel or partly outside) disc splat, shared by DepthBufferView and the criterion's
// kernels (block_kernel_impl.hpp). Internal linkage and always inlined: the kernel is also built with
// -mavx2, and no copy of it may reach baseline callers through the linker.
#include <cstdint>

namespace vantage::splat_kernel {
namespace {

// Writes 1/z of the disc's plane (centre (u, v) at iz_centre, gradients du, dv per buffer pixel) at the
// pixel centres within [u - r, u + r] x [v - r, v + r], plus the centre pixel, clipped to the image,
// keeping the larger value. Bounds are clamped to [-2, size + 1] before the integer conversions (no
// overflow for huge discs); nothing is written for a negative or NaN radius or a non-finite centre.
inline __attribute__((always_inline)) void splat_general(float* data, std::int32_t width, std::int32_t height, float u,
                                                          float v, float iz_centre, float du, float dv, float radius_px) {
  if (!(radius_px >= 0.0f) || !(u - u == 0.0f) || !(v - v == 0.0f)) return;  // x - x != 0 for Inf and NaN
  auto clamp = [](float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); };
  auto floor_int = [](float x) {
    const std::int32_t t = static_cast<std::int32_t>(x);
    return static_cast<float>(t) > x ? t - 1 : t;
  };
  const float w = static_cast<float>(width);
  const float h = static_cast<float>(height);
  const std::int32_t centre_u = floor_int(clamp(u + 0.5f, -2.0f, w + 1.0f));
  const std::int32_t centre_v = floor_int(clamp(v + 0.5f, -2.0f, h + 1.0f));
  std::int32_t i0 = -floor_int(-clamp(u - radius_px, -2.0f, w + 1.0f));  // ceil
  std::int32_t j0 = -floor_int(-clamp(v - radius_px, -2.0f, h + 1.0f));
  std::int32_t i1 = floor_int(clamp(u + radius_px, -2.0f, w + 1.0f));
  std::int32_t j1 = floor_int(clamp(v + radius_px, -2.0f, h + 1.0f));
  i0 = i0 < centre_u ? i0 : centre_u;
  j0 = j0 < centre_v ? j0 : centre_v;
  i1 = i1 > centre_u ? i1 : centre_u;
  j1 = j1 > centre_v ? j1 : centre_v;
  i0 = i0 > 0 ? i0 : 0;
  j0 = j0 > 0 ? j0 : 0;
  i1 = i1 < width - 1 ? i1 : width - 1;
  j1 = j1 < height - 1 ? j1 : height - 1;
  if (i0 > i1 || j0 > j1) return;
  for (std::int32_t j = j0; j <= j1; ++j) {
    const float row = iz_centre + dv * (static_cast<float>(j) - v);
    float* line = data + j * width;
    for (std::int32_t i = i0; i <= i1; ++i) {
      const float iz = row + du * (static_cast<float>(i) - u);
      line[i] = iz > line[i] ? iz : line[i];
    }
  }
}

}  // namespace
}  // namespace vantage::splat_kernel
