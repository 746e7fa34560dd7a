#pragma once
// The iterated EKF measurement update (Gauss-Newton on the MAP cost, Bell and Cathey 1993) for one
// primitive. A new primitive's covariance is long along depth, and the collinearity function bends over
// that length: a single EKF step linearized at the prior biases the depth toward the camera and leaves
// a covariance too small for the error. Relinearizing H at the updated estimate removes that bias; for a
// well-estimated primitive the first iteration already converges, so it costs one extra projection.
//
// The consider form (Schmidt-Kalman) also carries an error common to all of a primitive's observations:
// o = phi(X) + B c + e, with c ~ N(0, P_c) the same in every image (the reference patch's own pixel noise
// shifts the feature every match looks for, by c in the reference image; B maps that shift into the new
// image) and e ~ N(0, R) independent. c is not estimated, but its cross-covariance with X's error,
// C = Cov(X_hat - X, c), is kept and updated, so repeated observations do not average the common error
// away: S = H Sigma H^T - H C B^T - B C^T H^T + B P_c B^T + R, K = (Sigma H^T - C B^T) S^-1,
// Sigma' = (I - KH) Sigma (I - KH)^T + (I - KH) C B^T K^T + K B C^T (I - KH)^T + K (B P_c B^T + R) K^T,
// C' = (I - KH) C + K B P_c. With P_c = 0 and C = 0 it is the iterated EKF.
//
// c may be a sum of independent parts whose cross-covariances the caller keeps apart (the front end's
// view-correlated match error decorrelates between views while the patch noise does not): the update is
// made with the sum, and one part's cross-covariance C_p, with its covariance P_p, is carried along by the
// same rule, C_p' = (I - KH) C_p + K B P_p, so that the caller can take the other part as C' - C_p'.
#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/estimation/ekf.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"

namespace vantage {

// The error common to a primitive's observations (see above): its covariance in the reference image
// (px^2), its cross-covariance with the primitive's position error (units x px), and B for this image.
struct CommonObservationError {
  Eigen::Matrix2d covariance_px2 = Eigen::Matrix2d::Zero();
  Eigen::Matrix<double, 3, 2> cross_covariance = Eigen::Matrix<double, 3, 2>::Zero();
  Eigen::Matrix2d B = Eigen::Matrix2d::Identity();
  // One part of c (see above): its covariance and cross-covariance, shares of the two above, read and
  // updated only with has_part (without, the update does not touch them: a frame's worth of instructions).
  bool has_part = false;
  Eigen::Matrix2d part_covariance_px2 = Eigen::Matrix2d::Zero();
  Eigen::Matrix<double, 3, 2> part_cross_covariance = Eigen::Matrix<double, 3, 2>::Zero();

  // The common error's covariance in this image: B P_c B^T (px^2).
  Eigen::Matrix2d projected_px2() const { return B * covariance_px2 * B.transpose(); }
};

// Same contract as ekf_update (core/estimation/ekf.hpp): the Mahalanobis gate on the innovation at the
// prior, the Joseph-form covariance (with H and its own gain at the final iterate, so computed as
// Sigma - K S K^T; the Joseph products only where that subtraction cancels: an axis keeps less than 1e-6
// of its prior variance, or the result is not positive definite), the primitive unchanged on any error,
// counts into stats. max_iterations >= 1 (1 is the plain EKF update).
Status iterated_ekf_update(Primitive& primitive, const Eigen::Vector2d& observation_px, const Viewpoint& view,
                           const PinholeIntrinsics& intrinsics, const EkfConfig& config, int max_iterations,
                           EkfStats* stats);

// The consider form: config.R_px2 is the independent part R; common->cross_covariance is updated with
// the primitive (unchanged on error).
Status iterated_consider_update(Primitive& primitive, CommonObservationError* common, const Eigen::Vector2d& observation_px,
                                const Viewpoint& view, const PinholeIntrinsics& intrinsics, const EkfConfig& config,
                                int max_iterations, EkfStats* stats);

// project_with_jacobian of the primitive's X_world in the view, when the caller has it already (the
// tracker's prediction): the first linearization then costs no projection.
struct ProjectionAtPrior {
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();
  Eigen::Matrix<double, 2, 3> H = Eigen::Matrix<double, 2, 3>::Zero();
};

// The same update, linearized first at `at_prior` (which must be X_world's projection in `view`).
Status iterated_consider_update(Primitive& primitive, CommonObservationError* common, const Eigen::Vector2d& observation_px,
                                const Viewpoint& view, const PinholeIntrinsics& intrinsics, const EkfConfig& config,
                                int max_iterations, const ProjectionAtPrior& at_prior, EkfStats* stats);

// One update of a batch: the arguments of iterated_consider_update with at_prior, per primitive.
struct ConsiderUpdateRequest {
  Primitive* primitive = nullptr;
  CommonObservationError* common = nullptr;
  Eigen::Vector2d observation_px = Eigen::Vector2d::Zero();
  EkfConfig config;
  ProjectionAtPrior at_prior;
};
inline constexpr int kUpdateBatchSize = 4;

// iterated_consider_update(request, view, ..., at_prior) for each of up to kUpdateBatchSize requests (distinct
// primitives) seen from one view: the same statuses, primitives, cross-covariances and stats, bit for bit.
// Where the CPU has AVX2 (x86-64) the four updates run in the lanes of double vectors, each lane doing the
// scalar update's operations in Eigen's order without FMA (core test); a lane whose short-form covariance
// fails its check is done again by the scalar update (the Joseph form). Elsewhere one by one.
void iterated_consider_update_batch(const ConsiderUpdateRequest* requests, int count, const Viewpoint& view,
                                    const PinholeIntrinsics& intrinsics, int max_iterations, EkfStats* stats,
                                    Status* statuses);

}  // namespace vantage
