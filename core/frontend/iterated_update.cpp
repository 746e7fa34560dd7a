#include "core/frontend/iterated_update.hpp"

#include <cmath>

#include "core/geometry/projection.hpp"

namespace vantage {

Status iterated_ekf_update(Primitive& primitive, const Eigen::Vector2d& observation_px, const Viewpoint& view,
                           const PinholeIntrinsics& intrinsics, const EkfConfig& config, int max_iterations,
                           EkfStats* stats) {
  CommonObservationError none;
  return iterated_consider_update(primitive, &none, observation_px, view, intrinsics, config, max_iterations, stats);
}

Status iterated_consider_update(Primitive& primitive, CommonObservationError* common, const Eigen::Vector2d& observation_px,
                                const Viewpoint& view, const PinholeIntrinsics& intrinsics, const EkfConfig& config,
                                int max_iterations, EkfStats* stats) {
  EkfStats ignored;
  EkfStats& counts = stats != nullptr ? *stats : ignored;
  if (!observation_px.allFinite() || !view.position_world.allFinite() || !view.R_world_cam.allFinite() ||
      !primitive.X_world.allFinite() || !config.R_px2.allFinite() || !common->covariance_px2.allFinite() ||
      !common->cross_covariance.allFinite() || !common->B.allFinite()) {
    ++counts.rejected_inputs;
    return Status::kNonFiniteInput;
  }
  if (!is_spd(primitive.Sigma_world)) {
    ++counts.rejected_inputs;
    return Status::kNotSpd;
  }
  const Eigen::Vector3d X0 = primitive.X_world;
  const Eigen::Matrix3d& Sigma = primitive.Sigma_world;
  const Eigen::Matrix<double, 3, 2> CB = common->cross_covariance * common->B.transpose();  // C B^T
  const Eigen::Matrix2d R_total = common->B * common->covariance_px2 * common->B.transpose() + config.R_px2;
  // Innovation covariance and gain at a linearization (H).
  auto gain = [&](const Eigen::Matrix<double, 2, 3>& H, Eigen::Matrix2d* S, Eigen::Matrix<double, 3, 2>* K) {
    const Eigen::Matrix2d HCB = H * CB;
    *S = H * Sigma * H.transpose() - HCB - HCB.transpose() + R_total;
    *K = (Sigma * H.transpose() - CB) * S->inverse();
  };
  Eigen::Vector2d predicted;
  Eigen::Matrix<double, 2, 3> H;
  if (!ok(project_with_jacobian(X0, view, intrinsics, &predicted, &H))) {
    ++counts.rejected_inputs;
    return Status::kBehindCamera;
  }
  Eigen::Matrix2d S;
  Eigen::Matrix<double, 3, 2> K;
  gain(H, &S, &K);
  const Eigen::Vector2d innovation = observation_px - predicted;
  if (!(innovation.dot(S.inverse() * innovation) <= config.gate_chi2)) {
    ++counts.gated_outliers;
    return Status::kGatedOutlier;
  }
  Eigen::Vector3d X = X0;
  for (int iteration = 0; iteration < (max_iterations < 1 ? 1 : max_iterations); ++iteration) {
    if (iteration > 0) {
      if (!ok(project_with_jacobian(X, view, intrinsics, &predicted, &H))) {
        ++counts.rejected_inputs;
        return Status::kBehindCamera;
      }
      gain(H, &S, &K);
    }
    const Eigen::Vector3d next = X0 + K * (observation_px - predicted - H * (X0 - X));
    const Eigen::Vector3d step = next - X;
    X = next;
    // Converged when the step is far below the prior's spread along it.
    if (step.squaredNorm() <= 1e-6 * Sigma.trace()) break;
  }
  // H and K at the last linearization point.
  if (!ok(project_with_jacobian(X, view, intrinsics, &predicted, &H))) {
    ++counts.rejected_inputs;
    return Status::kBehindCamera;
  }
  gain(H, &S, &K);
  const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
  const Eigen::Matrix3d mixed = I_KH * CB * K.transpose();
  const Eigen::Matrix3d joseph =
      I_KH * Sigma * I_KH.transpose() + mixed + mixed.transpose() + K * R_total * K.transpose();
  const Eigen::Matrix<double, 3, 2> cross =
      I_KH * common->cross_covariance + K * common->B * common->covariance_px2;
  if (!X.allFinite() || !joseph.allFinite() || !cross.allFinite()) {
    ++counts.rejected_inputs;
    return Status::kNonFiniteInput;
  }
  const Eigen::Matrix3d Sigma_new = 0.5 * (joseph + joseph.transpose());
  if (!is_spd(Sigma_new)) {
    ++counts.rejected_inputs;
    return Status::kNotSpd;
  }
  primitive.X_world = X;
  primitive.Sigma_world = Sigma_new;
  common->cross_covariance = cross;
  ++primitive.observation_count;
  ++counts.accepted;
  return Status::kOk;
}

}  // namespace vantage
