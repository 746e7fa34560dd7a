#include "core/frontend/iterated_update.hpp"

#include <cmath>

#include "core/frontend/update_checks.hpp"
#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// The pieces are separate, not inlined, functions: Eigen's temporaries in one frame outgrow the core's
// 16 KB frame limit under ASan. innovation_gain alone is left to the compiler: inlined once into
// consider_update's loop (ASan frame 10.9 KB) it saves its call and the stores of its results (0.5 M
// instructions per bench frame, bit-identical).

// Innovation covariance S, its inverse, the gain K and G = Sigma H^T - C B^T (X's covariance with the
// innovation; K = G S^-1) at a linearization H (consider form, see the header). False when S is not
// positive definite.
bool innovation_gain(const Eigen::Matrix<double, 2, 3>& H, const Eigen::Matrix3d& Sigma,
                     const Eigen::Matrix<double, 3, 2>& CB, const Eigen::Matrix2d& R_total, Eigen::Matrix2d* S_inv,
                     Eigen::Matrix<double, 3, 2>* K, Eigen::Matrix<double, 3, 2>* G) {
  const Eigen::Matrix<double, 3, 2> SigmaHt = Sigma * H.transpose();
  const Eigen::Matrix2d HCB = H * CB;
  const Eigen::Matrix2d HSH = H * SigmaHt;
  // Symmetric 2x2: explicit inverse.
  const double s00 = HSH(0, 0) - 2.0 * HCB(0, 0) + R_total(0, 0);
  const double s11 = HSH(1, 1) - 2.0 * HCB(1, 1) + R_total(1, 1);
  const double s01 = 0.5 * (HSH(0, 1) + HSH(1, 0)) - HCB(0, 1) - HCB(1, 0) + 0.5 * (R_total(0, 1) + R_total(1, 0));
  const double det = s00 * s11 - s01 * s01;
  if (!(s00 > 0.0) || !(det > 0.0)) return false;
  const double inv_det = 1.0 / det;
  *S_inv << s11 * inv_det, -s01 * inv_det, -s01 * inv_det, s00 * inv_det;
  *G = SigmaHt - CB;
  *K = *G * *S_inv;
  return true;
}

// x - x summed over the coefficients: zero when all are finite, NaN when any is NaN or infinite. The
// inputs' checks as one vectorizable sum instead of a compare and branch per coefficient.
template <typename Derived>
double nonfinite_probe(const Eigen::MatrixBase<Derived>& m) {
  return (m.array() - m.array()).sum();
}

// Every input finite: one summed probe (noinline, like the helpers below, to keep consider_update's frame
// small under ASan).
[[gnu::noinline]] bool inputs_finite(const Primitive& primitive, const CommonObservationError& common,
                                     const Eigen::Vector2d& observation_px, const Viewpoint& view,
                                     const EkfConfig& config, const ProjectionAtPrior* at_prior) {
  double probe = nonfinite_probe(observation_px) + nonfinite_probe(view.position_world) +
                 nonfinite_probe(view.R_world_cam) + nonfinite_probe(primitive.X_world) + nonfinite_probe(config.R_px2) +
                 nonfinite_probe(common.covariance_px2) + nonfinite_probe(common.cross_covariance) +
                 nonfinite_probe(common.B);
  if (common.has_part) {
    probe += nonfinite_probe(common.part_covariance_px2) + nonfinite_probe(common.part_cross_covariance);
  }
  if (at_prior != nullptr) probe += nonfinite_probe(at_prior->predicted_px) + nonfinite_probe(at_prior->H);
  return probe == 0.0;
}

// Sylvester's criterion for a matrix symmetric by construction (0.5 (M + M^T)): finite, and the leading
// minors (the LLT's pivots' products) positive, for a fraction of an LLT's cost.
bool spd3_symmetrized(const Eigen::Matrix3d& M) {
  if (!(nonfinite_probe(M) == 0.0)) return false;
  const double minor2 = M(0, 0) * M(1, 1) - M(0, 1) * M(1, 0);
  return M(0, 0) > 0.0 && minor2 > 0.0 && M.determinant() > 0.0;
}

// spd3_symmetrized for any 3x3, with is_spd's scale and symmetry checks first (a non-finite matrix fails
// one of them or the probe).
bool spd3(const Eigen::Matrix3d& M) {
  const double scale = std::abs(M(0, 0)) + std::abs(M(1, 1)) + std::abs(M(2, 2));
  if (!(scale > 0.0)) return false;
  const double tolerance = 1e-9 * scale;
  if (std::abs(M(0, 1) - M(1, 0)) > tolerance || std::abs(M(0, 2) - M(2, 0)) > tolerance ||
      std::abs(M(1, 2) - M(2, 1)) > tolerance) {
    return false;
  }
  return spd3_symmetrized(M);
}

}  // namespace

