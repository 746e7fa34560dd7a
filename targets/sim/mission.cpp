#include "targets/sim/mission.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include <unistd.h>

#include "core/frontend/image_front_end.hpp"
#include "core/planning/precision_level.hpp"
#include "core/planning/sensing_executive.hpp"
#include "sim_hal/ground_truth/gate_diagnostics.hpp"
#include "sim_hal/ground_truth/normal_oracle.hpp"
#include "sim_hal/ground_truth/normals_by_source.hpp"
#include "sim_hal/ground_truth/tail_oracle.hpp"
#include "sim_hal/kinematic_robot.hpp"
#include "sim_hal/oracle/oracle_measurement_source.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_error.hpp"
#include "targets/common/search_depth_range.hpp"
#include "targets/sim/grid_driver.hpp"

namespace vantage::simtarget {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Forwards to the run's measurement source and times it (the executive holds one reference for life).
struct TimedMeasurement final : MeasurementSource {
  MeasurementSource* target = nullptr;
  double seconds = 0.0;
  // --normal-oracle: gives the image front end's primitives the truth's normals before each update (not
  // timed: a diagnostic's cost is no measurement's).
  sim::NormalOracle* normal_oracle = nullptr;
  ImageFrontEnd* front_end = nullptr;
  Status initialize(const GrayImageView& a, const Viewpoint& va, const GrayImageView& b, const Viewpoint& vb,
                    PrimitivePoolView& pool, UpdateReport* report) override {
    const auto t0 = Clock::now();
    const Status s = target->initialize(a, va, b, vb, pool, report);
    seconds += seconds_since(t0);
    return s;
  }
  Status update(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                UpdateReport* report) override {
    if (normal_oracle != nullptr) normal_oracle->apply(*front_end, pool);
    const auto t0 = Clock::now();
    const Status s = target->update(image, view, pool, report);
    seconds += seconds_since(t0);
    return s;
  }
  const PinholeIntrinsics& intrinsics() const override { return target->intrinsics(); }
};

// Ground-truth coverage as the executive's external stop condition (evaluation only: the planner sees a
// yes/no, never the samples).
struct CoverageGoal final : ExternalGoal {
  const sim::GroundTruth* ground_truth = nullptr;
  double target = 0.99;
  double distance = 0.5;
  double sigma_target = 0.008;
  double last = 0.0;
  double seconds = 0.0;
  bool reached(const PrimitivePoolView& pool) override {
    const auto t0 = Clock::now();
    last = ground_truth->coverage(pool, distance, sigma_target);
    seconds += seconds_since(t0);
    return last >= target;
  }
};

// Static storage for the big heap-free objects (tens of MB): never on the stack.
PrimitivePool<kDefaultPrimitiveCapacity> g_pool;
ImageFrontEnd g_front_end;
TimedMeasurement g_measurement;
CoverageGoal g_goal;
GridDriver g_grid;
SensingExecutive g_executive(g_pool, g_measurement, g_grid, &g_goal);

struct SimRig {
  sim::SimClock clock;
  std::unique_ptr<sim::KinematicRobot> robot;
  std::unique_ptr<sim::RaycastCamera> camera;
  std::vector<std::uint8_t> pixels;
  MutableGrayImageView frame;
  double render_seconds = 0.0;

