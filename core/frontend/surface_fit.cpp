#include "core/frontend/surface_fit.hpp"

#include <array>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace vantage {

namespace {

// The plane fit of both overloads; Sigmas (same length as neighbours, or empty) give the tilt variance.
bool fit_plane(const Eigen::Vector3d& centre, const Eigen::Matrix3d* centre_Sigma, Span<const Eigen::Vector3d> neighbours,
               Span<const Eigen::Matrix3d> neighbour_Sigmas, const Eigen::Vector3d& camera_world,
               const PlaneFitConfig& config, Eigen::Vector3f* normal, double* tilt_variance) {
  const bool with_sigmas = centre_Sigma != nullptr && neighbour_Sigmas.size() == neighbours.size();
  Eigen::Vector3d sum = centre;
  Eigen::Matrix3d outer = centre * centre.transpose();
  Eigen::Matrix3d sigma_sum = with_sigmas ? *centre_Sigma : Eigen::Matrix3d::Zero();
  std::size_t used = 0;
  for (std::size_t k = 0; k < neighbours.size(); ++k) {
    const Eigen::Vector3d& X = neighbours[k];
    if (!X.allFinite() || (X - centre).norm() > config.max_neighbour_distance) continue;
    sum += X;
    outer += X * X.transpose();
    if (with_sigmas) sigma_sum += neighbour_Sigmas[k];
    ++used;
  }
  if (used < config.min_neighbours) return false;
  const double count = static_cast<double>(used + 1);
  const Eigen::Vector3d mean = sum / count;
  const Eigen::Matrix3d scatter = outer / count - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  if (eigen.info() != Eigen::Success) return false;
  const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending
  if (!(lambda(1) > 0.0) || lambda(0) > config.max_flatness * lambda(1)) return false;
  Eigen::Vector3d n = eigen.eigenvectors().col(0).normalized();
  if (n.dot(camera_world - centre) < 0.0) n = -n;
  if (!n.allFinite()) return false;
  if (tilt_variance != nullptr) {
    // Least squares of a plane through points with out-of-plane variance s^2: the tilt's covariance is
    // s^2 (sum_k d_k d_k^T)^-1 over the in-plane offsets d_k from the centroid; its largest eigenvalue
    // is s^2 / (count * lambda_1). s^2 is the larger of what the points' covariances predict and what
    // the fit's residual shows (3 parameters fitted), so surface curvature counts as well as noise.
    const double predicted = with_sigmas ? n.dot(sigma_sum * n) / count : 0.0;
    const double residual = count > 3.0 ? count * lambda(0) / (count - 3.0) : lambda(1);
    const double s2 = predicted > residual ? predicted : residual;
    const double averaged = s2 / (count * lambda(1));
    const double floor = config.residual_tilt_floor * residual / lambda(1);
    *tilt_variance = averaged > floor ? averaged : floor;
  }
  *normal = n.cast<float>();
  return true;
}

// The plane q . X' = 1 through points X' = X - camera, fitted along the camera's rays: point k lies on
// its ray r_k (unit) at distance t_k, and the plane puts it at 1 / (q . r_k). With the error along the
// ray (a new primitive's depth), y_k = 1 / t_k is the noisy response and r_k an exact regressor, so the
// weighted least squares in q is linear and unbiased to first order; var(y_k) = (r_k^T Sigma_k r_k) / t_k^4.
struct RayPlaneFit {
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();  // sum_k w_k r_k r_k^T
  double chi2 = 0.0;
};

struct RayPoint {
  Eigen::Vector3d ray = Eigen::Vector3d::Zero();
  double inverse_distance = 0.0;
  double weight = 0.0;
};

bool ray_point(const Eigen::Vector3d& X, const Eigen::Matrix3d& Sigma, const Eigen::Vector3d& camera, RayPoint* out) {
  const Eigen::Vector3d offset = X - camera;
  const double t = offset.norm();
  if (!(t > 0.0) || !std::isfinite(t)) return false;
  out->ray = offset / t;
  out->inverse_distance = 1.0 / t;
  const double variance_t = out->ray.dot(Sigma * out->ray);
  const double variance_y = variance_t / (t * t * t * t);
  if (!(variance_y > 0.0) || !std::isfinite(variance_y)) return false;
  out->weight = 1.0 / variance_y;
  return true;
}

bool ray_plane_fit(const RayPoint* points, const bool* used, std::size_t count, RayPlaneFit* fit) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < count; ++k) {
    if (!used[k]) continue;
    information += points[k].weight * points[k].ray * points[k].ray.transpose();
    moment += points[k].weight * points[k].inverse_distance * points[k].ray;
  }
  const Eigen::LDLT<Eigen::Matrix3d> solver(information);
  if (solver.info() != Eigen::Success || !solver.isPositive()) return false;
  fit->q = solver.solve(moment);
  if (!fit->q.allFinite() || !(fit->q.norm() > 0.0)) return false;
  fit->information = information;
  fit->chi2 = 0.0;
  for (std::size_t k = 0; k < count; ++k) {
    if (!used[k]) continue;
    const double r = points[k].inverse_distance - fit->q.dot(points[k].ray);
    fit->chi2 += points[k].weight * r * r;
  }
  return std::isfinite(fit->chi2);
}