namespace update_checks {

Status check_inputs(const Primitive& primitive, const CommonObservationError& common,
                    const Eigen::Vector2d& observation_px, const Viewpoint& view, const EkfConfig& config,
                    const ProjectionAtPrior* at_prior) {
  if (!inputs_finite(primitive, common, observation_px, view, config, at_prior)) return Status::kNonFiniteInput;
  return spd3(primitive.Sigma_world) ? Status::kOk : Status::kNotSpd;
}

bool short_form_trusted(const Eigen::Matrix3d& Sigma_new, const Eigen::Matrix3d& Sigma_prior) {
  constexpr double kKeptFraction = 1e-6;
  return Sigma_new(0, 0) >= kKeptFraction * Sigma_prior(0, 0) && Sigma_new(1, 1) >= kKeptFraction * Sigma_prior(1, 1) &&
         Sigma_new(2, 2) >= kKeptFraction * Sigma_prior(2, 2) && spd3_symmetrized(Sigma_new);
}

}  // namespace update_checks

namespace {

// v^T Sigma^-1 v for a symmetric positive definite 3x3 (spd3 holds): the adjugate's quadratic form over
// the determinant, without forming the inverse.
double mahalanobis_squared(const Eigen::Matrix3d& Sigma, const Eigen::Vector3d& v) {
  const double c00 = Sigma(1, 1) * Sigma(2, 2) - Sigma(1, 2) * Sigma(1, 2);
  const double c01 = Sigma(0, 2) * Sigma(1, 2) - Sigma(0, 1) * Sigma(2, 2);
  const double c02 = Sigma(0, 1) * Sigma(1, 2) - Sigma(0, 2) * Sigma(1, 1);
  const double c11 = Sigma(0, 0) * Sigma(2, 2) - Sigma(0, 2) * Sigma(0, 2);
  const double c12 = Sigma(0, 1) * Sigma(0, 2) - Sigma(0, 0) * Sigma(1, 2);
  const double c22 = Sigma(0, 0) * Sigma(1, 1) - Sigma(0, 1) * Sigma(0, 1);
  const double det = Sigma(0, 0) * c00 + Sigma(0, 1) * c01 + Sigma(0, 2) * c02;
  const double quadratic = c00 * v.x() * v.x() + c11 * v.y() * v.y() + c22 * v.z() * v.z() +
                           2.0 * (c01 * v.x() * v.y() + c02 * v.x() * v.z() + c12 * v.y() * v.z());
  return quadratic / det;
}

// Joseph-form covariance for gain K at H, valid for any K (consider form, see the header): the fallback
// when Sigma - K G^T cancels to a matrix that is not positive definite.
[[gnu::noinline]] Eigen::Matrix3d joseph_covariance(const Eigen::Matrix<double, 3, 2>& K,
                                                   const Eigen::Matrix<double, 2, 3>& H, const Eigen::Matrix3d& Sigma,
                                                   const Eigen::Matrix<double, 3, 2>& CB,
                                                   const Eigen::Matrix2d& R_total) {
  const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
  const Eigen::Matrix3d mixed = I_KH * CB * K.transpose();
  const Eigen::Matrix3d joseph = I_KH * Sigma * I_KH.transpose() + K * R_total * K.transpose();
  return joseph + mixed + mixed.transpose();
}

// C' = (I - KH) C + K B P_c, for the whole common error or one part of it.
[[gnu::noinline]] Eigen::Matrix<double, 3, 2> updated_cross_covariance(const Eigen::Matrix<double, 3, 2>& K,
                                                                       const Eigen::Matrix<double, 2, 3>& H,
                                                                       const Eigen::Matrix<double, 3, 2>& C,
                                                                       const Eigen::Matrix2d& B,
                                                                       const Eigen::Matrix2d& P_c) {
  const Eigen::Matrix<double, 3, 2> kept = C - K * (H * C);
  return kept + K * (B * P_c);
}

// The posterior covariance for K, the last linearization point's own gain (G = K S): Sigma - K G^T, or
// the Joseph form where that short form is not to be trusted (see consider_update). False when neither is
// positive definite.
[[gnu::noinline]] bool updated_covariance(const Eigen::Matrix<double, 3, 2>& K, const Eigen::Matrix<double, 3, 2>& G,
                                          const Eigen::Matrix<double, 2, 3>& H, const Eigen::Matrix3d& Sigma,
                                          const Eigen::Matrix<double, 3, 2>& CB, const Eigen::Matrix2d& R_total,
                                          Eigen::Matrix3d* Sigma_new) {
  const Eigen::Matrix3d shortened = Sigma - K * G.transpose();
  *Sigma_new = 0.5 * (shortened + shortened.transpose());
  if (update_checks::short_form_trusted(*Sigma_new, Sigma)) return true;
  const Eigen::Matrix3d joseph = joseph_covariance(K, H, Sigma, CB, R_total);
  *Sigma_new = 0.5 * (joseph + joseph.transpose());
  return spd3_symmetrized(*Sigma_new);
}

Status consider_update(Primitive& primitive, CommonObservationError* common, const Eigen::Vector2d& observation_px,
                       const Viewpoint& view, const PinholeIntrinsics& intrinsics, const EkfConfig& config,
                       int max_iterations, const ProjectionAtPrior* at_prior, EkfStats* stats) {
  EkfStats ignored;
  EkfStats& counts = stats != nullptr ? *stats : ignored;
  const Status inputs = update_checks::check_inputs(primitive, *common, observation_px, view, config, at_prior);
  if (!ok(inputs)) {
    ++counts.rejected_inputs;
    return inputs;
  }
  const Eigen::Vector3d X0 = primitive.X_world;
  const Eigen::Matrix3d& Sigma = primitive.Sigma_world;
  const Eigen::Matrix<double, 3, 2> CB = common->cross_covariance * common->B.transpose();  // C B^T
  const Eigen::Matrix2d R_total = common->projected_px2() + config.R_px2;
  // Gauss-Newton on the MAP cost: linearize at X (one projection per pass, so the frame stays small under
  // ASan), gate on the first pass (at the prior). It stops when a step is negligible against the prior's
  // spread (Mahalanobis length below kStepSigmas: H and K at the point it started from are then those at
  // the estimate, to that fraction of a standard deviation), or after max_iterations steps with a last
  // linearization at the estimate.
  constexpr double kStepSigmas = 1e-3;
  const int iterations = max_iterations < 1 ? 1 : max_iterations;
  Eigen::Vector3d X = X0;
  Eigen::Vector2d predicted;
  Eigen::Matrix<double, 2, 3> H;
  Eigen::Matrix2d S_inv;
  Eigen::Matrix<double, 3, 2> K;
  Eigen::Matrix<double, 3, 2> G;
  for (int iteration = 0;; ++iteration) {
    if (iteration == 0 && at_prior != nullptr) {
      predicted = at_prior->predicted_px;
      H = at_prior->H;
    } else if (!ok(project_with_jacobian(X, view, intrinsics, &predicted, &H))) {
      ++counts.rejected_inputs;
      return Status::kBehindCamera;
    }
    if (!innovation_gain(H, Sigma, CB, R_total, &S_inv, &K, &G)) {
      ++counts.rejected_inputs;
      return Status::kNotSpd;
    }
    if (iteration == 0) {
      const Eigen::Vector2d innovation = observation_px - predicted;
      const double nis = innovation.dot(S_inv * innovation);
      counts.nis.record(nis);
      if (!(nis <= config.gate_chi2)) {
        ++counts.gated_outliers;
        return Status::kGatedOutlier;
      }
    }
    if (iteration == iterations) break;
    const Eigen::Vector3d step = X0 + K * (observation_px - predicted - H * (X0 - X)) - X;
    X += step;
    // The first step is the EKF's own; the later ones are the relinearization's corrections.
    if (iteration == 0) continue;
    if (mahalanobis_squared(Sigma, step) <= kStepSigmas * kStepSigmas) break;
  }
  // H and K are those at the last linearization point, and K is that point's own gain, for which the
  // Joseph form equals Sigma - K S K^T = Sigma - K G^T (expand it with K S = G): a sixth of the products.
  // Its subtraction cancels where an observation pins a long axis down: its rounding, eps times the
  // prior's variance, stays small against the result only while every axis keeps at least that
  // fraction of its prior variance; otherwise (and when the result is not positive definite) the Joseph
  // form, a sum of positive semidefinite terms without the consider part.
  Eigen::Matrix3d Sigma_new;
  const bool positive_definite = updated_covariance(K, G, H, Sigma, CB, R_total, &Sigma_new);
  const Eigen::Matrix<double, 3, 2> cross =
      updated_cross_covariance(K, H, common->cross_covariance, common->B, common->covariance_px2);
  const Eigen::Matrix<double, 3, 2> part_cross =
      common->has_part
          ? updated_cross_covariance(K, H, common->part_cross_covariance, common->B, common->part_covariance_px2)
          : common->part_cross_covariance;
  if (!X.allFinite() || !cross.allFinite() || !part_cross.allFinite() || !positive_definite) {
    ++counts.rejected_inputs;
    return Status::kNotSpd;
  }
  primitive.X_world = X;
  primitive.Sigma_world = Sigma_new;
  common->cross_covariance = cross;
  common->part_cross_covariance = part_cross;
  ++primitive.observation_count;
  ++counts.accepted;
  return Status::kOk;
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
  return consider_update(primitive, common, observation_px, view, intrinsics, config, max_iterations, nullptr, stats);
}

Status iterated_consider_update(Primitive& primitive, CommonObservationError* common, const Eigen::Vector2d& observation_px,
                                const Viewpoint& view, const PinholeIntrinsics& intrinsics, const EkfConfig& config,
                                int max_iterations, const ProjectionAtPrior& at_prior, EkfStats* stats) {
  return consider_update(primitive, common, observation_px, view, intrinsics, config, max_iterations, &at_prior, stats);
}

}  // namespace vantage
