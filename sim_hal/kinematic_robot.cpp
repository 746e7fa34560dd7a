#include "sim_hal/kinematic_robot.hpp"

#include <cmath>

#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

bool finite(const Viewpoint& v) { return v.position_world.allFinite() && v.R_world_cam.allFinite(); }

}  // namespace

KinematicRobot::KinematicRobot(const KinematicRobotConfig& config, const OccupancyGrid& occupancy,
                               const Viewpoint& start, const hal::Clock* clock)
    : config_(config), occupancy_(occupancy), clock_(clock), pose_(start), target_(start), noise_rng_(config.seed) {
  if (!(config_.speed > 0.0) || !std::isfinite(config_.speed)) throw SimError("kinematic robot: speed must be positive");
  if (!(config_.arrival_tolerance >= 0.0) || !(config_.elevation_tolerance >= 0.0)) {
    throw SimError("kinematic robot: tolerances must be >= 0");
  }
  if (!(config_.pose_noise.position_sigma >= 0.0) || !(config_.pose_noise.rotation_sigma_rad >= 0.0)) {
    throw SimError("kinematic robot: pose noise must be >= 0");
  }
  if (!ok(start.validate())) throw SimError("kinematic robot: start pose is not finite or not a rotation");
  const GridGeometry& g = occupancy_.geometry();
  if (std::abs(start.position_world.z() - g.elevation_m) > config_.elevation_tolerance) {
    throw SimError("kinematic robot: start pose is off the grid plane");
  }
  if (occupancy_.occupied(g.cell_of(start.position_world.head<2>()))) {
    throw SimError("kinematic robot: start pose lies in an occupied or off-grid cell");
  }
}

hal::MotionFault KinematicRobot::command(const Viewpoint& target) {
  hal::MotionFault f = hal::MotionFault::kNone;
  const GridGeometry& g = occupancy_.geometry();
  if (!finite(target)) {
    f = hal::MotionFault::kNonFiniteTarget;
  } else if (!ok(target.validate()) || std::abs(target.position_world.z() - g.elevation_m) > config_.elevation_tolerance) {
    f = hal::MotionFault::kRejected;
  } else if (occupancy_.occupied(g.cell_of(target.position_world.head<2>()))) {
    f = hal::MotionFault::kTargetOccupied;
  }
  fault_ = f;
  if (f != hal::MotionFault::kNone) {
    // Stop where we are rather than keep flying toward an old target.
    target_.position_world = pose_.position_world;
    arrived_ = true;
    return f;
  }
  target_ = target;
  target_.position_world.z() = g.elevation_m;
  pose_.R_world_cam = target.R_world_cam;
  arrived_ = (target_.position_world - pose_.position_world).norm() <= config_.arrival_tolerance;
  if (arrived_) pose_.position_world = target_.position_world;
  return f;
}

void KinematicRobot::update(double dt_s) {
  if (!std::isfinite(dt_s) || dt_s <= 0.0) return;
  simulated_time_s_ += dt_s;
  if (arrived_) return;
  const Eigen::Vector3d to_go = target_.position_world - pose_.position_world;
  const double remaining = to_go.norm();
  const double step = config_.speed * dt_s;
  if (step >= remaining - config_.arrival_tolerance) {
    pose_.position_world = target_.position_world;
    distance_travelled_ += remaining;
    arrived_ = true;
  } else {
    pose_.position_world += to_go * (step / remaining);
    distance_travelled_ += step;
  }
}

hal::PoseReport KinematicRobot::current_pose() const {
  hal::PoseReport report;
  report.pose = pose_;
  report.valid = true;
  report.timestamp_ns = clock_ != nullptr ? clock_->now_ns() : static_cast<std::int64_t>(std::llround(simulated_time_s_ * 1e9));
  const PoseNoiseConfig& n = config_.pose_noise;
  if (n.position_sigma > 0.0 || n.rotation_sigma_rad > 0.0) {
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::Vector3d dp, dr;
    for (int i = 0; i < 3; ++i) dp[i] = normal(noise_rng_) * n.position_sigma;
    for (int i = 0; i < 3; ++i) dr[i] = normal(noise_rng_) * n.rotation_sigma_rad;
    report.pose.position_world += dp;
    const double angle = dr.norm();
    if (angle > 0.0) {
      report.pose.R_world_cam = Eigen::AngleAxisd(angle, dr / angle).toRotationMatrix() * pose_.R_world_cam;
    }
  }
  return report;
}

}  // namespace vantage::sim