  // Moves the robot to view (straight line; the planner only commands neighbouring cells).
  void move_to(const Viewpoint& view) {
    const hal::MotionFault fault = robot->command(view);
    if (fault != hal::MotionFault::kNone) {
      throw sim::SimError(std::string("robot refused a planned viewpoint: ") + hal::to_string(fault));
    }
    for (int step = 0; step < 100000 && !robot->arrived(); ++step) {
      robot->update(0.05);
      clock.advance(0.05);
    }
    if (!robot->arrived()) throw sim::SimError("robot did not arrive at a planned viewpoint");
  }
  GrayImageView grab() {
    hal::FrameInfo info;
    const auto t0 = Clock::now();
    const hal::CaptureStatus s = camera->grab(frame, info, 1000);
    render_seconds += seconds_since(t0);
    if (s != hal::CaptureStatus::kOk) throw sim::SimError(std::string("ray-cast camera: ") + hal::to_string(s));
    return frame.as_const();
  }
};

void print_progress(const MissionOptions& o, const SensingExecutive& e, double coverage, double path_units,
                    double elapsed_s, bool final_line) {
  if (!o.live) return;
  // A terminal gets one line rewritten in place; a log file gets a line every 25 images.
  const bool tty = isatty(fileno(stderr)) != 0;
  if (!tty && !final_line && e.images() % 25 != 0) return;
  std::fprintf(stderr, "%s[%s] images %4u/%u | NBV iterations %3u | coverage %5.1f%% | avg sigma %.5f | path %7.1f | %6.1f s ",
               tty ? "\r" : "", to_string(o.planner), e.images(), o.budget, e.nbv_iterations(), 100.0 * coverage, e.precision_level(),
               path_units, elapsed_s);
  if (final_line || !tty) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

}  // namespace

const char* to_string(MeasurementKind kind) { return kind == MeasurementKind::kImage ? "image" : "oracle"; }

const PrimitivePoolView& mission_pool() { return g_pool; }

// RMS of distances; p95 by nearest rank (as GroundTruth::accuracy). Sorts *d.
void rms_p95(std::vector<double>* d, double* rms, double* p95) {
  double sum_sq = 0.0;
  for (double x : *d) sum_sq += x * x;
  *rms = d->empty() ? 0.0 : std::sqrt(sum_sq / static_cast<double>(d->size()));
  std::sort(d->begin(), d->end());
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(d->size())));
  *p95 = d->empty() ? 0.0 : (*d)[rank == 0 ? 0 : rank - 1];
}

// The accuracy figures split by primitive_flags::kProvisional and by update count; distances in the
// alive primitives' index order (GroundTruth::accuracy).
void split_accuracy(const PrimitivePoolView& pool, const std::vector<double>& distances, MissionSummary* summary) {
  std::vector<double> confirmed, provisional, unobserved, updated2;
  std::size_t k = 0;
  for (PrimitiveIndex i = 0; i < pool.index_bound() && k < distances.size(); ++i) {
    if (!pool.is_alive(i)) continue;
    const double d = distances[k++];
    ((pool[i].flags & primitive_flags::kProvisional) != 0 ? provisional : confirmed).push_back(d);
    if ((pool[i].flags & primitive_flags::kProvisional) != 0 && pool[i].observation_count == 0) unobserved.push_back(d);
    if (d > 1.0) {
      ++summary->gross;
      if ((pool[i].flags & primitive_flags::kProvisional) != 0) ++summary->gross_provisional;
    }
    if (pool[i].observation_count >= 2) updated2.push_back(d);
  }
  double unused = 0.0;
  summary->provisional = provisional.size();
  summary->provisional_unobserved = unobserved.size();
  rms_p95(&unobserved, &summary->accuracy_rms_unobserved, &unused);
  rms_p95(&confirmed, &summary->accuracy_rms_confirmed, &summary->accuracy_p95_confirmed);
  rms_p95(&provisional, &summary->accuracy_rms_provisional, &unused);
  rms_p95(&updated2, &summary->accuracy_rms_updated2, &unused);
}

double split_epsilon_for(const MissionOptions& options, double cell_size) {
  if (options.split_epsilon_cells > 0.0) return options.split_epsilon_cells;
  // With epsilon e the recursion halts at d <= 2e, so waypoints lie e..2e cells apart (0.75: 8-neighbours).
  return std::max(0.75, 0.75 * options.image_spacing / cell_size);
}

