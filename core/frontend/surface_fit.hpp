#pragma once
// A primitive's surface: its normal from a local plane fit of neighbouring primitives, and its radius
// from the pixel footprint at its depth.
#include <cstddef>

#include <Eigen/Core>

#include "core/common/span.hpp"

namespace vantage {

struct PlaneFitConfig {
  std::size_t min_neighbours = 3;  // besides the centre
  double max_neighbour_distance = 1.0;  // scene units; farther neighbours lie across a depth edge
  double max_flatness = 0.1;  // smallest / middle eigenvalue of the scatter: above it, not a plane
};

// The normal of the plane through centre and the neighbours (closer than max_neighbour_distance),
// oriented toward the camera at camera_world. False (normal untouched) when there are too few
// neighbours or they do not form a plane.
bool fit_plane_normal(const Eigen::Vector3d& centre, Span<const Eigen::Vector3d> neighbours,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal);

// The same fit with the normal's uncertainty: *tilt_variance (rad^2, each of the two tilt axes) bounds the
// covariance of the normal's tilt, s^2 / (sum over the points of their in-plane spread along the narrower
// axis), where s^2 is the larger of the points' mean out-of-plane variance n^T Sigma n and the fit's
// residual variance. neighbour_Sigmas has one covariance per neighbour (false otherwise).
bool fit_plane_normal(const Eigen::Vector3d& centre, const Eigen::Matrix3d& centre_Sigma,
                      Span<const Eigen::Vector3d> neighbours, Span<const Eigen::Matrix3d> neighbour_Sigmas,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal,
                      double* tilt_variance);

// Radius of the disc that covers one stride x stride pixel cell at camera depth depth, on a plane whose
// normal makes angle acos(cos_incidence) with the viewing ray (incidence clamped at 75 degrees).
double footprint_radius(double stride_px, double depth, double focal_px, double cos_incidence);

}  // namespace vantage
