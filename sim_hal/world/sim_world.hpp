#pragma once
// The simulated world built from a SceneConfig: the normalized mesh in an Embree scene and the occupied
// cells. Camera, robot, ground truth and oracle are built on top of it by the target.
#include <memory>

#include "sim_hal/kinematic_robot.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/scene/embree_scene.hpp"
#include "sim_hal/scene/mesh_loader.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/world/occupancy.hpp"

namespace vantage::sim {

class SimWorld {
 public:
  // Loads and normalizes the mesh, builds the Embree scene and the occupancy. Throws SimError.
  explicit SimWorld(const SceneConfig& config);
  // For tests and tools: an already normalized mesh (world frame) instead of config.mesh_path.
  SimWorld(const SceneConfig& config, TriangleMesh world_mesh);

  const SceneConfig& config() const { return config_; }
  const EmbreeScene& scene() const { return *scene_; }
  const OccupancyGrid& occupancy() const { return *occupancy_; }
  const NormalizationResult& normalization() const { return normalization_; }

 private:
  SceneConfig config_;
  NormalizationResult normalization_;
  std::unique_ptr<EmbreeScene> scene_;
  std::unique_ptr<OccupancyGrid> occupancy_;
};

// The camera and robot settings a scene file describes (seed shared; the robot's pose-noise stream is
// seed + 1 so it does not repeat the camera's noise).
RaycastCameraConfig camera_config_from(const SceneConfig& config);
KinematicRobotConfig robot_config_from(const SceneConfig& config);

}  // namespace vantage::sim
