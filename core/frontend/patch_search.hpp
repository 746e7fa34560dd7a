#pragma once
// NCC peak searches: in a 2D window around a predicted projection (tracking) and along an epipolar
// segment (initialization and model augmentation). Both take the best local NCC maximum, require it
// above a threshold and unique (no other local maximum, away from the peak's 8-neighbourhood, within
// uniqueness_ratio of it), and refine it to subpixel by a parabola fit in x and in y.
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/span.hpp"
#include "core/frontend/ncc.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"

namespace vantage {

enum class MatchOutcome : std::uint8_t {
  kMatched = 0,
  kBelowThreshold,  // no local NCC maximum at or above the threshold
  kAmbiguous,       // a second local maximum within uniqueness_ratio of the best
  kNoRoom,          // the search region left the image or outgrew the scratch space
  kNoSubpixel,      // the photometric refinement did not converge within a pixel of the peak
  kBeyondDepthRange,  // epipolar only: the best peak lies in the guard band past the depth range
};

// A subpixel fit has converged when its last step is shorter than this (pixels): the searches' stop and
// their convergence test (MatchConfig::subpixel_stop_step_px's default).
inline constexpr double kSubpixelConvergedStepPx = 1e-2;

struct MatchConfig {
  float ncc_min = 0.8f;            // NCC a match must reach
  float uniqueness_ratio = 0.95f;  // a second local maximum must stay below ratio * best
  // Gauss-Newton steps of the photometric refinement after the parabola fit (0: parabola only).
  int subpixel_iterations = 3;
  // The fit stops after a step shorter than this (pixels).
  double subpixel_stop_step_px = kSubpixelConvergedStepPx;
  // search_window refuses (kNoSubpixel) a fit whose last step was not shorter than subpixel_stop_step_px
  // (the direct path always requires it). Off: such a fit is taken as it stands after its last step.
  bool require_converged_fit = false;
  // Build of the inner loops (match_kernel.hpp); one this CPU lacks falls back to the baseline.
  MatchKernel kernel = MatchKernel::kAuto;
};

// Subpixel refinement of a match near integer peak (x, y): Gauss-Newton on I(p + d) = alpha * t + beta
// (gain and offset, like NCC) over the template's valid pixels, started at *uv_px (the parabola fit).
// A parabola through NCC samples is biased toward integer positions ("pixel locking"); this is not.
// covariance_px2 (may be null) gets the least-squares covariance of the position: residual variance
// times the shift block of (J^T J)^-1, so a weakly textured or badly fitting patch reports a large one.
// False, outputs untouched, when it does not converge within one pixel of (x, y) or the block leaves
// the image.
bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2);
// The same with a chosen build of the inner loops; false, outputs untouched, also when the kernel is not
// supported here (match_kernel_supported).
bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2, MatchKernel kernel);
// The same, also giving the length of the fit's last step (last_step_px): below kSubpixelConvergedStepPx
// when the fit converged by the window search's rule.
bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2, MatchKernel kernel,
                     double* last_step_px);

// Tracking search: integer positions whose offset d from predicted_px has d^T S_inv d <= gate_chi2
// (the 3-sigma ellipse for gate 9), inside a box of +-half_width x +-half_height pixels.
struct WindowQuery {
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d S_inv = Eigen::Matrix2d::Identity();
  double gate_chi2 = 9.0;
  std::int32_t half_width_px = 2;
  std::int32_t half_height_px = 2;
  // The caller's prior puts the feature within about a pixel of predicted_px (EXPERIMENTS.md, "Speed"): the
  // photometric fit runs from the prediction first and is taken when it converges and its NCC reaches
  // ncc_min (*best_ncc is then that NCC, of the subpixel-aligned patch); otherwise the window is searched
  // as without it.
  bool direct_fit = false;
};

// The box of a window search (the window plus a one-pixel ring) is at most this wide and high: half
// sizes up to 30 px. A larger window gives kNoRoom.
inline constexpr std::int32_t kWindowSearchMaxBox = 64;

// Scratch floats a window search needs for a given half size: the NCC of the box (the window plus a
// one-pixel ring) and ncc_box's working space.
constexpr std::size_t window_scratch_size(std::int32_t max_half_px) {
  const std::int32_t box = 2 * max_half_px + 3;
  return static_cast<std::size_t>(box) * ncc_box_out_stride(box) + ncc_box_scratch_size(box, box);
}

// covariance_px2 (may be null): the match's covariance from refine_subpixel, NaN when
// subpixel_iterations is 0 (then the caller's fixed R applies). kNoRoom also for a box wider or higher
// than kWindowSearchMaxBox.
MatchOutcome search_window(const GrayImageView& image, const NccTemplate& tmpl, const WindowQuery& query,
                           const MatchConfig& config, Span<float> scratch, Eigen::Vector2d* uv_px, float* best_ncc,
                           Eigen::Matrix2d* covariance_px2 = nullptr);

// Epipolar search: the ray through uv_first_px of `first` between camera depths depth_min and depth_max
// (z along first's optical axis, scene units) projects to a segment (a curve under distortion) in the
// second image; every integer pixel on it is a candidate. When part of the range projects outside the
// second image (or behind it) the search gives kNoRoom: the true match could be where it cannot look.
// The guard band: the segment goes on past both ends by guard_fraction of the range's inverse-depth
// span (the far side at most to infinity), as far as it stays in the image. Its peaks compete for
// uniqueness, and a best peak there gives kBeyondDepthRange: a surface beyond the range then yields no
// primitive instead of one at the best wrong depth inside it (EXPERIMENTS.md, "Session 22").
struct EpipolarQuery {
  Eigen::Vector2d uv_first_px = Eigen::Vector2d::Zero();
  Viewpoint first;
  Viewpoint second;
  double depth_min = 1.0;
  double depth_max = 100.0;
  double guard_fraction = 0.0;  // >= 0 (a negative one is none); NaN, or so large the guard needs more than
                                // 256 knots a side: kNoRoom
};

MatchOutcome search_epipolar(const GrayImageView& second_image, const NccTemplate& tmpl, const EpipolarQuery& query,
                             const PinholeIntrinsics& intrinsics, const MatchConfig& config, Span<float> scratch_ncc,
                             Span<std::int32_t> scratch_xy, Eigen::Vector2d* uv_second_px, float* best_ncc,
                             Eigen::Matrix2d* covariance_px2 = nullptr);

}  // namespace vantage
