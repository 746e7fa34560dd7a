#include "hal/mavlink/ned_frame.hpp"

#include <cmath>

namespace vantage::hal::mavlink {

bool heading_and_tilt(const Viewpoint& view, double* yaw_ned_rad, double* tilt_rad) {
  const Eigen::Vector3d axis = view.R_world_cam.col(2);
  if (!axis.allFinite() || axis.norm() < 1e-9) return false;
  const Eigen::Vector3d unit = axis.normalized();
  const double horizontal = std::hypot(unit.x(), unit.y());
  if (horizontal < std::sin(1.0 * M_PI / 180.0)) return false;
  // ENU axis (e, n, u): NED yaw = atan2(east, north).
  *yaw_ned_rad = std::atan2(unit.x(), unit.y());
  *tilt_rad = std::atan2(-unit.z(), horizontal);
  return true;
}

Viewpoint viewpoint_from(const Eigen::Vector3d& position_world, double yaw_ned_rad, double tilt_rad) {
  const double c = std::cos(tilt_rad);
  const Eigen::Vector3d z_cam(c * std::sin(yaw_ned_rad), c * std::cos(yaw_ned_rad), -std::sin(tilt_rad));
  // Camera x (image right) is horizontal, to the right of the heading; y (image down) completes the frame.
  const Eigen::Vector3d x_cam(std::cos(yaw_ned_rad), -std::sin(yaw_ned_rad), 0.0);
  const Eigen::Vector3d y_cam = z_cam.cross(x_cam);
  Viewpoint view;
  view.position_world = position_world;
  view.R_world_cam.col(0) = x_cam;
  view.R_world_cam.col(1) = y_cam;
  view.R_world_cam.col(2) = z_cam;
  return view;
}

}  // namespace vantage::hal::mavlink
