#pragma once
// The criterion's per-view inner loops, internal to core/criterion (see README.md, "The inner loop").
// Written once (block_kernel_impl.hpp) with GCC/Clang vector extensions and built twice: for the
// baseline ISA (block_kernel.cpp: SSE2 pairs on x86-64, NEON pairs on aarch64) and, on x86-64 only, with
// AVX2 + FMA (block_kernel_avx2.cpp), chosen at run time. This header is self-contained on purpose (plain
// pointers and floats, no Eigen, no inline functions): the AVX2 translation unit must not instantiate
// any inline function that baseline code also uses, or the linker could hand the AVX2 copy to a baseline
// caller.
#include <cstddef>
#include <cstdint>

namespace vantage::criterion_kernel {

inline constexpr std::size_t kLanes = 16;  // one cluster (kClusterSize, checked in criterion_evaluate.cpp)

// A slot whose log2_wa is at or below this adds exactly 0 to F (a primitive flagged kUnconsumed): it
// still occludes, only its weight is dropped.
inline constexpr float kZeroWeightLog2 = -1.0e4f;

// The model's per-slot structure of arrays (CriterionArrays), read only.
struct Slots {
  const float* x;
  const float* y;
  const float* z;
  const float* nx;
  const float* ny;
  const float* nz;
  const float* s00;  // Sigma / scale, upper triangle
  const float* s01;
  const float* s02;
  const float* s11;
  const float* s12;
  const float* s22;
  const float* log2_wa;  // log2(det(Sigma / scale) * (pi r^2)^h)
  const float* h;
  const float* radius;
};

// The model's cluster bounds (ClusterArrays), read only, readable up to a multiple of 8 clusters.
struct Bounds {
  const float* centre_x;
  const float* centre_y;
  const float* centre_z;
  const float* radius;
  const float* axis_x;
  const float* axis_y;
  const float* axis_z;
  const float* sin_half_angle;
  const float* cos_half_angle;
};

// Per-view constants.
struct ViewConstants {
  float r00, r01, r02, r10, r11, r12, r20, r21, r22;  // R_cam_world
  float cam_x, cam_y, cam_z;                           // camera centre, world
  float fx, fy, cx, cy, inv_fx, inv_fy, f_max;         // the depth buffer's pinhole
  float u_max, v_max, u_clamp, v_clamp;                // image bounds, buffer pixels
  std::int32_t width, height;                          // buffer size, pixels
  std::int32_t spare;                                  // the buffer's spare cell (masked writes)
  float tolerance_radii;
  float relative_tolerance;  // kRelativeDepthTolerance
  float near_depth;          // kNearDepth
  float grazing_cosine2;     // kGrazingCosine^2
  float log2_fxfy;           // log2(fx fy) of the camera, for g in its pixels
  // Side planes of the buffer's frustum, inward unit normals through the camera centre (camera frame):
  // left (left_x, 0, left_z), right (right_x, 0, right_z), top (0, top_y, top_z), bottom (0, bottom_y, bottom_z).
  float left_x, left_z, right_x, right_z, top_y, top_z, bottom_y, bottom_z;
};

// Where a view renders: the depth buffer (width * height + 1 spare cell) and one entry per lane of every
// kept cluster (entry k * kLanes + i for lane i of clusters[k]).
struct Target {
  float* depth;
  std::int32_t* pixel;  // the lane's centre pixel; the spare cell for lanes that cannot be visible
  float* threshold;     // visible when depth[pixel] <= threshold; -1 for lanes that cannot be visible
};

// Writes into kept (ascending) the clusters [0, count) that may hold a primitive front-facing and in the
// frustum: not behind the camera or outside a side plane (bounding sphere), and not facing away (normal
// cone: angle(axis, camera - centre) > 90 deg + alpha + asin(r / d)). Returns how many.
using CullFunction = std::size_t (*)(const Bounds& bounds, const ViewConstants& view, std::size_t count,
                                     std::uint32_t* kept);
// Splats the front-facing primitives of the clusters (slot base clusters[k] * kLanes) into target.depth,
// drops from `clusters` (in place, order kept) those without a candidate (front-facing, centre in the
// image) and fills the entries of the rest: entry n * kLanes + i for lane i of the n-th remaining
// cluster. Returns how many clusters remain; *candidates = the number of candidates.
using RenderFunction = std::size_t (*)(const Slots& slots, const ViewConstants& view, std::uint32_t* clusters,
                                       std::size_t count, const Target& target, std::size_t* candidates);
// After render: sum of w' g^h / f' over the visible lanes of positive radius (scaled units, F / scale^2).
using SumFunction = double (*)(const Slots& slots, const ViewConstants& view, const std::uint32_t* clusters,
                               std::size_t count, const Target& target);

struct Functions {
  CullFunction cull;
  RenderFunction render;
  SumFunction sum_visible;
};

namespace baseline {
std::size_t cull(const Bounds& bounds, const ViewConstants& view, std::size_t count, std::uint32_t* kept);
std::size_t render(const Slots& slots, const ViewConstants& view, std::uint32_t* clusters, std::size_t count,
                   const Target& target, std::size_t* candidates);
double sum_visible(const Slots& slots, const ViewConstants& view, const std::uint32_t* clusters, std::size_t count,
                   const Target& target);
}  // namespace baseline

#if defined(__x86_64__)
#define VANTAGE_CRITERION_HAS_AVX2_KERNEL 1
namespace avx2_fma {
std::size_t cull(const Bounds& bounds, const ViewConstants& view, std::size_t count, std::uint32_t* kept);
std::size_t render(const Slots& slots, const ViewConstants& view, std::uint32_t* clusters, std::size_t count,
                   const Target& target, std::size_t* candidates);
double sum_visible(const Slots& slots, const ViewConstants& view, const std::uint32_t* clusters, std::size_t count,
                   const Target& target);
}  // namespace avx2_fma
#else
#define VANTAGE_CRITERION_HAS_AVX2_KERNEL 0
#endif

}  // namespace vantage::criterion_kernel
