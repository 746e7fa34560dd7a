#pragma once
// Per-primitive extended Kalman filter (paper eqs. 1-3). The scene is static, so there is no time
// update; each image contributes one measurement update per matched primitive. The covariance update
// uses the Joseph form and is symmetrized, so it stays SPD in floating point.
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/estimation/nis_histogram.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"

namespace vantage {

// chi-square 95% quantile for 2 degrees of freedom: the default Mahalanobis gate on the innovation.
inline constexpr double kChiSquare2Dof95 = 5.991464547107979;

struct EkfConfig {
  Eigen::Matrix2d R_px2 = Eigen::Matrix2d::Identity() * 0.25;  // image measurement covariance, px^2
  double gate_chi2 = kChiSquare2Dof95;                          // reject innovations beyond this

  // kOk, kNonFiniteInput, or kNotSpd when R is not SPD, kInvalidArgument when the gate is not positive.
  Status validate() const;
};

struct EkfStats {
  std::uint64_t accepted = 0;
  std::uint64_t gated_outliers = 0;
  std::uint64_t rejected_inputs = 0;  // non-finite, non-SPD or behind-camera inputs
  NisHistogram nis;                   // every innovation the gate tested, at the prior (accepted or gated)
};

// The covariance Sigma after one measurement from view at X: the Joseph-form update, symmetrized.
// kBehindCamera when X is not in front of the view; *Sigma_out untouched on error.
Status covariance_after_observation(const Eigen::Vector3d& X_world, const Eigen::Matrix3d& Sigma_world,
                                    const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                    const Eigen::Matrix2d& R_px2, Eigen::Matrix3d* Sigma_out);

// Update the primitive with observation o_t = (u, v) from view (eqs. 1-3). On any error the primitive
// is unchanged: kNonFiniteInput, kNotSpd (its Sigma), kBehindCamera, kGatedOutlier. Counts into stats
// when it is not null.
Status ekf_update(Primitive& primitive, const Eigen::Vector2d& observation_px, const Viewpoint& view,
                  const PinholeIntrinsics& intrinsics, const EkfConfig& config, EkfStats* stats);

// The covariance after one hypothetical observation from view, P untouched (PredictModel, Fig. 3).
Status predict_covariance(const Primitive& primitive, const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                          const Eigen::Matrix2d& R_px2, Eigen::Matrix3d* Sigma_predicted);

// True when Sigma is finite, symmetric (relative tolerance 1e-9) and positive definite.
bool is_spd(const Eigen::Matrix3d& Sigma);

}  // namespace vantage
