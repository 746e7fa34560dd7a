#include "targets/bench/bench_models.hpp"

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "sim_hal/scene/mesh_loader.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/scene/surface_sampler.hpp"
#include "sim_hal/sim_error.hpp"

namespace vantage::bench {

namespace {

BunnyModel build(PrimitivePoolView& pool) {
  BunnyModel model;
  try {
    const sim::SceneConfig scene = sim::SceneConfig::paper_defaults();
    sim::TriangleMesh mesh = sim::load_mesh(scene.mesh_path);
    sim::NormalizationConfig normalization;
    normalization.viewing_distance = scene.viewing_distance;
    normalization.intrinsics = scene.intrinsics;
    sim::normalize_for_paper_setup(mesh, normalization);
    model.surface_area = mesh.surface_area();
    model.intrinsics = scene.intrinsics;
    model.grid = scene.grid;
    const std::vector<sim::SurfaceSample> samples = sim::sample_surface(mesh, kBunnyPrimitives, 2009u);
    if (samples.size() != kBunnyPrimitives) {
      model.error = "sampling " + scene.mesh_path + " gave too few points";
      return model;
    }
    const float radius = static_cast<float>(std::sqrt(model.surface_area / (3.14159265358979323846 * kBunnyPrimitives)));
    std::mt19937 rng(70000u);
    std::uniform_real_distribution<double> sigma(0.01, 0.2);
    std::uniform_real_distribution<float> saliency(0.0f, 1.0f);
    pool.clear();
    for (const sim::SurfaceSample& s : samples) {
      Primitive p;
      p.X_world = s.position;
      p.normal_world = s.normal.cast<float>();
      p.radius = radius;
      const Eigen::Matrix3d axes = Eigen::Quaterniond::UnitRandom().toRotationMatrix();
      const Eigen::Vector3d variances(std::pow(sigma(rng), 2), std::pow(sigma(rng), 2), std::pow(sigma(rng), 2));
      p.Sigma_world = axes * variances.asDiagonal() * axes.transpose();
      p.Sigma_world = 0.5 * (p.Sigma_world + p.Sigma_world.transpose());
      p.saliency_h = saliency(rng);
      if (!vantage::ok(pool.insert(p, nullptr))) {
        model.error = "primitive pool refused a bunny sample";
        return model;
      }
    }
    model.ok = true;
  } catch (const std::exception& e) {
    model.error = e.what();
  }
  return model;
}

}  // namespace

const BunnyModel& bunny_model(PrimitivePoolView** pool_out) {
  static const std::unique_ptr<PrimitivePool<>> pool = std::make_unique<PrimitivePool<>>();
  static const BunnyModel model = build(*pool);
  *pool_out = pool.get();
  return model;
}

}  // namespace vantage::bench
