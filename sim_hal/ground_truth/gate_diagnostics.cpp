#include "sim_hal/ground_truth/gate_diagnostics.hpp"

#include <algorithm>
#include <cmath>

#include "core/frontend/patch_warp.hpp"
#include "core/geometry/projection.hpp"

namespace vantage::sim {

namespace {
constexpr double kChi2Dof2Q95 = 5.991464547107979;

// (d.e)^2 / d^T Sigma d: the part of e^T Sigma^-1 e along the unit direction d (1 dof).
double one_dof_nees(const Eigen::Vector3d& d, const Eigen::Vector3d& e, const Eigen::Matrix3d& Sigma) {
  return d.dot(e) * d.dot(e) / d.dot(Sigma * d);
}

// The bin of the view change between a primitive's consecutive correct matches (kLagBinNames).
int lag_bin(double lag_deg) {
  int bin = 0;
  for (double edge : {1.0, 2.0, 4.0, 8.0, 16.0, 32.0}) bin += lag_deg >= edge ? 1 : 0;
  return bin;
}
constexpr const char* kLagBinNames[] = {"0-1", "1-2", "2-4", "4-8", "8-16", "16-32", "32+"};
// The bin of r - 1 (kDeformationBinNames).
int deformation_bin(double r) {
  int bin = 0;
  for (double edge : {0.05, 0.1, 0.2, 0.4, 0.7, 1.0}) bin += r - 1.0 >= edge ? 1 : 0;
  return bin;
}
constexpr const char* kDeformationBinNames[] = {"0-0.05", "0.05-0.1", "0.1-0.2", "0.2-0.4", "0.4-0.7", "0.7-1", "1+"};

// The angle between two unit vectors, in degrees.
double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / M_PI;
}
}  // namespace

Eigen::Vector2d nearest_seed_px(const Eigen::Vector2d& uv_px, double stride_px) {
  const double half = std::floor(stride_px / 2.0);
  return Eigen::Vector2d(std::round((uv_px.x() - half) / stride_px) * stride_px + half,
                         std::round((uv_px.y() - half) / stride_px) * stride_px + half);
}

bool seed_px_of(const PinholeIntrinsics& intrinsics, std::int32_t stride_px, const Primitive& p,
                const Viewpoint& creating, Eigen::Vector2d* seed_px) {
  Eigen::Vector2d uv_creating;
  if (!ok(project(p.X_world, creating, intrinsics, &uv_creating))) return false;
  *seed_px = nearest_seed_px(uv_creating, stride_px);
  return true;
}

bool seed_true_point(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, std::int32_t stride_px,
                     const Primitive& p, const Viewpoint& creating, Eigen::Vector3d* X_true) {
  Eigen::Vector2d seed;
  if (!seed_px_of(intrinsics, stride_px, p, creating, &seed)) return false;
  const Eigen::Vector3d ray = back_project_ray_world(seed, creating, intrinsics);
  const double t = scene.first_hit(creating.position_world, ray);
  if (!std::isfinite(t)) return false;
  *X_true = creating.position_world + t * ray;
  return true;
}

