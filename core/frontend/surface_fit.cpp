#include "core/frontend/surface_fit.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>

namespace vantage {

bool fit_plane_normal(const Eigen::Vector3d& centre, Span<const Eigen::Vector3d> neighbours,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal) {
  Eigen::Vector3d sum = centre;
  Eigen::Matrix3d outer = centre * centre.transpose();
  std::size_t used = 0;
  for (const Eigen::Vector3d& X : neighbours) {
    if (!X.allFinite() || (X - centre).norm() > config.max_neighbour_distance) continue;
    sum += X;
    outer += X * X.transpose();
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
  *normal = n.cast<float>();
  return true;
}

double footprint_radius(double stride_px, double depth, double focal_px, double cos_incidence) {
  constexpr double kMinCos = 0.2588190451;  // cos 75 degrees
  const double c = std::abs(cos_incidence) < kMinCos ? kMinCos : std::abs(cos_incidence);
  // Half the cell diagonal on a fronto-parallel plane, stretched by the incidence.
  return 0.5 * std::sqrt(2.0) * stride_px * depth / focal_px / c;
}

}  // namespace vantage
