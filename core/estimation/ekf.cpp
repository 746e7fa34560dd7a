#include "core/estimation/ekf.hpp"

#include <Eigen/Cholesky>

#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

bool is_spd2(const Eigen::Matrix2d& M) {
  if (!M.allFinite()) return false;
  if (std::abs(M(0, 1) - M(1, 0)) > 1e-9 * (std::abs(M(0, 0)) + std::abs(M(1, 1)))) return false;
  return M(0, 0) > 0.0 && M.determinant() > 0.0;
}

}  // namespace

Status EkfConfig::validate() const {
  if (!R_px2.allFinite() || !std::isfinite(gate_chi2)) return Status::kNonFiniteInput;
  if (!is_spd2(R_px2)) return Status::kNotSpd;
  if (!(gate_chi2 > 0.0)) return Status::kInvalidArgument;
  return Status::kOk;
}

bool is_spd(const Eigen::Matrix3d& Sigma) {
  if (!Sigma.allFinite()) return false;
  const double scale = Sigma.diagonal().cwiseAbs().sum();
  if (!(scale > 0.0)) return false;
  if ((Sigma - Sigma.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) return false;
  Eigen::LLT<Eigen::Matrix3d> llt(Sigma);
  return llt.info() == Eigen::Success;
}

Status covariance_after_observation(const Eigen::Vector3d& X_world, const Eigen::Matrix3d& Sigma,
                                    const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                    const Eigen::Matrix2d& R_px2, Eigen::Matrix3d* Sigma_out) {
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> H;
  const Status projected = project_with_jacobian(X_world, view, intrinsics, &uv, &H);
  if (!ok(projected)) return projected;
  const Eigen::Matrix2d S = H * Sigma * H.transpose() + R_px2;
  const Eigen::Matrix<double, 3, 2> K = Sigma * H.transpose() * S.inverse();
  const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
  const Eigen::Matrix3d joseph = I_KH * Sigma * I_KH.transpose() + K * R_px2 * K.transpose();
  *Sigma_out = 0.5 * (joseph + joseph.transpose());
  return Status::kOk;
}

Status ekf_update(Primitive& primitive, const Eigen::Vector2d& observation_px, const Viewpoint& view,
                  const PinholeIntrinsics& intrinsics, const EkfConfig& config, EkfStats* stats) {
  EkfStats ignored;
  EkfStats& counts = stats != nullptr ? *stats : ignored;
  if (!observation_px.allFinite() || !view.position_world.allFinite() || !view.R_world_cam.allFinite() ||
      !primitive.X_world.allFinite()) {
    ++counts.rejected_inputs;
    return Status::kNonFiniteInput;
  }
  if (!is_spd(primitive.Sigma_world)) {
    ++counts.rejected_inputs;
    return Status::kNotSpd;
  }
  Eigen::Vector2d predicted_px;
  Eigen::Matrix<double, 2, 3> H;
  const Status projected = project_with_jacobian(primitive.X_world, view, intrinsics, &predicted_px, &H);
  if (!ok(projected)) {
    ++counts.rejected_inputs;
    return projected;
  }
  const Eigen::Matrix3d& Sigma = primitive.Sigma_world;
  const Eigen::Matrix2d S = H * Sigma * H.transpose() + config.R_px2;
  const Eigen::Matrix2d S_inv = S.inverse();
  const Eigen::Vector2d innovation = observation_px - predicted_px;
  const double mahalanobis2 = innovation.dot(S_inv * innovation);
  counts.nis.record(mahalanobis2);
  if (!(mahalanobis2 <= config.gate_chi2)) {
    ++counts.gated_outliers;
    return Status::kGatedOutlier;
  }
  const Eigen::Matrix<double, 3, 2> K = Sigma * H.transpose() * S_inv;
  const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
  const Eigen::Matrix3d joseph = I_KH * Sigma * I_KH.transpose() + K * config.R_px2 * K.transpose();
  primitive.X_world += K * innovation;
  primitive.Sigma_world = 0.5 * (joseph + joseph.transpose());
  ++primitive.observation_count;
  ++counts.accepted;
  return Status::kOk;
}

Status predict_covariance(const Primitive& primitive, const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                          const Eigen::Matrix2d& R_px2, Eigen::Matrix3d* Sigma_predicted) {
  if (!primitive.X_world.allFinite() || !view.position_world.allFinite() || !view.R_world_cam.allFinite() ||
      !R_px2.allFinite()) {
    return Status::kNonFiniteInput;
  }
  if (!is_spd(primitive.Sigma_world)) return Status::kNotSpd;
  return covariance_after_observation(primitive.X_world, primitive.Sigma_world, view, intrinsics, R_px2,
                                      Sigma_predicted);
}

}  // namespace vantage
