#pragma once
// Where the simulated camera is: the TRUE camera viewpoint (world frame). The kinematic robot implements
// it; a SITL adapter can too. Rendering always uses the true pose; noise goes on the reported pose only.
#include "core/geometry/viewpoint.hpp"

namespace vantage::sim {

class SimPoseSource {
 public:
  virtual Viewpoint camera_pose() const = 0;

 protected:
  ~SimPoseSource() = default;
};

}  // namespace vantage::sim
