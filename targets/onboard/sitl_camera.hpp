#pragma once
// SITL only (host builds with the simulator): the sim_hal ray-cast camera rendering the scene at the pose
// the vehicle reports over MAVLink (hal::Motion::current_pose), through sim_hal's SimPoseSource.
#include <string>

#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/motion.hpp"

namespace vantage::onboard {

// Builds the scene (the paper's bunny when scene_path is empty) and the camera once; *camera stays valid
// for the life of the process. Empty string on success, else one line.
std::string open_sim_camera(const std::string& scene_path, const hal::Motion& motion, const hal::Clock& clock,
                            hal::Camera** camera);

}  // namespace vantage::onboard
