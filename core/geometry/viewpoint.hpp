#pragma once
// A viewpoint nu = (x, theta): camera centre in the world frame and the camera's orientation.
// Frames: world is right-handed with z up (the grid plane is z = elevation); the camera frame is
// OpenCV's: x right, y down, z along the optical axis. R_world_cam's columns are the camera axes
// expressed in the world frame, so X_cam = R_world_cam^T (X_world - position_world).
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/common/status.hpp"

namespace vantage {

struct Viewpoint {
  Eigen::Vector3d position_world = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_world_cam = Eigen::Matrix3d::Identity();

  // kOk, kNonFiniteInput, or kInvalidArgument when R_world_cam is not a rotation (tolerance 1e-6).
  Status validate() const;
};

// A camera at position_world looking at target_world with image "up" as close to up_world as the
// geometry allows. kInvalidArgument when target equals position or the view is parallel to up.
Status look_at(const Eigen::Vector3d& position_world, const Eigen::Vector3d& target_world,
               const Eigen::Vector3d& up_world, Viewpoint* out);

}  // namespace vantage
