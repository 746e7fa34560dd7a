#pragma once
// The onboard mission loop: core's SensingExecutive stepped with the configured camera and the MAVLink
// motion driver. Wiring only: every planning decision is made in core/planning. The core objects (model
// pool, image front end, view grid, executive, frame buffers) are held in static storage.
#include <cstddef>
#include <functional>
#include <string>

#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/mavlink/mavlink_motion.hpp"
#include "targets/onboard/onboard_config.hpp"

namespace vantage::onboard {

enum ExitCode : int {
  kExitDone = 0,
  kExitMissionFailed = 1,
  kExitConfig = 2,
  kExitCamera = 3,
  kExitVehicle = 4,
};

struct StaticFootprint {
  std::size_t pool_bytes;
  std::size_t front_end_bytes;
  std::size_t grid_bytes;
  std::size_t executive_bytes;
  std::size_t frame_bytes;
  std::size_t total() const { return pool_bytes + front_end_bytes + grid_bytes + executive_bytes + frame_bytes; }
};
StaticFootprint static_footprint();

// Reopens the camera after kDeviceLost; empty string on success. May be empty (no reopen).
using CameraReopen = std::function<std::string()>;

// Runs the mission; prints progress to stdout and returns an ExitCode with *summary one line saying how
// it ended.
int run_mission(const OnboardConfig& config, hal::Camera& camera, const CameraReopen& reopen,
                hal::mavlink::MavlinkMotion& motion, const hal::Clock& clock, std::string* summary);

}  // namespace vantage::onboard
