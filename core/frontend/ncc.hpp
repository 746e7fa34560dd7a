#pragma once
// Normalized cross-correlation (NCC) of p x p patches (p = kPatchSize) and the parabola fit that
// refines an integer NCC peak to subpixel. A template is zero-mean with a validity mask, so a warped
// reference patch whose corners fall outside the stored patch still correlates on the pixels it has.
#include <array>
#include <cstdint>

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

// Offset in [-0.5, 0.5] of the vertex of the parabola through (-1, left), (0, centre), (1, right);
// 0 when the three points are not a strict maximum at the centre.
double parabola_peak_offset(double left, double centre, double right);

}  // namespace vantage
