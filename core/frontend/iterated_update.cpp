#include "core/frontend/iterated_update.hpp"

#include <cmath>

#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// The pieces are separate, not inlined, functions: Eigen's temporaries in one frame outgrow the core's
// 16 KB frame limit under ASan.

// Innovation covariance S and gain K at a linearization H (consider form, see the header).
[[gnu::noinline]] void innovation_gain(const Eigen::Matrix<double, 2, 3>& H, const Eigen::Matrix3d& Sigma,
                                       const Eigen::Matrix<double, 3, 2>& CB, const Eigen::Matrix2d& R_total,
                                       Eigen::Matrix2d* S, Eigen::Matrix<double, 3, 2>* K) {
  const Eigen::Matrix2d HCB = H * CB;
  *S = H * Sigma * H.transpose() - HCB - HCB.transpose() + R_total;
  *K = (Sigma * H.transpose() - CB) * S->inverse();
}

// Joseph-form covariance for gain K at H, valid for any K (consider form, see the header).
[[gnu::noinline]] Eigen::Matrix3d joseph_covariance(const Eigen::Matrix<double, 3, 2>& K,
                                                   const Eigen::Matrix<double, 2, 3>& H, const Eigen::Matrix3d& Sigma,
                                                   const Eigen::Matrix<double, 3, 2>& CB,
                                                   const Eigen::Matrix2d& R_total) {
  const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
  const Eigen::Matrix3d mixed = I_KH * CB * K.transpose();
  const Eigen::Matrix3d joseph = I_KH * Sigma * I_KH.transpose() + K * R_total * K.transpose();
  return joseph + mixed + mixed.transpose();
}

// C' = (I - KH) C + K B P_c.
[[gnu::noinline]] Eigen::Matrix<double, 3, 2> updated_cross_covariance(const Eigen::Matrix<double, 3, 2>& K,
                                                                       const Eigen::Matrix<double, 2, 3>& H,
                                                                       const CommonObservationError& common) {
  const Eigen::Matrix<double, 3, 2> kept = common.cross_covariance - K * (H * common.cross_covariance);
  return kept + K * (common.B * common.covariance_px2);
}

}  // namespace

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
  // Gauss-Newton on the MAP cost: linearize at X (one projection per pass, so the frame stays small under
  // ASan), gate on the first pass (at the prior), stop after the linearization that follows the last step.
  const int iterations = max_iterations < 1 ? 1 : max_iterations;
  Eigen::Vector3d X = X0;
  Eigen::Vector2d predicted;
  Eigen::Matrix<double, 2, 3> H;
  Eigen::Matrix2d S;
  Eigen::Matrix<double, 3, 2> K;
  bool converged = false;
  for (int iteration = 0;; ++iteration) {
    if (!ok(project_with_jacobian(X, view, intrinsics, &predicted, &H))) {
      ++counts.rejected_inputs;
      return Status::kBehindCamera;
    }
    innovation_gain(H, Sigma, CB, R_total, &S, &K);
    if (iteration == 0) {
      const Eigen::Vector2d innovation = observation_px - predicted;
      if (!(innovation.dot(S.inverse() * innovation) <= config.gate_chi2)) {
        ++counts.gated_outliers;
        return Status::kGatedOutlier;
      }
    }
    if (converged || iteration == iterations) break;
    const Eigen::Vector3d next = X0 + K * (observation_px - predicted - H * (X0 - X));
    // Converged when the step is far below the prior's spread along it.
    converged = (next - X).squaredNorm() <= 1e-6 * Sigma.trace();
    X = next;
  }
  // H and K are those at the last linearization point.
  const Eigen::Matrix3d joseph = joseph_covariance(K, H, Sigma, CB, R_total);
  const Eigen::Matrix<double, 3, 2> cross = updated_cross_covariance(K, H, *common);
  const Eigen::Matrix3d Sigma_new = 0.5 * (joseph + joseph.transpose());
  if (!X.allFinite() || !cross.allFinite() || !is_spd(Sigma_new)) {
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
