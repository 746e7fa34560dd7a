#include "core/geometry/viewpoint.hpp"

#include <cmath>

namespace vantage {

Status Viewpoint::validate() const {
  if (!position_world.allFinite() || !R_world_cam.allFinite()) return Status::kNonFiniteInput;
  const double orthogonality_error = (R_world_cam.transpose() * R_world_cam - Eigen::Matrix3d::Identity()).norm();
  if (orthogonality_error > 1e-6 || std::abs(R_world_cam.determinant() - 1.0) > 1e-6) {
    return Status::kInvalidArgument;
  }
  return Status::kOk;
}

Status look_at(const Eigen::Vector3d& position_world, const Eigen::Vector3d& target_world,
               const Eigen::Vector3d& up_world, Viewpoint* out) {
  if (!position_world.allFinite() || !target_world.allFinite() || !up_world.allFinite()) {
    return Status::kNonFiniteInput;
  }
  const Eigen::Vector3d forward = target_world - position_world;
  if (forward.norm() < 1e-12) return Status::kInvalidArgument;
  const Eigen::Vector3d z_cam = forward.normalized();
  // Image x (right) is forward x up; image y (down) then completes a right-handed frame: y = z x x.
  const Eigen::Vector3d x_raw = z_cam.cross(up_world);
  if (x_raw.norm() < 1e-9) return Status::kInvalidArgument;
  const Eigen::Vector3d x_cam = x_raw.normalized();
  const Eigen::Vector3d y_cam = z_cam.cross(x_cam);
  out->position_world = position_world;
  out->R_world_cam.col(0) = x_cam;
  out->R_world_cam.col(1) = y_cam;
  out->R_world_cam.col(2) = z_cam;
  return Status::kOk;
}

}  // namespace vantage