// The fit's residual variance (out of the plane q . X' = 1, 3 parameters fitted) over the in-plane spread
// of its points along the narrower axis: the tilt one point's residual says, which neither the points' own
// noise nor their count bounds (PlaneFitConfig::residual_tilt_floor's form). 0 when it is not defined.
// Not inlined: its Eigen temporaries in the caller's frame outgrow the core's 16 KB frame limit under ASan.
[[gnu::noinline]] double residual_over_spread(const RayPoint* points, const bool* used, std::size_t count, const Eigen::Vector3d& q) {
  const double q_norm = q.norm();
  const Eigen::Vector3d n = q / q_norm;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double residual_sum = 0.0;
  std::size_t in_fit = 0;
  for (std::size_t k = 0; k < count; ++k) {
    if (!used[k]) continue;
    const Eigen::Vector3d X = points[k].ray / points[k].inverse_distance;  // camera-relative
    const double h = (q.dot(X) - 1.0) / q_norm;
    mean += X;
    residual_sum += h * h;
    ++in_fit;
  }
  if (in_fit <= 3) return 0.0;
  mean /= static_cast<double>(in_fit);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < count; ++k) {
    if (!used[k]) continue;
    Eigen::Vector3d d = points[k].ray / points[k].inverse_distance - mean;
    d -= n * n.dot(d);
    scatter += d * d.transpose();
  }
  scatter /= static_cast<double>(in_fit);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> spread(scatter, Eigen::EigenvaluesOnly);
  if (spread.info() != Eigen::Success) return 0.0;
  const double lambda_1 = spread.eigenvalues()(1);  // (0) is the normal's, zero after the projection
  const double ratio = residual_sum / (static_cast<double>(in_fit) - 3.0) / lambda_1;
  return lambda_1 > 0.0 && std::isfinite(ratio) ? ratio : 0.0;
}

}  // namespace

