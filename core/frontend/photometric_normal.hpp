#pragma once
// A primitive's normal from its appearance: the plane through X with normal n maps the reference patch
// (stored in the creating view) into a new view by the plane-induced warp (patch_warp.hpp); a wrong
// normal distorts the warped patch, and the distortion grows with the change of view and toward grazing
// incidence. Gauss-Newton over the 7x7 reference pixels y on
//   I(u + M(t) y) = alpha * T(y) + beta,   M(t) = A(n(t))^-1,   n(t) = normalize(n0 + t1 e1 + t2 e2)
// (u the patch centre in the new image, t the tilt of the normal about two axes of its plane, gain and
// offset as NCC), with the normal's prior N(n0, prior_tilt_variance I) as a Gaussian prior on t. The
// residual variance comes from the fit. The reference pixels are not resampled (only the new image is,
// bilinearly), so the template's values are exactly the stored patch.
#include <array>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/frontend/match_kernel.hpp"
#include "core/frontend/ncc.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"

namespace vantage {

struct PhotometricNormalQuery {
  Eigen::Vector3d X_world = Eigen::Vector3d::Zero();
  Eigen::Vector3f normal_world = Eigen::Vector3f::UnitZ();  // the prior mean n0, unit length
  double prior_tilt_variance = 0.25;                        // rad^2 per axis, > 0
  Viewpoint reference;                                       // the view the patch was taken in
  Viewpoint target;                                          // the new view
  Eigen::Vector2d uv_target_px = Eigen::Vector2d::Zero();    // start of u (a match of the patch)
  int iterations = 5;
  // Also stop when the step's squared length in the information metric (its Newton decrement, in
  // squared posterior standard deviations) is below this: the rest of the way is well inside the
  // estimate's own uncertainty. 0: only the step-length rule. On at 1e-2 (5.7 -> 3.8 passes per estimate):
  // over eleven missions coverage was level and avg sigma lower (core/frontend/EXPERIMENTS.md, tenth round).
  double stop_decrement = 1e-2;
  // A primitive faces a camera when cos(normal, direction to the camera) exceeds this; the estimate
  // must face both views.
  double min_facing_cos = 0.05;
  // Which build of the pixel loop runs (match_kernel.hpp; the builds agree up to float rounding).
  MatchKernel kernel = MatchKernel::kAuto;
};

struct PhotometricNormalEstimate {
  Eigen::Vector3f normal_world = Eigen::Vector3f::UnitZ();
  // Posterior covariance of the tilt (rad^2) about the axes of tilt_axes, and its largest eigenvalue.
  Eigen::Matrix2d tilt_covariance = Eigen::Matrix2d::Zero();
  double tilt_variance = 0.0;
  Eigen::Vector2d uv_target_px = Eigen::Vector2d::Zero();  // u at the solution
  double gain = 1.0;                                       // alpha at the solution
  double residual_variance_gray2 = 0.0;
  // Posterior covariance of u (px^2): the shift block of the same sandwich form as tilt_covariance, so
  // the tilt, gain and offset are marginalized (the normal's uncertainty is in it).
  Eigen::Matrix2d shift_covariance_px2 = Eigen::Matrix2d::Zero();
};

// kInvalidArgument for a non-unit normal, a non-positive prior variance or iterations outside [1, 20];
// kBehindCamera when X is behind either view or the normal turns away from one (or edge-on);
// kOutsideImage when the patch leaves the image or u moves more than 1.5 px from its start; kNotSpd when
// the system is singular (no texture). The estimate is untouched on error.
Status estimate_photometric_normal(const GrayImageView& image, const std::array<std::uint8_t, kPatchPixels>& patch,
                                   const PhotometricNormalQuery& query, const PinholeIntrinsics& intrinsics,
                                   PhotometricNormalEstimate* estimate);

// The sandwich's meat J^T C J of one pass of the fit (match_kernel::PhotometricPass, its outputs and
// per-pixel rows; J = [g, two tilt columns, -T, -1]): C the residual field's lag-one correlations
// (correlated_residuals.hpp's model, clamped the same way), *rho_x and *rho_y, and J^T J the pass's own.
// The cross terms are summed in float lanes from the rows (the pass's precision). The estimate's tilt
// covariance uses it at the last pass. kernel: kBaseline forces the baseline build; otherwise AVX2 where
// the CPU has it (the same bits: no FMA).
Eigen::Matrix<double, 6, 6> photometric_correlated_meat(const match_kernel::PhotometricPass& pass,
                                                       const std::array<std::uint8_t, kPatchPixels>& patch,
                                                       double* rho_x, double* rho_y,
                                                       MatchKernel kernel = MatchKernel::kAuto);

}  // namespace vantage
