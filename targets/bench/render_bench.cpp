// Ray-cast camera frame rate at 640x480 on the default scene (the normalized glmark2 bunny), seen from
// the viewing distance, with 1 and 2 render threads. Target: >= 100 frames/s with 2 threads (Release).
// Run: vantage-bench --benchmark_filter=Render --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>

#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive_pool.hpp"
#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/oracle/oracle_measurement_source.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/world/sim_world.hpp"

namespace {

const vantage::sim::SimWorld& bunny_world() {
  static const std::unique_ptr<vantage::sim::SimWorld> world =
      std::make_unique<vantage::sim::SimWorld>(vantage::sim::SceneConfig::paper_defaults());
  return *world;
}

void BM_RenderBunnyVga(benchmark::State& state) {
  const auto& world = bunny_world();
  vantage::sim::RaycastCameraConfig config;
  config.intrinsics = world.config().intrinsics;
  config.shading = world.config().shading;
  config.threads = static_cast<int>(state.range(0));
  const vantage::sim::RaycastCamera camera(world.scene(), config, nullptr);
  vantage::Viewpoint view;
  if (!vantage::ok(vantage::look_at(Eigen::Vector3d(world.config().viewing_distance, 0.0, 0.0),
                                    Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view))) {
    state.SkipWithError("look_at failed");
    return;
  }
  static vantage::GrayImageBuffer<640, 480> image;
  if (!vantage::ok(image.resize(config.intrinsics.width_px, config.intrinsics.height_px))) {
    state.SkipWithError("intrinsics larger than 640x480");
    return;
  }
  for (auto _ : state) {
    if (!vantage::ok(camera.render(view, image.view(), nullptr))) {
      state.SkipWithError("render failed");
      return;
    }
    benchmark::DoNotOptimize(image.view().pixels[0]);
  }
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
// Wall time is the figure of merit; CPU time covers all threads of the process, so on a machine shared
// with other work CPU time / threads is what the frame would take on otherwise idle cores.
BENCHMARK(BM_RenderBunnyVga)
    ->Arg(1)
    ->Arg(2)
    ->ArgName("threads")
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime();

// Ground truth on the bunny: building it (samples + visible set, once per scene) and evaluating a model
// of oracle primitives (coverage, accuracy, average sigma: meant to run once per image).
vantage::PrimitivePool<> g_pool;

void BM_GroundTruthBuildBunny(benchmark::State& state) {
  const auto& world = bunny_world();
  std::size_t visible = 0;
  for (auto _ : state) {
    const vantage::sim::GroundTruth truth(world.scene(), world.occupancy(), world.config().intrinsics,
                                          vantage::sim::GroundTruthConfig{});
    visible = truth.visible_count();
  }
  state.counters["visible_samples"] = static_cast<double>(visible);
  state.counters["occupied_cells"] = world.occupancy().occupied_count();
  state.counters["scale"] = world.normalization().scale;
  state.counters["area_fraction"] = world.normalization().mean_area_fraction;
}
BENCHMARK(BM_GroundTruthBuildBunny)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

void BM_GroundTruthEvaluateBunny(benchmark::State& state) {
  const auto& world = bunny_world();
  static const vantage::sim::GroundTruth truth(world.scene(), world.occupancy(), world.config().intrinsics,
                                               vantage::sim::GroundTruthConfig{});
  vantage::sim::OracleConfig oracle_config;
  oracle_config.intrinsics = world.config().intrinsics;
  vantage::sim::OracleMeasurementSource oracle(world.scene(), oracle_config);
  g_pool.clear();
  vantage::Viewpoint a, b;
  vantage::UpdateReport report;
  if (!vantage::ok(vantage::look_at(Eigen::Vector3d(40, 0, 0), Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &a)) ||
      !vantage::ok(vantage::look_at(Eigen::Vector3d(40, 4, 0), Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &b)) ||
      !vantage::ok(oracle.initialize(vantage::GrayImageView{}, a, vantage::GrayImageView{}, b, g_pool, &report))) {
    state.SkipWithError("oracle initialization failed");
    return;
  }
  vantage::sim::Evaluation e;
  for (auto _ : state) e = truth.evaluate(g_pool);
  state.counters["primitives"] = static_cast<double>(e.primitive_count);
  state.counters["rms_error"] = e.rms_error;
}
BENCHMARK(BM_GroundTruthEvaluateBunny)->Unit(benchmark::kMillisecond)->UseRealTime();

// One oracle update (EKF updates of every primitive seen + augmentation) on the bunny, 70K sites, from
// views walking around the object at the viewing distance.
void BM_OracleUpdateBunny(benchmark::State& state) {
  const auto& world = bunny_world();
  vantage::sim::OracleConfig oracle_config;
  oracle_config.intrinsics = world.config().intrinsics;
  vantage::sim::OracleMeasurementSource oracle(world.scene(), oracle_config);
  g_pool.clear();
  auto view_at = [](double azimuth) {
    vantage::Viewpoint v;
    (void)vantage::look_at(Eigen::Vector3d(40.0 * std::cos(azimuth), 40.0 * std::sin(azimuth), 0.0),
                           Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &v);
    return v;
  };
  vantage::UpdateReport report;
  if (!vantage::ok(oracle.initialize(vantage::GrayImageView{}, view_at(0.0), vantage::GrayImageView{}, view_at(0.1),
                                     g_pool, &report))) {
    state.SkipWithError("oracle initialization failed");
    return;
  }
  double azimuth = 0.1;
  std::uint64_t updated = 0;
  for (auto _ : state) {
    azimuth += 0.3;
    if (!vantage::ok(oracle.update(vantage::GrayImageView{}, view_at(azimuth), g_pool, &report))) {
      state.SkipWithError("oracle update failed");
      return;
    }
    updated += report.updated;
  }
  state.counters["updates_per_image"] = static_cast<double>(updated) / static_cast<double>(state.iterations());
  state.counters["primitives"] = static_cast<double>(g_pool.size());
}
BENCHMARK(BM_OracleUpdateBunny)->Unit(benchmark::kMillisecond)->Iterations(20)->UseRealTime();

}  // namespace