void GateDiagnostics::on_observation(const TrackedObservation& o) {
  const bool gated = o.outcome == Status::kGatedOutlier;
  if (!gated && !ok(o.outcome)) return;
  Bucket& b = gated ? gated_ : accepted_;
  b.observations += 1;
  const Primitive& p = o.prior;
  const PinholeIntrinsics& k = intrinsics_;
  Eigen::Vector3d X_true;
  Eigen::Vector2d uv_true;
  Eigen::Vector2d predicted;
  Eigen::Matrix<double, 2, 3> H;
  if (!seed_true_point(scene_, k, stride_px_, p, o.creating_view, &X_true) || !ok(project(X_true, o.view, k, &uv_true)) ||
      !ok(project_with_jacobian(p.X_world, o.view, k, &predicted, &H))) {
    b.no_truth += 1;
    return;
  }
  const Eigen::Vector3d to_truth = X_true - o.view.position_world;
  if (scene_.first_hit(o.view.position_world, to_truth.normalized()) < to_truth.norm() - 0.05) {
    b.occluded += 1;
    return;
  }
  const Eigen::Vector2d match_error = o.observed_px - uv_true;
  ByDeformation& deformation = by_deformation_[deformation_bin(warp_stretch_ratio(o.B, kMaxDeformationStretchRatio))];
  deformation.observations += 1;
  if (match_error.norm() > 2.0) {
    b.wrong += 1;
    return;
  }
  if (match_error.norm() > 1.0) {
    b.off += 1;
    return;
  }
  b.correct += 1;
  deformation.correct += 1;
  deformation.error_sq += match_error.squaredNorm();
  deformation.R += o.R_px2.trace();
  deformation.common += (o.B * o.common_covariance_px2 * o.B.transpose()).trace();
  const Eigen::Vector3d e = p.X_world - X_true;
  const double prior_nees = e.dot(p.Sigma_world.ldlt().solve(e));
  const Eigen::Vector2d prior_error = uv_true - o.predicted_px;
  const double prior_chi2 = prior_error.dot((H * p.Sigma_world * H.transpose()).inverse() * prior_error);
  const Eigen::Matrix2d R_total = o.match_covariance_px2();
  const double match_chi2 = match_error.dot(R_total.inverse() * match_error);
  const Eigen::Vector3d from_creating = (o.creating_view.position_world - X_true).normalized();
  const Eigen::Vector3d from_view = (o.view.position_world - X_true).normalized();
  const double view_change_deg = angle_deg(from_creating, from_view);
  b.prior_nees += prior_nees;
  b.prior_chi2 += prior_chi2;
  b.prior_chi2_tail += prior_chi2 > kChi2Dof2Q95 ? 1 : 0;
  b.match_chi2 += match_chi2;
  b.match_chi2_tail += match_chi2 > kChi2Dof2Q95 ? 1 : 0;
  b.error_px += match_error.norm();
  b.angle_deg += view_change_deg;
  b.young += p.observation_count < 3 ? 1 : 0;
  ByCount& c = by_count_[std::min<std::uint32_t>(5, p.observation_count / 4)];
  c.observations += 1;
  c.gated += gated ? 1 : 0;
  c.prior_nees += prior_nees;
  // The prior NEES's 1-dof parts along the creating ray and along the true surface normal: the latter is
  // the error the surface model carries (the seed truth's lateral pin does not reach it).
  const Eigen::Vector3d seed_ray = (X_true - o.creating_view.position_world).normalized();
  c.prior_along_ray += one_dof_nees(seed_ray, e, p.Sigma_world);
  std::uint32_t triangle = 0;
  if (std::isfinite(scene_.first_hit(o.creating_view.position_world, seed_ray, &triangle))) {
    const Eigen::Vector3d true_normal = scene_.mesh().triangle_normal(triangle);
    c.prior_along_normal += one_dof_nees(true_normal, e, p.Sigma_world);
    c.with_normal += 1;
  }
  Viewpoint spawn_other;
  if (p.observation_count == 0 && p.creating_view > 0 && ok(front_end_.view_pose(p.creating_view - 1, &spawn_other))) {
    const Eigen::Vector3d from_other = (spawn_other.position_world - X_true).normalized();
    const double baseline_deg = angle_deg(from_creating, from_other);
    ByCount& s = by_spawn_baseline_[std::min(5, static_cast<int>(baseline_deg / 2.0))];
    s.observations += 1;
    s.gated += gated ? 1 : 0;
    s.prior_nees += prior_nees;
  }
  PerPrimitive& q = primitives_[(static_cast<std::uint64_t>(o.index) << 32) | p.creating_view];
  const Eigen::Matrix2d A = o.B.inverse();
  const Eigen::Vector2d in_creating = A * match_error;
  q.matches += 1;
  q.sum += in_creating;
  q.sum_sq += in_creating * in_creating.transpose();
  q.P_c += o.common_covariance_px2;
  q.R += A * o.R_px2 * A.transpose();
  q.angle_deg += view_change_deg;
  // The error's correlation between this match and the primitive's previous correct one, by the view change.
  if (q.matches > 1) {
    Lag& lag = lags_[lag_bin(angle_deg(q.last_from_view, from_view))];
    lag.pairs += 1;
    lag.product += in_creating.dot(q.last_error);
    lag.square += 0.5 * (in_creating.squaredNorm() + q.last_error.squaredNorm());
  }
  q.last_error = in_creating;
  q.last_from_view = from_view;
}

void GateDiagnostics::print_bucket(std::FILE* out, const char* name, const Bucket& b) {
  const double n = std::max(1.0, b.correct);
  std::fprintf(out,
               "gate diagnostics, %s: %.0f observations: no truth %.0f, occluded %.0f, wrong (> 2 px) %.0f, off (1-2 px) "
               "%.0f, correct (<= 1 px) %.0f; of the correct: prior NEES %.2f (3), prior chi2 %.2f (2, above q95 %.3f), "
               "match chi2 %.2f (2, above q95 %.3f), mean error %.3f px, view change %.1f deg, < 3 updates %.3f\n",
               name, b.observations, b.no_truth, b.occluded, b.wrong, b.off, b.correct, b.prior_nees / n, b.prior_chi2 / n,
               b.prior_chi2_tail / n, b.match_chi2 / n, b.match_chi2_tail / n, b.error_px / n, b.angle_deg / n, b.young / n);
}