SimSetup build_setup(const sim::SceneConfig& scene, std::uint64_t seed, std::size_t ground_truth_samples) {
  SimSetup setup;
  setup.scene = scene;
  setup.scene.seed = static_cast<std::uint32_t>(seed);
  setup.world = std::make_unique<sim::SimWorld>(setup.scene);
  sim::GroundTruthConfig gt;
  gt.threads = 2;
  gt.sample_count = ground_truth_samples;
  setup.ground_truth = std::make_unique<sim::GroundTruth>(setup.world->scene(), setup.world->occupancy(),
                                                          setup.scene.intrinsics, gt);
  return setup;
}

MissionSummary run_mission(const SimSetup& setup, const MissionOptions& options, MissionTrace* trace) {
  const auto wall_t0 = Clock::now();
  const sim::SceneConfig& scene = setup.scene;
  const GridGeometry& geo = scene.grid;
  MissionSummary summary;
  summary.scene = options.scene_name;
  summary.planner = to_string(options.planner);
  summary.measurement = to_string(options.measurement);
  summary.coverage_target = options.coverage_target;
  summary.sigma_target = options.sigma_target;
  summary.budget = options.budget;
  summary.seed = options.seed;
  *trace = MissionTrace{};
  trace->geometry = geo;

  // Measurement source for this run.
  std::unique_ptr<sim::OracleMeasurementSource> oracle;
  std::unique_ptr<sim::GateDiagnostics> diagnostics;
  std::unique_ptr<sim::TailOracle> tail_oracle;
  std::unique_ptr<sim::NormalOracle> normal_oracle;
  if (options.measurement == MeasurementKind::kOracle) {
    sim::OracleConfig oc;
    oc.intrinsics = scene.intrinsics;
    oc.site_count = options.oracle_sites;
    oc.seed = static_cast<std::uint32_t>(options.seed * 7919u + 11u);
    oc.unconsumed_after_gated = static_cast<int>(options.unconsumed_after);
    oracle = std::make_unique<sim::OracleMeasurementSource>(setup.world->scene(), oc);
    g_measurement.target = oracle.get();
  } else {
    FrontEndConfig fc;
    const targets::SearchDepthRange depth = targets::default_search_depth_range(geo, scene.viewing_distance);
    fc.depth_min = depth.min_m;
    fc.depth_max = depth.max_m;
    fc.unconsumed_after_rejections = options.unconsumed_after;
    fc.erase_unsearchable = !options.keep_unsearchable;
    fc.direct_fit_max_px = options.direct_fit_max_px;
    fc.subpixel_iterations = options.subpixel_iterations;
    fc.require_converged_fit = options.require_converged_fit;
    fc.view_correlated_error_scale = options.view_correlated_error_scale;
    fc.view_correlation_deg = options.view_correlation_deg;
    fc.deformation_error_scale = options.deformation_error_scale;
    fc.deformation_error_power = options.deformation_error_power;
    fc.presmooth = options.presmooth;
    fc.spawn_normal_fit_along_rays = options.spawn_normal_fit_along_rays;
    fc.epipolar_guard_fraction = options.epipolar_guard_fraction;
    fc.spawn_back_match_max_px = options.spawn_back_match_max_px;
    fc.spawn_requires_plane_fit = options.spawn_requires_plane_fit;
    fc.inverse_warp_masked = options.inverse_warp_masked;
    fc.inverse_warp_ncc_min = static_cast<float>(options.inverse_warp_ncc_min);
    fc.match_sigma_floor_rad = options.match_sigma_floor_rad;
    fc.match_floor_tilt_power = options.match_floor_tilt_power;
    fc.normal_refit_residual_floor = options.normal_refit_residual_floor;
    fc.refit_supersedes_spawn_fit = options.refit_supersedes_spawn_fit;
    fc.normal_spawn_residual_floor = options.normal_spawn_residual_floor;
    fc.max_match_sigma_rad = options.max_match_sigma_rad;
    fc.confirm_min_depth_information = options.confirm_depth_information;
    fc.provisional_max_updates = options.provisional_max_updates;
    fc.erase_provisional_rejected = options.erase_provisional_rejected;
    const Status s = g_front_end.configure(scene.intrinsics, fc);
    if (!ok(s)) throw sim::SimError(std::string("image front end configuration: ") + vantage::to_string(s));
    g_measurement.target = &g_front_end;
    if (options.gate_diagnostics) {
      diagnostics = std::make_unique<sim::GateDiagnostics>(setup.world->scene(), g_front_end, fc.seed_stride_px);
    } else if (options.tail_oracle) {
      tail_oracle = std::make_unique<sim::TailOracle>(setup.world->scene(), scene.intrinsics, fc.seed_stride_px);
    }
    if (options.normal_oracle) {
      normal_oracle = std::make_unique<sim::NormalOracle>(setup.world->scene(), scene.intrinsics, fc.seed_stride_px);
    }
  }
  g_measurement.normal_oracle = normal_oracle.get();
  g_measurement.front_end = &g_front_end;
  g_front_end.set_observer(diagnostics ? static_cast<TrackObserver*>(diagnostics.get()) : tail_oracle.get());
  g_measurement.seconds = 0.0;
  g_pool.clear();
  g_goal.ground_truth = setup.ground_truth.get();
  g_goal.target = options.coverage_target;
  g_goal.sigma_target = options.sigma_target;
  g_goal.last = 0.0;
  g_goal.seconds = 0.0;
  g_grid.configure(geo, scene.intrinsics, setup.world->occupancy(), options.model_free_mask);

  // Two initial views with a small baseline (one cell) at the viewing distance, on the -y side.
  const GridCell first_cell = geo.cell_of(geo.center_xy + Eigen::Vector2d(0.0, -scene.viewing_distance));
  const GridCell second_cell{first_cell.ix + 1, first_cell.iy};
  if (!setup.world->occupancy().free(first_cell) || !setup.world->occupancy().free(second_cell)) {
    throw sim::SimError("scene: the initial views at the viewing distance fall in occupied or off-grid cells");
  }
  const Viewpoint first_view = sim::grid_cell_viewpoint(geo, first_cell);
  const Viewpoint second_view = sim::grid_cell_viewpoint(geo, second_cell);
  trace->initial_cells = {first_cell, second_cell};

  SimRig rig;
  sim::KinematicRobotConfig rc;
  rc.speed = scene.robot_speed;
  rc.pose_noise = scene.pose_noise;
  rc.seed = static_cast<std::uint32_t>(options.seed);
  rig.robot = std::make_unique<sim::KinematicRobot>(rc, setup.world->occupancy(), first_view, &rig.clock);
  sim::RaycastCameraConfig cc;
  cc.intrinsics = scene.intrinsics;
  cc.shading = scene.shading;
  cc.threads = scene.render_threads;
  cc.seed = static_cast<std::uint32_t>(options.seed);
  rig.camera = std::make_unique<sim::RaycastCamera>(setup.world->scene(), cc, rig.robot.get(), &rig.clock);
  rig.pixels.assign(static_cast<std::size_t>(scene.intrinsics.width_px) * scene.intrinsics.height_px, 0);
  rig.frame = MutableGrayImageView{rig.pixels.data(), scene.intrinsics.width_px, scene.intrinsics.height_px,
                                   scene.intrinsics.width_px};

  std::vector<std::uint8_t> first_pixels;
  {
    const GrayImageView first = rig.grab();
    first_pixels.assign(first.pixels, first.pixels + rig.pixels.size());
  }
  const Viewpoint first_pose = rig.robot->current_pose().pose;
  rig.move_to(second_view);
  const GrayImageView second = rig.grab();
  const Viewpoint second_pose = rig.robot->current_pose().pose;

  SensingConfig config;
  config.policy = options.planner;
  config.split.epsilon_cells = split_epsilon_for(options, geo.cell_size_m);
  summary.split_epsilon_cells = config.split.epsilon_cells;
  config.rho_sigma = options.sigma_target;
  config.eta_utility = options.eta_utility;
  config.eta_relative = options.eta_relative;
  config.max_images = options.budget;
  config.capture_on_segments = options.capture_on_segments;
  config.orbit_radius_m = scene.viewing_distance;
  config.random_seed = options.seed;
  if (const char* field = config.invalid_field()) {
    throw sim::SimError(std::string("mission configuration: ") + field + " out of range");
  }
  const GrayImageView first_image{first_pixels.data(), rig.frame.width_px, rig.frame.height_px, rig.frame.stride_bytes};
  const Status begun = g_executive.begin(config, first_image, first_pose, second, second_pose);
  trace->path.push_back(second_cell);

  double planning_seconds = 0.0;
  double coverage_shown = 0.0;
  std::uint32_t seen_iterations = 0;
  bool first_evaluation = true;
  auto note_replan = [&]() {
    if (g_executive.nbv_iterations() == seen_iterations) return;
    seen_iterations = g_executive.nbv_iterations();
    trace->replans.push_back(ReplanRecord{g_executive.images(), g_executive.last_replan_reason(), g_executive.nbv_cell(),
                                          g_executive.utility()});
  };
  if (ok(begun)) {
    for (;;) {
      const SensingAction action = g_executive.next();
      if (action.kind == SensingActionKind::kDone || action.kind == SensingActionKind::kFailed) break;
      if (action.kind == SensingActionKind::kEvaluateGrid) {
        const auto t0 = Clock::now();
        const Status evaluated = g_grid.evaluate(g_pool);
        if (!ok(evaluated)) {
          summary.failed = true;
          summary.end_reason = std::string("grid evaluation failed: ") + vantage::to_string(evaluated);
          break;
        }
        ++summary.grid_evaluations;
        g_executive.on_grid_evaluated();
        planning_seconds += seconds_since(t0);
        const GridMapView map = g_grid.map();
        std::vector<float> cost(map.cost, map.cost + geo.cell_count());
        if (first_evaluation) trace->first_cost = cost;
        trace->final_cost = std::move(cost);
        first_evaluation = false;
        note_replan();
      } else if (action.kind == SensingActionKind::kMoveTo) {
        rig.move_to(action.view);
        const auto t0 = Clock::now();
        g_executive.on_arrived(rig.robot->current_pose().pose);
        planning_seconds += seconds_since(t0);
        trace->path.push_back(action.cell);
      } else {
        rig.move_to(action.view);  // orientation only, when the pose is already in the cell
        const GrayImageView image = rig.grab();
        const double measurement_before = g_measurement.seconds, goal_before = g_goal.seconds;
        const auto t0 = Clock::now();
        g_executive.on_image(image, rig.robot->current_pose().pose);
        planning_seconds += seconds_since(t0) - (g_measurement.seconds - measurement_before) -
                            (g_goal.seconds - goal_before);
        ImageRecord record;
        record.image = g_executive.images();
        record.nbv_iteration = g_executive.nbv_iterations();
        record.average_sigma = g_executive.precision_level();
        record.utility = g_executive.utility();
        record.cell = action.cell;
        if (g_goal.seconds != goal_before) {
          coverage_shown = g_goal.last;
          record.coverage = g_goal.last;
        } else if (options.coverage_every > 0 && record.image % options.coverage_every == 0) {
          coverage_shown = setup.ground_truth->coverage(g_pool, g_goal.distance, options.sigma_target);
          record.coverage = coverage_shown;
        }
        trace->images.push_back(record);
        note_replan();
        print_progress(options, g_executive, coverage_shown,
                       g_executive.path_length_cells() * geo.cell_size_m, seconds_since(wall_t0), false);
      }
    }
  }
  const SensingAction last = g_executive.next();
  if (!summary.failed) {
    summary.failed = last.kind == SensingActionKind::kFailed;
    summary.end_reason = last.kind == SensingActionKind::kDone ? to_string(last.done) : last.reason;
    if (summary.failed && last.failure != Status::kOk) {
      summary.end_reason += std::string(" (") + vantage::to_string(last.failure) + ")";
    }
  }
  summary.reached_goal = last.kind == SensingActionKind::kDone && last.done == DoneReason::kGoalsReached;
  g_front_end.set_observer(nullptr);
  if (diagnostics) diagnostics->print(stderr);
  if (tail_oracle) tail_oracle->print(stderr);
  if (normal_oracle) normal_oracle->print(stderr);
  if (options.normal_diagnostics && options.measurement == MeasurementKind::kImage) {
    sim::NormalsBySource normals;
    normals.add_pool(setup.world->scene(), g_front_end, g_pool);
    normals.print(stderr, "normal diagnostics: ");
    std::fprintf(stderr, "normal diagnostics: %llu primitives without a truth (creating view gone, or the seed ray or "
                 "patch off the mesh)\n", static_cast<unsigned long long>(normals.skipped()));
  }
  g_measurement.normal_oracle = nullptr;
  summary.images = g_executive.images();
  summary.nbv_iterations = g_executive.nbv_iterations();
  summary.path_length = g_executive.path_length_cells() * geo.cell_size_m;
  summary.mean_sigma = average_sigma(g_pool, &summary.primitives);
  summary.coverage = setup.ground_truth->coverage(g_pool, g_goal.distance, options.sigma_target);
  summary.model_coverage =
      setup.ground_truth->coverage(g_pool, g_goal.distance, std::numeric_limits<double>::infinity());
  summary.verified_coverage = setup.ground_truth->verified_coverage(
      g_pool, g_goal.distance, options.sigma_target, kVerifiedSigmas, &summary.precise, &summary.precise_verified);
  double rms = 0.0, p95 = 0.0, max_error = 0.0;
  std::vector<double> distances;
  setup.ground_truth->accuracy(g_pool, &rms, &p95, &max_error, &distances);
  summary.accuracy_rms = rms;
  summary.accuracy_p95 = p95;
  split_accuracy(g_pool, distances, &summary);
  summary.planning_seconds = planning_seconds;
  summary.measurement_seconds = g_measurement.seconds;
  summary.render_seconds = rig.render_seconds;
  summary.rejected_images = g_executive.rejected_images();
  if (options.measurement == MeasurementKind::kImage) {
    const FrontEndStats& fs = g_front_end.stats();
    summary.tracks_predicted = fs.tracks_predicted;
    summary.tracks_matched = fs.tracks_matched;
    summary.tracks_inverse_warped = fs.tracks_inverse_warped;
    summary.photometric_normals = fs.photometric_normals;
    summary.photometric_refits_unconverged = fs.photometric_refits_unconverged;
    summary.track_failures = fs.track_failures;
    summary.seeds_tried = fs.seeds_tried;
    summary.seeds_matched = fs.seeds_matched;
    summary.seeds_beyond_depth_range = fs.seeds_beyond_depth_range;
    summary.seeds_rejected_back_match = fs.seeds_rejected_back_match;
    summary.seeds_rejected_no_plane_fit = fs.seeds_rejected_no_plane_fit;
    summary.innovations = fs.ekf.nis;
  } else if (oracle != nullptr) {
    summary.innovations = oracle->ekf_stats().nis;
  }
  summary.unreachable_nbv = g_executive.unreachable_nbv_count();
  summary.split_fallbacks = g_executive.split_fallback_count();
  summary.stagnations = g_executive.stagnation_count();
  const GridMapView map = g_grid.map();
  if (map.free != nullptr) trace->free.assign(map.free, map.free + geo.cell_count());
  summary.wall_seconds = seconds_since(wall_t0);
  print_progress(options, g_executive, summary.coverage, summary.path_length, summary.wall_seconds, true);
  return summary;
}

}  // namespace vantage::simtarget
