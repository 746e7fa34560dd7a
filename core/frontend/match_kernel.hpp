#pragma once
// The matcher's inner loops, internal to core/frontend (see EXPERIMENTS.md, "Speed"): the box NCC, the
// photometric subpixel fit and the photometric normal's pass over its patch. Written once (match_kernel_impl.hpp) with GCC/Clang vector extensions and
// built twice, as core/criterion does: for the baseline ISA (match_kernel.cpp: SSE2 on x86-64, NEON on
// aarch64) and, on x86-64 only, with AVX2 + FMA (match_kernel_avx2.cpp), chosen at run time. This header
// is self-contained on purpose (plain pointers and numbers, no Eigen, no inline functions): the AVX2
// translation unit must not instantiate any inline function that baseline code also uses, or the linker
// could hand the AVX2 copy to a baseline caller.
#include <cstdint>

namespace vantage {

// Which build of the matcher's inner loops runs (ncc_box, refine_subpixel, search_window): kAuto picks
// AVX2 + FMA when the CPU has both, else the baseline. The builds agree up to float rounding.
enum class MatchKernel : std::uint8_t {
  kAuto = 0,
  kBaseline,  // SSE2 on x86-64, NEON on aarch64
  kAvx2Fma,   // x86-64 with AVX2 and FMA only
};

const char* to_string(MatchKernel kernel);
// True for kAuto and kBaseline; for kAvx2Fma when this build and this CPU have it.
bool match_kernel_supported(MatchKernel kernel);

namespace match_kernel {

inline constexpr int kSize = 7;  // the patch side (kPatchSize, checked in ncc.cpp)
inline constexpr int kPixels = kSize * kSize;

struct Image {
  const std::uint8_t* pixels;
  std::int32_t width_px;
  std::int32_t height_px;
  std::int32_t stride_bytes;
};

// A zero-mean template (values 0 where masked, mask 0 or 1), kPixels each, row-major.
struct Template {
  const float* values;
  const float* mask;
  float norm;                // sqrt(sum values^2), > 0
  std::int32_t valid_count;  // >= 2
};

// NCC box: centres [x0, x0 + w) x [y0, y0 + h), every centre's patch inside the image; plane_stride and
// out_stride as ncc_box_plane_stride(w) and ncc_box_out_stride(w) (ncc.hpp); scratch holds
// ncc_box_scratch_size(w, h) floats.
struct Box {
  std::int32_t x0;
  std::int32_t y0;
  std::int32_t w;
  std::int32_t h;
  std::int32_t plane_stride;
  std::int32_t out_stride;
};

// Photometric fit around integer peak (x, y) (block of +-3 px of margin inside the image, valid_count
// >= 8): in, dx and dy the start offset from (x, y); out, the converged offset and the shift covariance,
// and ncc: the NCC of the template with the resampled image at the last step's linearization point (from
// the fit's own sums, no extra pass: with r = I - alpha t - beta the centred sums of t I and I I follow
// from those of t t, t r and r r).
struct Fit {
  double dx;
  double dy;
  double cov_xx;
  double cov_xy;
  double cov_yy;
  double ncc;
  double last_step_px;  // out: the length of the last step taken (below stop_step_px when it converged)
};

using NccBoxFunction = void (*)(const Image& image, const Template& tmpl, const Box& box, float* scratch, float* out);
// Gauss-Newton steps up to `iterations`, stopping after a step shorter than stop_step_px. False when it
// does not converge within one pixel of (x, y), the normal equations are singular or the result is not finite.
using FitFunction = bool (*)(const Image& image, const Template& tmpl, std::int32_t x, std::int32_t y, int iterations,
                             double stop_step_px, Fit* fit);

// One Gauss-Newton pass of the photometric normal (photometric_normal.cpp): reference pixel y of the
// centred 7x7 grid lands at p = u + M y in the image; r = I(p) - gain T(y) - offset and
// J = [g, g . dM0 y, g . dM1 y, -T(y), -1], I bilinear and g its central differences one pixel apart.
// Sums in float lanes (the pixels, template values and products of a 7x7 patch), returned in double.
struct PhotometricPass {
  // In: 2x2 matrices row-major.
  double u_x;
  double u_y;
  double M[4];
  double dM0[4];
  double dM1[4];
  double gain;
  double offset;
  // Out: J^T J (symmetric), J^T r, sum r^2, and per pixel (row ty, column tx < 7) gx, gy, the two tilt
  // columns and r for the residual correlation model.
  double JtJ[6][6];
  double Jtr[6];
  double sum_r2;
  float rows[5][kSize][8];
};

// False when a pixel's bilinear cell and its ring leave the image (p outside [1, w - 2) x [1, h - 2))
// or an input is not finite; *pass's outputs are then unspecified.
using PhotometricFunction = bool (*)(const Image& image, const std::uint8_t* patch, PhotometricPass* pass);

struct Functions {
  NccBoxFunction ncc_box;
  FitFunction refine;
  PhotometricFunction photometric;
};

// The functions of a kernel (kAuto resolved, an unsupported one falls back to the baseline); ncc.cpp.
Functions functions(MatchKernel kernel);

namespace baseline {
void ncc_box(const Image& image, const Template& tmpl, const Box& box, float* scratch, float* out);
bool refine(const Image& image, const Template& tmpl, std::int32_t x, std::int32_t y, int iterations,
            double stop_step_px, Fit* fit);
bool photometric(const Image& image, const std::uint8_t* patch, PhotometricPass* pass);
}  // namespace baseline

#if defined(__x86_64__)
#define VANTAGE_MATCH_HAS_AVX2_KERNEL 1
namespace avx2_fma {
void ncc_box(const Image& image, const Template& tmpl, const Box& box, float* scratch, float* out);
bool refine(const Image& image, const Template& tmpl, std::int32_t x, std::int32_t y, int iterations,
            double stop_step_px, Fit* fit);
bool photometric(const Image& image, const std::uint8_t* patch, PhotometricPass* pass);
}  // namespace avx2_fma
#else
#define VANTAGE_MATCH_HAS_AVX2_KERNEL 0
#endif

}  // namespace match_kernel
}  // namespace vantage