bool fit_plane_normal_along_rays(const Eigen::Vector3d& centre, const Eigen::Matrix3d& centre_Sigma,
                                 Span<const Eigen::Vector3d> neighbours, Span<const Eigen::Matrix3d> neighbour_Sigmas,
                                 const Eigen::Vector3d& camera_world, const RayPlaneFitConfig& config,
                                 Eigen::Vector3f* normal, double* tilt_variance) {
  if (neighbour_Sigmas.size() != neighbours.size() || !centre.allFinite() || !centre_Sigma.allFinite()) return false;
  // The centre first (never dropped: the fit is for its normal), then the neighbours in reach.
  std::array<RayPoint, kMaxRayPlaneFitPoints> points;
  std::array<bool, kMaxRayPlaneFitPoints> used{};
  if (!ray_point(centre, centre_Sigma, camera_world, &points[0])) return false;
  used[0] = true;
  std::size_t count = 1;
  for (std::size_t k = 0; k < neighbours.size(); ++k) {
    const Eigen::Vector3d& X = neighbours[k];
    if (!X.allFinite() || !neighbour_Sigmas[k].allFinite() || !((X - centre).norm() <= config.max_neighbour_distance)) {
      continue;
    }
    if (count == kMaxRayPlaneFitPoints) return false;
    if (!ray_point(X, neighbour_Sigmas[k], camera_world, &points[count])) continue;
    used[count] = true;
    ++count;
  }
  std::size_t in_fit = count;
  if (in_fit < config.min_neighbours + 1) return false;
  RayPlaneFit fit;
  std::size_t dropped = 0;
  for (;;) {
    if (!ray_plane_fit(points.data(), used.data(), count, &fit)) return false;
    const double dof = static_cast<double>(in_fit) - 3.0;
    if (dof > 0.0 && fit.chi2 <= config.max_chi2_per_dof * dof) break;
    if (dropped == config.max_dropped || in_fit == config.min_neighbours + 1) return false;
    // The neighbour the plane explains worst leaves the fit.
    std::size_t worst = 0;
    double worst_residual = -1.0;
    for (std::size_t k = 1; k < count; ++k) {
      if (!used[k]) continue;
      const double r = points[k].inverse_distance - fit.q.dot(points[k].ray);
      if (points[k].weight * r * r > worst_residual) {
        worst_residual = points[k].weight * r * r;
        worst = k;
      }
    }
    if (worst == 0) return false;
    used[worst] = false;
    --in_fit;
    ++dropped;
  }
  // n = q / |q|: its covariance J Cov(q) J^T with J = (I - n n^T) / |q|, Cov(q) the inverse information
  // scaled by chi^2 / dof when the residuals exceed the points' own noise (curvature counts like noise).
  const double dof = static_cast<double>(in_fit) - 3.0;
  const double scale = fit.chi2 / dof > 1.0 ? fit.chi2 / dof : 1.0;
  const double q_norm = fit.q.norm();
  Eigen::Vector3d n = fit.q / q_norm;
  const Eigen::Matrix3d J = (Eigen::Matrix3d::Identity() - n * n.transpose()) / q_norm;
  const Eigen::Matrix3d covariance = scale * J * fit.information.inverse() * J.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(0.5 * (covariance + covariance.transpose()),
                                                               Eigen::EigenvaluesOnly);
  if (eigen.info() != Eigen::Success) return false;
  double variance = eigen.eigenvalues()(2);
  if (config.residual_tilt_floor > 0.0) {
    const double floor = config.residual_tilt_floor * residual_over_spread(points.data(), used.data(), count, fit.q);
    if (floor > variance) variance = floor;
    if (variance >= config.floored_claim_limit) variance = 0.99 * config.floored_claim_limit;
  }
  if (!(variance > 0.0) || !std::isfinite(variance) || !n.allFinite()) return false;
  if (n.dot(camera_world - centre) < 0.0) n = -n;
  *normal = n.cast<float>();
  *tilt_variance = variance;
  return true;
}

bool fit_plane_normal(const Eigen::Vector3d& centre, Span<const Eigen::Vector3d> neighbours,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal) {
  return fit_plane(centre, nullptr, neighbours, Span<const Eigen::Matrix3d>(), camera_world, config, normal, nullptr);
}

bool fit_plane_normal(const Eigen::Vector3d& centre, const Eigen::Matrix3d& centre_Sigma,
                      Span<const Eigen::Vector3d> neighbours, Span<const Eigen::Matrix3d> neighbour_Sigmas,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal,
                      double* tilt_variance) {
  if (neighbour_Sigmas.size() != neighbours.size()) return false;
  return fit_plane(centre, &centre_Sigma, neighbours, neighbour_Sigmas, camera_world, config, normal, tilt_variance);
}

double footprint_radius(double stride_px, double depth, double focal_px, double cos_incidence) {
  const double c = std::abs(cos_incidence) < kFootprintMinCosIncidence ? kFootprintMinCosIncidence
                                                                        : std::abs(cos_incidence);
  // Half the cell diagonal on a fronto-parallel plane, stretched by the incidence.
  return 0.5 * std::sqrt(2.0) * stride_px * depth / focal_px / c;
}

}  // namespace vantage
