#pragma once
// Motion capability: command a viewpoint and read back where the vehicle is. Implemented by the
// MAVLink driver (hal/mavlink) and the kinematic robot (sim_hal/).
#include <cstdint>

#include "core/geometry/viewpoint.hpp"

namespace vantage::hal {

enum class MotionFault : std::uint8_t {
  kNone = 0,
  kTargetOccupied,   // the commanded viewpoint lies in an occupied cell
  kNonFiniteTarget,  // NaN/Inf in the commanded viewpoint
  kLinkLost,         // no heartbeat from the vehicle within the configured time
  kRejected,         // the vehicle refused the command
};

const char* to_string(MotionFault fault);

struct PoseReport {
  Viewpoint pose;                // current camera viewpoint, world frame (see core/geometry/viewpoint.hpp)
  std::int64_t timestamp_ns = 0;
  bool valid = false;            // false until a pose has been received
};

class Motion {
 public:
  // Starts moving toward the viewpoint; returns the fault that prevents it, kNone when accepted.
  virtual MotionFault command(const Viewpoint& target) = 0;
  // Advances the driver: the simulator integrates motion over dt, real drivers poll their link.
  virtual void update(double dt_s) = 0;
  virtual PoseReport current_pose() const = 0;
  // True once the last accepted command's target is reached within the driver's tolerance.
  virtual bool arrived() const = 0;
  virtual MotionFault fault() const = 0;

 protected:
  ~Motion() = default;
};

}  // namespace vantage::hal
