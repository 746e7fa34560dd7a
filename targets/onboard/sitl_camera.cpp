#include "targets/onboard/sitl_camera.hpp"

#include <memory>

#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/sim_error.hpp"
#include "sim_hal/sim_pose_source.hpp"
#include "sim_hal/world/sim_world.hpp"

namespace vantage::onboard {
namespace {

// The camera renders where the vehicle says it is.
class MotionPoseSource final : public sim::SimPoseSource {
 public:
  explicit MotionPoseSource(const hal::Motion& motion) : motion_(motion) {}
  Viewpoint camera_pose() const override { return motion_.current_pose().pose; }

 private:
  const hal::Motion& motion_;
};

struct SitlRig {
  std::unique_ptr<sim::SimWorld> world;
  std::unique_ptr<MotionPoseSource> pose_source;
  std::unique_ptr<sim::RaycastCamera> camera;
};

SitlRig g_rig;  // built once at start-up, lives for the process

}  // namespace

std::string open_sim_camera(const std::string& scene_path, const hal::Motion& motion, const hal::Clock& clock,
                            hal::Camera** camera) {
  try {
    const sim::SceneConfig scene = scene_path.empty() ? sim::SceneConfig::paper_defaults() : sim::load_scene_config(scene_path);
    g_rig.world = std::make_unique<sim::SimWorld>(scene);
    g_rig.pose_source = std::make_unique<MotionPoseSource>(motion);
    sim::RaycastCameraConfig config;
    config.intrinsics = scene.intrinsics;
    config.shading = scene.shading;
    config.threads = scene.render_threads;
    config.seed = scene.seed;
    g_rig.camera = std::make_unique<sim::RaycastCamera>(g_rig.world->scene(), config, g_rig.pose_source.get(), &clock);
  } catch (const sim::SimError& e) {
    return std::string("sim: ") + e.what();
  }
  *camera = g_rig.camera.get();
  return {};
}

}  // namespace vantage::onboard
