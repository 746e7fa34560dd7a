#pragma once
// Normalized cross-correlation (NCC) of p x p patches (p = kPatchSize) and the parabola fit that
// refines an integer NCC peak to subpixel. A template is zero-mean with a validity mask, so a warped
// reference patch whose corners fall outside the stored patch still correlates on the pixels it has.
#include <array>
#include <cstddef>
#include <cstdint>

#include "core/common/span.hpp"
#include "core/frontend/match_kernel.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive.hpp"

namespace vantage {

inline constexpr int kPatchRadius = kPatchSize / 2;
inline constexpr int kPatchPixels = kPatchSize * kPatchSize;

struct NccTemplate {
  std::array<float, kPatchPixels> values{};  // zero mean over the valid pixels, 0 where masked
  std::array<float, kPatchPixels> mask{};    // 1 for a valid pixel, 0 for a masked one
  float norm = 0.0f;                         // sqrt(sum values^2)
  float stddev_gray = 0.0f;                  // standard deviation of the valid pixels, gray levels
  int valid_count = 0;
};

// Template from a stored p x p patch (row-major). All pixels valid.
void make_template(const std::array<std::uint8_t, kPatchPixels>& patch, NccTemplate* out);
// Template from gray values in [0, 255] and a mask (1 valid, 0 masked), row-major p x p.
void make_template(const std::array<float, kPatchPixels>& gray, const std::array<float, kPatchPixels>& mask,
                   NccTemplate* out);

// Copies the p x p patch centred on integer pixel (cx, cy). The caller guarantees it lies inside.
void extract_patch(const GrayImageView& image, std::int32_t cx, std::int32_t cy,
                   std::array<std::uint8_t, kPatchPixels>* out);

// True when the p x p patch centred on (cx, cy) lies inside the image with `margin_px` more on each side.
bool patch_inside(const GrayImageView& image, std::int32_t cx, std::int32_t cy, std::int32_t margin_px = 0);

// NCC in [-1, 1] of the template against the image patch centred on integer pixel (cx, cy); the caller
// guarantees the patch lies inside. A flat image patch (or flat template) correlates at -1: it can
// never be a match.
float ncc_at(const GrayImageView& image, std::int32_t cx, std::int32_t cy, const NccTemplate& tmpl);

// Row stride of ncc_box's float copy of the pixels under a box w centres wide: the region (w + p - 1)
// rounded up to whole 16-pixel conversion chunks, and at least the 8-lane groups of centres plus p - 1.
constexpr std::int32_t ncc_box_plane_stride(std::int32_t w) {
  const std::int32_t lanes_w = (w + 7) / 8 * 8 + kPatchSize - 1;
  const std::int32_t region_w = (w + kPatchSize - 1 + 15) / 16 * 16;
  return lanes_w > region_w ? (lanes_w + 15) / 16 * 16 : region_w;
}

// Floats of scratch space ncc_box needs for a box of w x h centres: the float copy of the pixels and
// its row sums of I and I^2.
constexpr std::size_t ncc_box_scratch_size(std::int32_t w, std::int32_t h) {
  const std::size_t padded_w = static_cast<std::size_t>((w + 7) / 8 * 8);
  return static_cast<std::size_t>(h + kPatchSize - 1) * (static_cast<std::size_t>(ncc_box_plane_stride(w)) + 2 * padded_w);
}

// Row stride of ncc_box's output: whole groups of 8 centres.
constexpr std::int32_t ncc_box_out_stride(std::int32_t w) { return (w + 7) / 8 * 8; }

// NCC at every centre of the box [x0, x0 + w) x [y0, y0 + h): out[y * ncc_box_out_stride(w) + x] for
// y < h, x < w (the lanes past w are written and hold nothing meaningful), the same value as ncc_at at
// each centre up to float rounding. The window search's dense form: the pixels are converted once, the
// sums of I and I^2 are box sums, eight centres share each template multiply. The caller guarantees
// every centre's patch lies inside the image. False, out untouched, when w or h is not positive or
// scratch is smaller than ncc_box_scratch_size(w, h).
bool ncc_box(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x0, std::int32_t y0, std::int32_t w,
             std::int32_t h, Span<float> scratch, float* out);
// The same with a chosen build of the inner loops (match_kernel.hpp); false, out untouched, also when the
// kernel is not supported here (match_kernel_supported).
bool ncc_box(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x0, std::int32_t y0, std::int32_t w,
             std::int32_t h, Span<float> scratch, float* out, MatchKernel kernel);

// Offset in [-0.5, 0.5] of the vertex of the parabola through (-1, left), (0, centre), (1, right);
// 0 when the three points are not a strict maximum at the centre.
double parabola_peak_offset(double left, double centre, double right);

}  // namespace vantage
