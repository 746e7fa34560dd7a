#pragma once
// The criterion's per-cluster block kernel, internal to core/criterion: declared here for
// criterion_evaluate.cpp, built in its own file (block_kernel.cpp) with the flags it needs.
#include <cstddef>
#include <cstdint>

#include "core/criterion/criterion_model.hpp"

namespace vantage {

// Per-view constants.
struct BlockConstants {
  float r00, r01, r02, r10, r11, r12, r20, r21, r22;  // R_cam_world
  float cam_x, cam_y, cam_z;                           // camera centre, world
  float fx, fy, cx, cy, inv_fx, inv_fy, f_max;         // the depth buffer's pinhole
  float u_max, v_max, u_clamp, v_clamp;                // image bounds, buffer pixels
  std::int32_t width;                                  // buffer width, pixels
  std::int32_t spare;                                  // the buffer's spare cell (masked writes)
  float tolerance_radii;
  float log2_fxfy;  // log2(fx fy) of the camera, for g in its pixels
};

// Per lane of one cluster.
struct BlockOutput {
  alignas(64) float u[kClusterSize];
  alignas(64) float v[kClusterSize];
  alignas(64) float iz[kClusterSize];
  alignas(64) float du[kClusterSize];
  alignas(64) float dv[kClusterSize];
  alignas(64) float rpx[kClusterSize];
  alignas(64) float iz_pixel[kClusterSize];
  alignas(64) float threshold[kClusterSize];
  alignas(64) float contribution[kClusterSize];  // raw weight: the caller keeps it on members only
  alignas(64) std::int32_t has_area[kClusterSize];
  alignas(64) std::int32_t pixel[kClusterSize];
  alignas(64) std::int32_t write_pixel[kClusterSize];  // the pixel of a single-pixel splat, else spare
  alignas(64) std::int32_t general[kClusterSize];      // needs the multi-pixel splat
  alignas(64) std::int32_t member[kClusterSize];       // front-facing with its centre in the image
};

// One cluster (kClusterSize lanes from slot `base`). Vectorized by GCC for the baseline ISA (SSE2 on x86-64,
// NEON on aarch64); see block_kernel_impl.hpp.
void block_kernel(const CriterionArrays& arrays, std::size_t base, const BlockConstants& constants, BlockOutput& out);

}  // namespace vantage
