// Image front end, one 640x480 frame of a ray-cast textured plane with 20,000 primitives in view:
// occlusion splat, prediction, warped-patch NCC search in the 3-sigma window, photometric subpixel fit,
// iterated EKF update, the merge scan (Track); the same plus the augmentation scan (Frame). Target:
// <= 10 ms on one core (Release).
// Run: vantage-bench --benchmark_filter=FrontEnd --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include "core/frontend/image_front_end.hpp"
#include "core/frontend/ncc.hpp"
#include "core/geometry/projection.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/binomial_smooth.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive_pool.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/world/sim_world.hpp"
#include "targets/bench/thread_cpu_time.hpp"

namespace {

constexpr std::size_t kPrimitivesInView = 20000;

// Static storage: the front end and the pool are megabytes, as on a robot.
vantage::ImageFrontEnd g_front_end;
vantage::PrimitivePool<32768> g_pool;
vantage::GrayImageBuffer<640, 480> g_first;
vantage::GrayImageBuffer<640, 480> g_second;
vantage::GrayImageBuffer<640, 480> g_frame;

vantage::Viewpoint orbit(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * M_PI / 180.0;
  const double el = elevation_deg * M_PI / 180.0;
  vantage::Viewpoint view;
  (void)vantage::look_at(Eigen::Vector3d(40.0 * std::cos(el) * std::cos(az), 40.0 * std::cos(el) * std::sin(az),
                                         40.0 * std::sin(el)),
                         Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view);
  return view;
}

// The model: primitives on the plane x = 0 at the seeds of a 3-px lattice of the first view, with the
// first image's patches, estimated to 0.02 units and off the truth by about that much.
bool fill_pool(const vantage::PinholeIntrinsics& k, const vantage::Viewpoint& first) {
  g_pool.clear();
  const vantage::GrayImageView image = g_first.view().as_const();
  std::uint32_t state = 12345u;
  auto uniform = [&state]() {
    state = state * 1664525u + 1013904223u;
    return (state >> 8) * (1.0 / 16777216.0) - 0.5;
  };
  for (std::int32_t y = 8; y < k.height_px - 8 && g_pool.size() < kPrimitivesInView; y += 3) {
    for (std::int32_t x = 8; x < k.width_px - 8 && g_pool.size() < kPrimitivesInView; x += 3) {
      const Eigen::Vector2d uv(x, y);
      const Eigen::Vector3d ray = vantage::back_project_ray_world(uv, first, k);
      const double t = -first.position_world.x() / ray.x();
      vantage::Primitive p;
      p.X_world = first.position_world + t * ray + 0.02 * Eigen::Vector3d(uniform(), uniform(), uniform());
      p.Sigma_world = Eigen::Matrix3d::Identity() * 0.02 * 0.02;
      p.normal_world = Eigen::Vector3f::UnitX();
      p.radius = static_cast<float>(1.5 * t / k.fx_px);
      p.creating_view = 0;
      vantage::extract_patch(image, x, y, &p.patch);
      if (!vantage::ok(g_pool.insert(p, nullptr))) return false;
    }
  }
  return g_pool.size() == kPrimitivesInView;
}

// The bench scene: a textured plane at 40 units, the first pair 1.5 degrees apart, the measured frame
// at 3 degrees azimuth, 1 degree elevation.
struct Views {
  vantage::PinholeIntrinsics k;
  vantage::Viewpoint first;
  vantage::Viewpoint second;
  vantage::Viewpoint frame;
};

// Renders the three images, configures the front end and initializes it from the first pair (which
// records view 0, the creating view of every bench primitive). False with the benchmark skipped on error.
bool set_up(benchmark::State& state, Views* views,
            const vantage::FrontEndConfig& config = vantage::FrontEndConfig{}) {
  vantage::sim::SceneConfig scene = vantage::sim::SceneConfig::paper_defaults();
  scene.shading.pixel_noise_sigma = 1.0;
  vantage::sim::TriangleMesh mesh;
  mesh.vertices = {Eigen::Vector3f(0, -40, -40), Eigen::Vector3f(0, 40, -40), Eigen::Vector3f(0, 40, 40),
                   Eigen::Vector3f(0, -40, 40)};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  const vantage::sim::SimWorld world(scene, mesh);
  vantage::sim::RaycastCameraConfig camera_config;
  camera_config.intrinsics = scene.intrinsics;
  camera_config.shading = scene.shading;
  const vantage::sim::RaycastCamera camera(world.scene(), camera_config, nullptr);
  views->k = camera.intrinsics();
  views->first = orbit(0.0, 0.0);
  views->second = orbit(1.5, 0.0);
  views->frame = orbit(3.0, 1.0);
  if (!vantage::ok(camera.render(views->first, g_first.view(), nullptr, 0)) ||
      !vantage::ok(camera.render(views->second, g_second.view(), nullptr, 1)) ||
      !vantage::ok(camera.render(views->frame, g_frame.view(), nullptr, 2))) {
    state.SkipWithError("render failed");
    return false;
  }
  vantage::UpdateReport report;
  if (!vantage::ok(g_front_end.configure(views->k, config)) ||
      !vantage::ok(g_front_end.initialize(g_first.view().as_const(), views->first, g_second.view().as_const(),
                                          views->second, g_pool, &report))) {
    state.SkipWithError("front end setup failed");
    return false;
  }
  return true;
}

// Re-initializes the front end from the first pair, then replaces the pool's spawned primitives by the
// bench's (and has the front end forget its per-slot tables, which described the spawned ones).
bool restart_with_bench_pool(const Views& views) {
  vantage::UpdateReport report;
  if (!vantage::ok(g_front_end.initialize(g_first.view().as_const(), views.first, g_second.view().as_const(),
                                          views.second, g_pool, &report)) ||
      !fill_pool(views.k, views.first)) {
    return false;
  }
  g_front_end.forget_primitive_tables();
  return true;
}

// Runs the timed loop: prepare() (not timed) then one update of the frame, timed by the update's own
// thread CPU time (the machine is shared); reports the per-frame counts.
template <typename Prepare>
void run_updates(benchmark::State& state, const Views& views, Prepare prepare) {
  vantage::UpdateReport report;
  double predicted = 0.0;
  double matched = 0.0;
  double updated = 0.0;
  double spawned = 0.0;
  double gated = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    if (!prepare()) {
      state.SkipWithError("bench preparation failed");
      return;
    }
    state.ResumeTiming();
    const double start_s = vantage::bench::thread_cpu_s();
    const vantage::Status status = g_front_end.update(g_frame.view().as_const(), views.frame, g_pool, &report);
    const double stop_s = vantage::bench::thread_cpu_s();
    benchmark::DoNotOptimize(status);
    state.SetIterationTime(stop_s - start_s);
    predicted += report.predicted_in_view;
    matched += report.matched;
    updated += report.updated;
    spawned += report.spawned;
    gated += report.gated_outliers;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["predicted_in_view"] = predicted / n;
  state.counters["matched"] = matched / n;
  state.counters["updated"] = updated / n;
  state.counters["spawned"] = spawned / n;
  state.counters["gated"] = gated / n;
}

// Tracking: every timed update sees the frame again from the previous frame's pose, so there is no
// baseline and no augmentation: occlusion splat, prediction, warped-patch search, subpixel fit, EKF
// updates, normal refits and the merge scan. Before each timed update, untimed: the front end is
// re-initialized, the pool refilled (the front end told to forget its per-slot tables, which described
// the spawned primitives), and one update of the frame confirms the primitives, so every iteration
// times the same second observation of them (the counters do not depend on how many iterations the
// library chooses).
void track_with(benchmark::State& state, const vantage::FrontEndConfig& config) {
  Views views;
  if (!set_up(state, &views, config)) return;
  run_updates(state, views, [&views] {
    vantage::UpdateReport report;
    return restart_with_bench_pool(views) &&
           vantage::ok(g_front_end.update(g_frame.view().as_const(), views.frame, g_pool, &report));
  });
}

void BM_FrontEndTrack20kVga(benchmark::State& state) { track_with(state, vantage::FrontEndConfig{}); }
BENCHMARK(BM_FrontEndTrack20kVga)->Unit(benchmark::kMillisecond)->UseManualTime();

// The same with the window always searched (FrontEndConfig::direct_fit_max_px = 0; by default a prior
// within a pixel is fitted from its prediction: core/frontend/EXPERIMENTS.md, "Seventh round").
void BM_FrontEndTrack20kVgaFullSearch(benchmark::State& state) {
  vantage::FrontEndConfig config;
  config.direct_fit_max_px = 0.0;
  track_with(state, config);
}
BENCHMARK(BM_FrontEndTrack20kVgaFullSearch)->Unit(benchmark::kMillisecond)->UseManualTime();

// The same with the fits that do not settle refused (FrontEndConfig::require_converged_fit with 6
// Gauss-Newton steps; core/frontend/EXPERIMENTS.md, "Session 30").
void BM_FrontEndTrack20kVgaConvergedFit(benchmark::State& state) {
  vantage::FrontEndConfig config;
  config.subpixel_iterations = 6;
  config.require_converged_fit = true;
  track_with(state, config);
}
BENCHMARK(BM_FrontEndTrack20kVgaConvergedFit)->Unit(benchmark::kMillisecond)->UseManualTime();

// The same with every measurement-model term the consistency work added switched off: no photometric
// normal, no normal uncertainty in R (no warp covariance), no reference-patch noise (no consider terms),
// one EKF iteration. What the matcher and a plain EKF cost, i.e. how far configuration alone can bring
// the frame toward its 10 ms budget (core/frontend/EXPERIMENTS.md, "The model terms' share").
void BM_FrontEndTrack20kVgaPlainModel(benchmark::State& state) {
  vantage::FrontEndConfig config;
  config.photometric_normal = false;
  config.model_normal_uncertainty = false;
  config.model_template_noise = false;
  config.ekf_iterations = 1;
  track_with(state, config);
}
BENCHMARK(BM_FrontEndTrack20kVgaPlainModel)->Unit(benchmark::kMillisecond)->UseManualTime();

// A whole frame: the same tracking plus model augmentation (epipolar search of the seeds no primitive
// covers against the previous image, 1.5 degrees away). The front end is re-initialized and the pool
// refilled, untimed, before each update so the previous image is the second one every time.
void frame_with(benchmark::State& state, const vantage::FrontEndConfig& config) {
  Views views;
  if (!set_up(state, &views, config)) return;
  run_updates(state, views, [&views] {
    return restart_with_bench_pool(views);
  });
}

void BM_FrontEndFrame20kVga(benchmark::State& state) { frame_with(state, vantage::FrontEndConfig{}); }
BENCHMARK(BM_FrontEndFrame20kVga)->Unit(benchmark::kMillisecond)->UseManualTime();

// The same without the spawn's left-right check (FrontEndConfig::spawn_back_match_max_px, 1 px by default
// since session 44): its cost is one more epipolar search per matched seed (core/frontend/EXPERIMENTS.md,
// "Session 42").
void BM_FrontEndFrame20kVgaNoBackMatch(benchmark::State& state) {
  vantage::FrontEndConfig config;
  config.spawn_back_match_max_px = 0.0;
  frame_with(state, config);
}
BENCHMARK(BM_FrontEndFrame20kVgaNoBackMatch)->Unit(benchmark::kMillisecond)->UseManualTime();

// FrontEndConfig::presmooth's cost: the 3x3 binomial low-pass of one 640x480 frame (thread CPU).
void BM_BinomialSmoothVga(benchmark::State& state) {
  Views views;
  if (!set_up(state, &views)) return;
  static vantage::GrayImageBuffer<640, 480> smoothed;
  for (auto _ : state) {
    const double start_s = vantage::bench::thread_cpu_s();
    const vantage::Status status = vantage::binomial_smooth3(g_frame.view().as_const(), smoothed.view());
    const double stop_s = vantage::bench::thread_cpu_s();
    benchmark::DoNotOptimize(status);
    benchmark::ClobberMemory();
    state.SetIterationTime(stop_s - start_s);
  }
}
BENCHMARK(BM_BinomialSmoothVga)->Unit(benchmark::kMicrosecond)->UseManualTime();

}  // namespace
