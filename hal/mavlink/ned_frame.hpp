#pragma once
// vantage's world frame (right-handed, z up) against the vehicle's MAV_FRAME_LOCAL_NED (x north, y
// east, z down). The world is taken as ENU: world x = east, world y = north, world z = up, with its
// origin at world_origin_ned in the vehicle's local frame. So
//   ned = world_origin_ned + (y_world, x_world, -z_world).
// Heading (NED yaw) is measured from north toward east; the camera's optical axis gives it. The camera
// tilt (angle of the optical axis below the horizon) is not a vehicle state over this link: a gimbal or a
// fixed mount holds it, and the reported pose uses the tilt of the last command (see README.md).
#include <Eigen/Core>

#include "core/geometry/viewpoint.hpp"

namespace vantage::hal::mavlink {

struct NedFrame {
  Eigen::Vector3d world_origin_ned = Eigen::Vector3d::Zero();  // m

  Eigen::Vector3d ned_from_world(const Eigen::Vector3d& p_world) const {
    return world_origin_ned + Eigen::Vector3d(p_world.y(), p_world.x(), -p_world.z());
  }
  Eigen::Vector3d world_from_ned(const Eigen::Vector3d& p_ned) const {
    const Eigen::Vector3d d = p_ned - world_origin_ned;
    return Eigen::Vector3d(d.y(), d.x(), -d.z());
  }
};

// Heading (rad, NED yaw) and tilt (rad, positive below the horizon) of a viewpoint's optical axis.
// false when the axis is within ~1 degree of vertical (no heading) or not finite.
bool heading_and_tilt(const Viewpoint& view, double* yaw_ned_rad, double* tilt_rad);

// The camera viewpoint at a world position with a heading and tilt (image up toward world up).
Viewpoint viewpoint_from(const Eigen::Vector3d& position_world, double yaw_ned_rad, double tilt_rad);

}  // namespace vantage::hal::mavlink