void GateDiagnostics::print(std::FILE* out) const {
  print_bucket(out, "gated", gated_);
  print_bucket(out, "accepted", accepted_);
  for (int i = 0; i < 6; ++i) {
    const ByCount& c = by_count_[i];
    const double n = std::max(1.0, c.observations);
    if (i < 5) {
      std::fprintf(
          out, "gate diagnostics, correct matches of primitives with %d-%d updates: %.0f, gated %.3f, prior NEES %.2f",
          4 * i, 4 * i + 3, c.observations, c.gated / n, c.prior_nees / n);
    } else {
      std::fprintf(
          out, "gate diagnostics, correct matches of primitives with %d+ updates: %.0f, gated %.3f, prior NEES %.2f",
          4 * i, c.observations, c.gated / n, c.prior_nees / n);
    }
    std::fprintf(out, " (3), along the creating ray %.2f (1), along the true normal %.2f (1)\n", c.prior_along_ray / n,
                 c.prior_along_normal / std::max(1.0, c.with_normal));
  }
  for (int i = 0; i < 6; ++i) {
    const ByCount& c = by_spawn_baseline_[i];
    const double n = std::max(1.0, c.observations);
    std::fprintf(out, "gate diagnostics, first re-observations (correct), spawn baseline %d%s deg: %.0f, gated %.3f, prior NEES %.2f\n",
                 2 * i, i < 5 ? "-" : "+", c.observations, c.gated / n, c.prior_nees / n);
  }
  // Consecutive correct matches of a primitive (creating image, px^2 over both axes): a white error gives a
  // correlation near 0, one common to every match near 1 at every view change.
  for (int i = 0; i < kLagBins; ++i) {
    const Lag& lag = lags_[i];
    const double n = std::max(1.0, lag.pairs);
    std::fprintf(out,
                 "gate diagnostics, consecutive correct matches %s deg apart: %.0f pairs, mean e_k . e_k-1 %.4f, "
                 "mean |e|^2 %.4f, correlation %.3f\n",
                 kLagBinNames[i], lag.pairs, lag.product / n, lag.square / n,
                 lag.product / std::max(1e-12, lag.square));
  }
  // By how unevenly the warp stretches the reference patch (r, the ratio of its singular values): the
  // correct matches' squared error against what the filter modelled (both axes, this image, px^2).
  for (int i = 0; i < kDeformationBins; ++i) {
    const ByDeformation& d = by_deformation_[i];
    const double n = std::max(1.0, d.correct);
    std::fprintf(out,
                 "gate diagnostics, warp singular value ratio - 1 %s: %.0f observations with a truth, correct %.3f; "
                 "of the correct: mean |e|^2 %.4f px^2, modelled R %.4f, common %.4f\n",
                 kDeformationBinNames[i], d.observations, d.correct / std::max(1.0, d.observations), d.error_sq / n,
                 d.R / n, d.common / n);
  }
  // Per primitive (>= 5 correct matches): the mean error's spread (common to its matches) and the spread
  // about it, in the creating image, against what the filter assumed (P_c and R taken back by B^-1); all
  // primitives, then by their matches' mean view change from the creating view (< 15, 15-30, > 30 deg).
  const char* names[4] = {"all", "view change < 15 deg", "view change 15-30 deg", "view change > 30 deg"};
  for (int group = 0; group < 4; ++group) {
    double primitives = 0, matches = 0;
    Eigen::Matrix2d common = Eigen::Matrix2d::Zero(), varying = Eigen::Matrix2d::Zero();
    Eigen::Matrix2d P_c = Eigen::Matrix2d::Zero(), R = Eigen::Matrix2d::Zero();
    for (const auto& entry : primitives_) {
      const PerPrimitive& q = entry.second;
      if (q.matches < 5) continue;
      const double angle = q.angle_deg / q.matches;
      if ((group == 1 && !(angle < 15.0)) || (group == 2 && !(angle >= 15.0 && angle < 30.0)) ||
          (group == 3 && !(angle >= 30.0))) {
        continue;
      }
      const Eigen::Vector2d mean = q.sum / q.matches;
      const Eigen::Matrix2d spread = (q.sum_sq - q.matches * mean * mean.transpose()) / (q.matches - 1);
      common += mean * mean.transpose() - spread / q.matches;
      varying += spread;
      P_c += q.P_c / q.matches;
      R += q.R / q.matches;
      primitives += 1;
      matches += q.matches;
    }
    const double n = std::max(1.0, primitives);
    std::fprintf(out,
                 "gate diagnostics, match error per axis (creating image, px^2; %s: %.0f primitives, %.0f correct "
                 "matches): common to a primitive's matches %.4f / %.4f (modelled P_c %.4f / %.4f), varying %.4f / "
                 "%.4f (modelled R %.4f / %.4f)\n",
                 names[group], primitives, matches, common(0, 0) / n, common(1, 1) / n, P_c(0, 0) / n, P_c(1, 1) / n,
                 varying(0, 0) / n, varying(1, 1) / n, R(0, 0) / n, R(1, 1) / n);
  }
}

}  // namespace vantage::sim
