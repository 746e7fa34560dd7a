#include "core/frontend/surface_fit.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>

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
    *tilt_variance = s2 / (count * lambda(1));
  }
  *normal = n.cast<float>();
  return true;
}

}  // namespace

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
  constexpr double kMinCos = 0.2588190451;  // cos 75 degrees
  const double c = std::abs(cos_incidence) < kMinCos ? kMinCos : std::abs(cos_incidence);
  // Half the cell diagonal on a fronto-parallel plane, stretched by the incidence.
  return 0.5 * std::sqrt(2.0) * stride_px * depth / focal_px / c;
}

}  // namespace vantage
