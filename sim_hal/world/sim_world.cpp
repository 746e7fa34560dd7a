#include "sim_hal/world/sim_world.hpp"

namespace vantage::sim {

namespace {

NormalizationConfig normalization_of(const SceneConfig& c) {
  NormalizationConfig n;
  n.up_axis = c.up_axis;
  n.viewing_distance = c.viewing_distance;
  n.target_area_fraction = c.target_area_fraction;
  n.intrinsics = c.intrinsics;
  n.fixed_scale = c.scale;
  return n;
}

TriangleMesh load_and_normalize(const SceneConfig& c, NormalizationResult* result) {
  TriangleMesh mesh = load_mesh(c.mesh_path);
  *result = normalize_for_paper_setup(mesh, normalization_of(c));
  return mesh;
}

}  // namespace

SimWorld::SimWorld(const SceneConfig& config) : config_(config) {
  validate_scene_config(config_);
  TriangleMesh mesh = load_and_normalize(config_, &normalization_);
  scene_ = std::make_unique<EmbreeScene>(std::move(mesh));
  occupancy_ = std::make_unique<OccupancyGrid>(scene_->mesh(), config_.grid, config_.occupancy_margin);
}

SimWorld::SimWorld(const SceneConfig& config, TriangleMesh world_mesh) : config_(config) {
  validate_scene_config(config_);
  scene_ = std::make_unique<EmbreeScene>(std::move(world_mesh));
  occupancy_ = std::make_unique<OccupancyGrid>(scene_->mesh(), config_.grid, config_.occupancy_margin);
}

RaycastCameraConfig camera_config_from(const SceneConfig& config) {
  RaycastCameraConfig c;
  c.intrinsics = config.intrinsics;
  c.shading = config.shading;
  c.threads = config.render_threads;
  c.seed = config.seed;
  return c;
}

KinematicRobotConfig robot_config_from(const SceneConfig& config) {
  KinematicRobotConfig c;
  c.speed = config.robot_speed;
  c.pose_noise = config.pose_noise;
  c.seed = config.seed + 1u;
  return c;
}

}  // namespace vantage::sim
