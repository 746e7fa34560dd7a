#pragma once
// A 3x3 binomial low-pass ([1 2 1] x [1 2 1] / 16, borders replicated), 8-bit in and out.
// Why: the matcher compares point samples of one frame with bilinear resamples of another. Bilinear
// interpolation is exact only for signals without energy near the sampling frequency; a camera's (or the
// ray caster's) aliased edges and fine texture shift the subpixel fit by an amount that depends on the
// texture's phase, which the fit's residual does not show. Blurring both frames the same way removes most
// of that energy. (Measured in the simulator, the front end's matches did not get more accurate:
// core/frontend/EXPERIMENTS.md, "Pre-smoothing".)
#include "core/common/status.hpp"
#include "core/image/gray_image.hpp"

namespace vantage {

// Widest row binomial_smooth3 takes (its row buffer lives on the stack).
inline constexpr std::int32_t kBinomialSmoothMaxWidth = 1280;

// Writes the smoothed `in` into `out` (same size, distinct memory). kInvalidImage for an invalid view,
// kInvalidArgument when the sizes differ or the width exceeds kBinomialSmoothMaxWidth; out unchanged then.
[[nodiscard]] Status binomial_smooth3(const GrayImageView& in, const MutableGrayImageView& out);

}  // namespace vantage
