#include "core/frontend/iterated_update.hpp"

#include <cmath>

#include "core/geometry/projection.hpp"

namespace vantage {

Status iterated_ekf_update(Primitive& primitive, const Eigen::Vector2d& observation_px, const Viewpoint& view,
                           const PinholeIntrinsics& intrinsics, const EkfConfig& config, int max_iterations,
                           EkfStats* stats) {
  EkfStats ignored;
  EkfStats& counts = stats != nullptr ? *stats : ignored;
  if (!observation_px.allFinite() || !view.position_world.allFinite() || !view.R_world_cam.allFinite() ||
      !primitive.X_world.allFinite() || !config.R_px2.allFinite()) {
    ++counts.rejected_inputs;
    return Status::kNonFiniteInput;
  }
  if (!is_spd(primitive.Sigma_world)) {
    ++counts.rejected_inputs;
    return Status::kNotSpd;
  }
  const Eigen::Vector3d X0 = primitive.X_world;
  const Eigen::Matrix3d& Sigma = primitive.Sigma_world;
  Eigen::Vector2d predicted;
  Eigen::Matrix<double, 2, 3> H;
  if (!ok(project_with_jacobian(X0, view, intrinsics, &predicted, &H))) {
    ++counts.rejected_inputs;
    return Status::kBehindCamera;
  }
  Eigen::Matrix2d S = H * Sigma * H.transpose() + config.R_px2;
  const Eigen::Vector2d innovation = observation_px - predicted;
  if (!(innovation.dot(S.inverse() * innovation) <= config.gate_chi2)) {
    ++counts.gated_outliers;
    return Status::kGatedOutlier;
  }
  Eigen::Vector3d X = X0;
  Eigen::Matrix<double, 3, 2> K = Sigma * H.transpose() * S.inverse();
  for (int iteration = 0; iteration < (max_iterations < 1 ? 1 : max_iterations); ++iteration) {
    if (iteration > 0) {
      if (!ok(project_with_jacobian(X, view, intrinsics, &predicted, &H))) {
        ++counts.rejected_inputs;
        return Status::kBehindCamera;
      }
      S = H * Sigma * H.transpose() + config.R_px2;
      K = Sigma * H.transpose() * S.inverse();
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
  S = H * Sigma * H.transpose() + config.R_px2;
  K = Sigma * H.transpose() * S.inverse();
  const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
  const Eigen::Matrix3d joseph = I_KH * Sigma * I_KH.transpose() + K * config.R_px2 * K.transpose();
  if (!X.allFinite() || !joseph.allFinite()) {
    ++counts.rejected_inputs;
    return Status::kNonFiniteInput;
  }
  primitive.X_world = X;
  primitive.Sigma_world = 0.5 * (joseph + joseph.transpose());
  ++primitive.observation_count;
  ++counts.accepted;
  return Status::kOk;
}

}  // namespace vantage
