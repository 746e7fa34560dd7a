#pragma once
// The paper's holonomic robot: a point moving in a straight line at constant speed on the grid plane
// z = elevation. The camera orientation jumps to the target viewpoint's rotation when a command is
// accepted (the paper treats orientation as free). current_pose() reports the true pose plus optional
// Gaussian noise; camera_pose() (what the renderer uses) is the true pose.
#include <cstdint>
#include <random>

#include "core/geometry/viewpoint.hpp"
#include "hal/motion.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_pose_source.hpp"
#include "sim_hal/world/occupancy.hpp"

namespace vantage::sim {

struct KinematicRobotConfig {
  double speed = 10.0;                 // scene units per second, > 0
  double arrival_tolerance = 1e-6;     // scene units
  double elevation_tolerance = 1e-3;   // |target z - grid elevation| allowed, else kRejected
  PoseNoiseConfig pose_noise;
  std::uint32_t seed = 1;
};

class KinematicRobot final : public hal::Motion, public SimPoseSource {
 public:
  // start must lie on the grid plane in a free cell (throws SimError otherwise). occupancy (and clock,
  // when given) must outlive the robot; with a clock, timestamps come from it (the robot does not
  // advance it).
  KinematicRobot(const KinematicRobotConfig& config, const OccupancyGrid& occupancy, const Viewpoint& start,
                 const hal::Clock* clock = nullptr);

  // kNonFiniteTarget for NaN/Inf, kTargetOccupied for an occupied or off-grid cell, kRejected for a
  // target off the plane z = elevation or an invalid rotation. On a fault the robot stops where it is.
  hal::MotionFault command(const Viewpoint& target) override;
  void update(double dt_s) override;
  hal::PoseReport current_pose() const override;
  bool arrived() const override { return arrived_; }
  hal::MotionFault fault() const override { return fault_; }

  Viewpoint camera_pose() const override { return pose_; }

  double distance_travelled() const { return distance_travelled_; }
  double simulated_time_s() const { return simulated_time_s_; }

 private:
  KinematicRobotConfig config_;
  const OccupancyGrid& occupancy_;
  const hal::Clock* clock_;
  Viewpoint pose_;
  Viewpoint target_;
  bool arrived_ = true;
  hal::MotionFault fault_ = hal::MotionFault::kNone;
  double distance_travelled_ = 0.0;
  double simulated_time_s_ = 0.0;
  mutable std::mt19937 noise_rng_;
};

}  // namespace vantage::sim
