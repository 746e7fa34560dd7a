#pragma once
// Texture saliency of a primitive's reference patch (paper section IV-C, eqs. 5-6).
//
// Sign convention (the paper's eqs. 5-6 are ambiguous in sign; this is the stated intent):
//   E = Shannon entropy of the squared autocorrelation a^2 of the patch normalized to sum 1 (a is the
//       (2p-1)x(2p-1) autocorrelation of the mean-free patch, a(0,0) = 1, |a| <= 1), divided by its maximum
//       log((2p-1)^2) so E lies in [0, 1] whatever p is;
//   h = 0.5 * erfc((E - tau) / gamma)  -- a smooth step that FALLS with entropy.
// A salient patch has a peaked autocorrelation, low E, and h -> 1: the projected area g matters (C = g^h / f).
// A homogeneous patch has a flat autocorrelation, high E, and h -> 0: g^0 = 1, oblique views are not
// penalized. A patch whose standard deviation is below min_stddev (constant, or only quantization
// noise) is homogeneous by definition: h = 0 without computing E, so no 0/0 and no NaN.
#include <array>
#include <cstdint>

#include "core/model/primitive.hpp"

namespace vantage {

using Patch = std::array<std::uint8_t, kPatchSize * kPatchSize>;

struct SaliencyParams {
  // Defaults from measured normalized entropies of 7x7 patches (200 of each kind, README.md): textured
  // patches measure noise 0.41-0.67, 2-px checkerboard 0.58, blobs 0.55-0.70, corners 0.46-0.70; smooth
  // ones measure shading ramps 0.78-0.82, quadratic shading 0.744, low-frequency waves 0.755-0.824.
  // (Straight edges, 0.53-0.80, straddle the threshold: the aperture problem makes them half-salient.)
  float tau = 0.72f;    // entropy threshold: h(tau) = 0.5
  float gamma = 0.02f;  // transition width: h(tau - gamma) = 0.92, h(tau + gamma) = 0.08
  float min_stddev = 1.0f;  // gray levels; below this the patch is homogeneous (h = 0)
};

// E in [0, 1] (see above); 1 for a patch below min_stddev.
float patch_autocorrelation_entropy(const Patch& patch, float min_stddev);

// h(P) in [0, 1]. Non-finite or non-positive gamma, or non-finite tau, give 0 (no saliency claimed).
float compute_saliency_h(const Patch& patch, const SaliencyParams& params);

// The smooth step alone: 0.5 * erfc((entropy - tau) / gamma).
float saliency_step(float entropy, const SaliencyParams& params);

}  // namespace vantage
