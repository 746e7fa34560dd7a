#pragma once
// Two-view triangulation with known poses: the midpoint of the closest approach of the two rays, refined
// by Gauss-Newton on the R-weighted reprojection error, and its covariance by forward propagation of both
// observations' pixel noise in information form, Sigma^-1 = sum_k H_k^T R_k^-1 H_k (H_k the collinearity
// Jacobian at the solution). A small baseline gives an information matrix weak along depth, hence a
// covariance elongated along depth.
#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"

namespace vantage {

struct TwoViewObservation {
  Eigen::Vector2d uv_a_px = Eigen::Vector2d::Zero();
  Viewpoint view_a;
  Eigen::Matrix2d R_a_px2 = Eigen::Matrix2d::Identity() * 0.25;
  Eigen::Vector2d uv_b_px = Eigen::Vector2d::Zero();
  Viewpoint view_b;
  Eigen::Matrix2d R_b_px2 = Eigen::Matrix2d::Identity() * 0.25;
};

// kNonFiniteInput for NaN/Inf, kInvalidArgument for (near) parallel rays, kBehindCamera when the point
// is not in front of both cameras, kNotSpd when the information matrix is singular. Outputs untouched
// on error.
Status triangulate_two_views(const TwoViewObservation& obs, const PinholeIntrinsics& intrinsics,
                             Eigen::Vector3d* X_world, Eigen::Matrix3d* Sigma_world);

}  // namespace vantage
