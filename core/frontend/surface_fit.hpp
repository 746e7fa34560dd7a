#pragma once
// A primitive's surface: its normal from a local plane fit of neighbouring primitives, and its radius
// from the pixel footprint at its depth.
#include <cstddef>
#include <limits>

#include <Eigen/Core>

#include "core/common/span.hpp"

namespace vantage {

struct PlaneFitConfig {
  std::size_t min_neighbours = 3;  // besides the centre
  double max_neighbour_distance = 1.0;  // scene units; farther neighbours lie across a depth edge
  double max_flatness = 0.1;  // smallest / middle eigenvalue of the scatter: above it, not a plane
  // The tilt variance is at least this times the fit's residual variance over the in-plane spread along the
  // narrower axis: what one point's residual says, not the average over all of them. Neighbours' errors
  // share views and a curved surface's residual is no noise, so neither averages away; without the floor
  // the bunny's refits claim 2-4 times too little and a mission's 9 times (EXPERIMENTS.md, "Session 25").
  // 0: off (the default: FrontEndConfig::normal_refit_residual_floor says what it does to the missions).
  double residual_tilt_floor = 0.0;
};

// The normal of the plane through centre and the neighbours (closer than max_neighbour_distance),
// oriented toward the camera at camera_world. False (normal untouched) when there are too few
// neighbours or they do not form a plane.
bool fit_plane_normal(const Eigen::Vector3d& centre, Span<const Eigen::Vector3d> neighbours,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal);

// The same fit with the normal's uncertainty: *tilt_variance (rad^2, each of the two tilt axes) bounds the
// covariance of the normal's tilt, s^2 / (sum over the points of their in-plane spread along the narrower
// axis), where s^2 is the larger of the points' mean out-of-plane variance n^T Sigma n and the fit's
// residual variance, and at least residual_tilt_floor times the residual variance over one point's spread.
// neighbour_Sigmas has one covariance per neighbour (false otherwise).
bool fit_plane_normal(const Eigen::Vector3d& centre, const Eigen::Matrix3d& centre_Sigma,
                      Span<const Eigen::Vector3d> neighbours, Span<const Eigen::Matrix3d> neighbour_Sigmas,
                      const Eigen::Vector3d& camera_world, const PlaneFitConfig& config, Eigen::Vector3f* normal,
                      double* tilt_variance);

// The plane fit for points whose errors lie along the rays from camera_world (a new primitive's depth
// error is many times its lateral one, and grows with depth): the plane q . (X - camera) = 1 fitted to
// the inverse distances along the points' rays by weighted least squares, each weighted by its variance
// along its ray (r^T Sigma r); a lateral error is taken as none. The rays are then exact regressors, so
// the fit is linear and its covariance honest, where an eigenvector fit of the scatter is tilted by
// noise that is not along the normal. Its chi^2 (count - 3 dof) tells a plane from a depth edge or a
// scatter: above max_chi2_per_dof, the neighbour with the largest weighted residual is dropped and the
// fit repeated, up to max_dropped times; still above, false. *tilt_variance is the largest eigenvalue
// of the unit normal's covariance, scaled by chi^2 / dof when that exceeds 1 (curvature counts like
// noise), and at least residual_tilt_floor times the residual over one point's spread. Unlike
// fit_plane_normal's scatter-ratio test, a noisy but planar neighbourhood gives a normal
// with a large variance instead of none. False (outputs untouched) with fewer than min_neighbours
// neighbours within max_neighbour_distance, more than kMaxRayPlaneFitPoints points, a neighbour_Sigmas
// count other than the neighbours', a non-finite centre, or a singular fit.
struct RayPlaneFitConfig {
  std::size_t min_neighbours = 3;  // besides the centre
  double max_neighbour_distance = 1.0;  // scene units
  double max_chi2_per_dof = 4.0;
  std::size_t max_dropped = 4;
  // The tilt variance is at least this times the fit's residual variance (distances out of the plane, the
  // centre's too) over the in-plane spread along the narrower axis, as PlaneFitConfig::residual_tilt_floor:
  // the chi^2 scaling reads the residuals against the points' noise, so a neighbourhood of well-known points
  // (a new primitive beside tracked ones) that is curved or rough at the patch's scale still claims a tilt
  // known to a degree or two. 0: off (this struct's default; the front end passes
  // FrontEndConfig::normal_spawn_residual_floor, 1 by default).
  double residual_tilt_floor = 0.0;
  // With the floor on, a claim at or above this (rad^2) is lowered to 0.99 of it: the front end passes the
  // facing prior's variance, since a normal replaces one only by claiming less, and a fitted normal is
  // still far closer to the surface's than the prior (5-17 degrees against 30-60, EXPERIMENTS.md, "Session
  // 26"); without the limit the floor left the 60-degree 640x480 plane's primitives on the prior (153 -> 418).
  double floored_claim_limit = std::numeric_limits<double>::infinity();
};
inline constexpr std::size_t kMaxRayPlaneFitPoints = 64;  // centre included

bool fit_plane_normal_along_rays(const Eigen::Vector3d& centre, const Eigen::Matrix3d& centre_Sigma,
                                 Span<const Eigen::Vector3d> neighbours, Span<const Eigen::Matrix3d> neighbour_Sigmas,
                                 const Eigen::Vector3d& camera_world, const RayPlaneFitConfig& config,
                                 Eigen::Vector3f* normal, double* tilt_variance);

// The steepest incidence a footprint is stretched for: cos 75 degrees.
inline constexpr double kFootprintMinCosIncidence = 0.2588190451;

// Radius of the disc that covers one stride x stride pixel cell at camera depth depth, on a plane whose
// normal makes angle acos(cos_incidence) with the viewing ray (incidence clamped at 75 degrees,
// kFootprintMinCosIncidence).
double footprint_radius(double stride_px, double depth, double focal_px, double cos_incidence);

}  // namespace vantage
