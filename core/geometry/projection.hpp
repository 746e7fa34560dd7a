#pragma once
// The collinearity observation function phi(X, nu) of the paper (section III) and its analytic
// Jacobian H = d phi / d X_world (2x3), both in pixels, with the intrinsics' radial distortion.
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"

namespace vantage {

// Points closer than this to the image plane (in camera z, scene units) count as behind the camera.
inline constexpr double kMinDepth = 1e-6;

// uv_px = phi(X_world, nu). kBehindCamera when the point is not in front of the camera. Does not check
// the image bounds (see in_image).
Status project(const Eigen::Vector3d& X_world, const Viewpoint& view, const PinholeIntrinsics& intrinsics,
               Eigen::Vector2d* uv_px);

// phi and H together (H is evaluated at X_world). kBehindCamera as for project.
Status project_with_jacobian(const Eigen::Vector3d& X_world, const Viewpoint& view,
                             const PinholeIntrinsics& intrinsics, Eigen::Vector2d* uv_px,
                             Eigen::Matrix<double, 2, 3>* H_px_per_unit);

// project_with_jacobian for up to kProjectionBatchSize points seen from one view, four at a time in AVX
// lanes where the CPU has AVX2 (x86-64; elsewhere one by one): each lane does the scalar function's
// operations in the order Eigen evaluates them (its 3-term products as a0 b0 + (a1 b1 + a2 b2) in the
// Jacobian's last factor, (a0 b0 + a1 b1) + a2 b2 in the camera-frame point, the zeros of the diagonal
// and normalization factors multiplied as Eigen does; no FMA), so the same bits on x86-64 (core test).
// X_world, uv_px, H_px_per_unit and status hold count (<= kProjectionBatchSize) entries; uv and H are
// written only where status[i] is kOk.
inline constexpr std::int32_t kProjectionBatchSize = 4;
void project_with_jacobian_batch(const Eigen::Vector3d* const* X_world, std::int32_t count, const Viewpoint& view,
                                 const PinholeIntrinsics& intrinsics, Eigen::Vector2d* uv_px,
                                 Eigen::Matrix<double, 2, 3>* H_px_per_unit, Status* status);

// True when uv lies inside the image with the given margin (pixels) on every side.
bool in_image(const Eigen::Vector2d& uv_px, const PinholeIntrinsics& intrinsics, double margin_px = 0.0);

// The viewing ray through pixel uv (undistorted by fixed-point iteration), unit length, world frame.
Eigen::Vector3d back_project_ray_world(const Eigen::Vector2d& uv_px, const Viewpoint& view,
                                       const PinholeIntrinsics& intrinsics);

}  // namespace vantage
