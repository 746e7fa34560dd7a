#pragma once
// The criterion's per-cluster block kernel (see criterion_model.hpp and README.md), included by
// block_kernel.cpp only. Internal linkage, so a future second build of it (say with -mavx2 in another
// translation unit) cannot leak into the baseline one through the linker.
#include <cstddef>
#include <cstdint>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/depth_buffer.hpp"
#include "core/criterion/fast_math.hpp"

namespace vantage {
namespace {

// The kernel body, one lane per primitive of the cluster at `base`. Divisions, logs and roots run on
// every lane, unmasked: a lane behind the camera or facing away computes garbage that the masks drop.
// block_kernel.cpp is compiled with -fno-trapping-math and -fno-math-errno (core/CMakeLists.txt): otherwise
// GCC will not speculate them and leaves the loop scalar. Comparisons combine with &, not &&, for the same
// reason, and per-view constants are locals (a conditional load from a struct makes GCC branch).
// Inputs and the output as restrict parameters: GCC honours restrict on parameters (also after
// inlining), not on local pointers, and without it gives up on the alias checks.
inline void block_kernel_lanes(const float* __restrict px, const float* __restrict py, const float* __restrict pz,
                               const float* __restrict nx, const float* __restrict ny, const float* __restrict nz,
                               const float* __restrict s00, const float* __restrict s01,
                               const float* __restrict s02, const float* __restrict s11,
                               const float* __restrict s12, const float* __restrict s22,
                               const float* __restrict lwa, const float* __restrict hh, const float* __restrict rr,
                               const BlockConstants& kc, BlockOutput* __restrict out_ptr) {
  BlockOutput& out = *out_ptr;
  const float r00 = kc.r00, r01 = kc.r01, r02 = kc.r02;
  const float r10 = kc.r10, r11 = kc.r11, r12 = kc.r12;
  const float r20 = kc.r20, r21 = kc.r21, r22 = kc.r22;
  const float cam_x = kc.cam_x, cam_y = kc.cam_y, cam_z = kc.cam_z;
  const float fx = kc.fx, fy = kc.fy, cx = kc.cx, cy = kc.cy;
  const float inv_fx = kc.inv_fx, inv_fy = kc.inv_fy, f_max = kc.f_max;
  const float u_max = kc.u_max, v_max = kc.v_max, u_clamp = kc.u_clamp, v_clamp = kc.v_clamp;
  const std::int32_t width = kc.width;
  const std::int32_t spare = kc.spare;
  const float grazing2 = kGrazingCosine * kGrazingCosine;
  const float tolerance_radii = kc.tolerance_radii;
  const float log2_fxfy = kc.log2_fxfy;
  for (std::size_t i = 0; i < kClusterSize; ++i) {
    const float ux = px[i] - cam_x;
    const float uy = py[i] - cam_y;
    const float uz = pz[i] - cam_z;
    const float xc = r00 * ux + r01 * uy + r02 * uz;
    const float yc = r10 * ux + r11 * uy + r12 * uz;
    const float zc = r20 * ux + r21 * uy + r22 * uz;
    const float facing = -(nx[i] * ux + ny[i] * uy + nz[i] * uz);  // n . (camera - X)
    const float ncx = r00 * nx[i] + r01 * ny[i] + r02 * nz[i];
    const float ncy = r10 * nx[i] + r11 * ny[i] + r12 * nz[i];
    const float dist2 = ux * ux + uy * uy + uz * uz;
    const bool front = (zc > kNearDepth) & (facing > 0.0f);
    const float inv_z = 1.0f / zc;
    const float u = fx * xc * inv_z + cx;
    const float v = fy * yc * inv_z + cy;
    // 1/z gradients of the disc's plane n_cam . X = k with k = -facing (see splat_math).
    const bool grazing = facing * facing < grazing2 * dist2;
    const float minus_inv_facing = -1.0f / facing;
    const float inv_k = grazing ? 0.0f : minus_inv_facing;
    const float du = ncx * inv_k * inv_fx;
    const float dv = ncy * inv_k * inv_fy;
    const float radius = rr[i];
    const float radius_px = radius * f_max * inv_z;
    const bool in_image = (u >= -0.5f) & (v >= -0.5f) & (u < u_max) & (v < v_max);
    float uc = u > -1.0f ? u : -1.0f;
    uc = uc < u_clamp ? uc : u_clamp;
    float vc = v > -1.0f ? v : -1.0f;
    vc = vc < v_clamp ? vc : v_clamp;
    const std::int32_t pi = static_cast<std::int32_t>(uc + 0.5f);
    const std::int32_t pj = static_cast<std::int32_t>(vc + 0.5f);
    const std::int32_t pixel = pj * width + pi;
    const float iz_pixel = inv_z + du * (static_cast<float>(pi) - u) + dv * (static_cast<float>(pj) - v);
    // splat_math::visibility_threshold, inlined: one division, and the select on its sign happens in
    // the append loop (<= 0 means the tolerance reaches the camera: always visible).
    const float threshold = iz_pixel / (1.0f - kRelativeDepthTolerance - tolerance_radii * radius * iz_pixel);
    // f = |Sigma v|: with Sigma' = Sigma / scale, f' = |Sigma' u| / |u|, u = X - x (never negative in
    // float, unlike a stored Sigma^2).
    const float su_x = s00[i] * ux + s01[i] * uy + s02[i] * uz;
    const float su_y = s01[i] * ux + s11[i] * uy + s12[i] * uz;
    const float su_z = s02[i] * ux + s12[i] * uy + s22[i] * uz;
    const float qu = su_x * su_x + su_y * su_y + su_z * su_z;
    // w C = 2^(log2(w' (pi r^2)^h) + h log2(fx fy facing / z^3)) * |u| / |Sigma' u|.
    const float log2_g_rest = fast::log2(facing * inv_z * inv_z * inv_z);
    const float weight = fast::exp2(lwa[i] + hh[i] * (log2_fxfy + log2_g_rest)) * __builtin_sqrtf(dist2 / qu);
    const bool member = front & in_image;
    const bool fast_splat = member & (radius_px < 0.5f);
    out.u[i] = u;
    out.v[i] = v;
    out.iz[i] = inv_z;
    out.du[i] = du;
    out.dv[i] = dv;
    out.rpx[i] = radius_px;
    out.iz_pixel[i] = iz_pixel;
    out.threshold[i] = threshold;
    out.contribution[i] = weight;  // raw: masked in the scalar loop (a select here makes GCC branch)
    out.has_area[i] = radius > 0.0f ? 1 : 0;
    out.pixel[i] = pixel;
    out.write_pixel[i] = fast_splat ? pixel : spare;
    // Larger or off-centre footprints go to the general splat, unless the square misses the image.
    const bool overlaps = (u + radius_px >= -0.5f) & (v + radius_px >= -0.5f) & (u - radius_px < u_max) &
                          (v - radius_px < v_max);
    out.general[i] = (front & overlaps & !fast_splat) ? 1 : 0;
    out.member[i] = member ? 1 : 0;
  }
}

inline void block_kernel_body(const CriterionArrays& a, std::size_t base, const BlockConstants& kc,
                              BlockOutput& out) {
  block_kernel_lanes(a.x + base, a.y + base, a.z + base, a.nx + base, a.ny + base, a.nz + base, a.s00 + base,
                     a.s01 + base, a.s02 + base, a.s11 + base, a.s12 + base, a.s22 + base, a.log2_wa + base,
                     a.h + base, a.radius + base, kc, &out);
}

}  // namespace
}  // namespace vantage
