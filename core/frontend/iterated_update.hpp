#pragma once
// The iterated EKF measurement update (Gauss-Newton on the MAP cost, Bell and Cathey 1993) for one
// primitive. A new primitive's covariance is long along depth, and the collinearity function bends over
// that length: a single EKF step linearized at the prior biases the depth toward the camera and leaves
// a covariance too small for the error. Relinearizing H at the updated estimate removes that bias; for a
// well-estimated primitive the first iteration already converges, so it costs one extra projection.
#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/estimation/ekf.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"

namespace vantage {

// Same contract as ekf_update (core/estimation/ekf.hpp): the Mahalanobis gate on the innovation at the
// prior, the Joseph-form covariance (with H at the final iterate), the primitive unchanged on any error,
// counts into stats. max_iterations >= 1 (1 is the plain EKF update).
Status iterated_ekf_update(Primitive& primitive, const Eigen::Vector2d& observation_px, const Viewpoint& view,
                           const PinholeIntrinsics& intrinsics, const EkfConfig& config, int max_iterations,
                           EkfStats* stats);

}  // namespace vantage
