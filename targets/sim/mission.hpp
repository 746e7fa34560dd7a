#pragma once
// One simulated mission: the sim_hal world, camera and robot, a measurement source (image front end or
// oracle), the view grid evaluated on two threads, and core's SensingExecutive stepping them. This file
// only wires; every planning decision is made in core/planning.
#include <memory>
#include <string>

#include "core/frontend/image_front_end.hpp"
#include "core/planning/planner_policy.hpp"
#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/world/sim_world.hpp"
#include "targets/sim/mission_trace.hpp"

namespace vantage::simtarget {

enum class MeasurementKind { kImage, kOracle };

struct MissionOptions {
  std::string scene_name = "paper bunny (defaults)";
  PlannerPolicy planner = PlannerPolicy::kNbv;
  MeasurementKind measurement = MeasurementKind::kImage;
  std::uint32_t budget = 600;          // images, the two initial ones included
  std::uint64_t seed = 1;
  double coverage_target = 0.99;       // ground truth coverage of the visible area
  double sigma_target = 0.008;         // PrecisionLevel goal rho, units
  double eta_utility = 0.0;
  double eta_relative = 0.0;           // replan when U < eta_relative * U after PredictModel
  // Sampling rate along a path: about one image per image_spacing units (SplitPath's epsilon is
  // 0.75 cells per cell of spacing, at least 0.75 = one image per cell displacement). split_epsilon_cells
  // > 0 sets epsilon directly instead. See README.md "Sampling rate".
  double image_spacing = 4.0;
  double split_epsilon_cells = 0.0;
  bool capture_on_segments = false;
  // kUnconsumed after this many rejected observations in a row (front end: failed or gated; oracle:
  // gated); 0: off. core/planning/README.md, "Why coverage stalls".
  std::uint32_t unconsumed_after = 3;
  // Image front end: keep unconsumed primitives the search window cannot cover (FrontEndConfig::erase_unsearchable).
  bool keep_unsearchable = !FrontEndConfig{}.erase_unsearchable;
  // Image front end: FrontEndConfig::presmooth (the 3x3 binomial low-pass of every frame) and
  // match_sigma_floor_rad (the floor added in quadrature to every match's standard deviation, as an angle).
  bool presmooth = FrontEndConfig{}.presmooth;
  // Image front end: FrontEndConfig::spawn_normal_fit_along_rays (a new primitive's normal fitted along the
  // spawn camera's rays; false: the scatter fit).
  bool spawn_normal_fit_along_rays = FrontEndConfig{}.spawn_normal_fit_along_rays;
  // Image front end: FrontEndConfig::epipolar_guard_fraction (the epipolar search's guard band).
  double epipolar_guard_fraction = FrontEndConfig{}.epipolar_guard_fraction;
  // Image front end: FrontEndConfig::spawn_back_match_max_px (the spawn match's left-right check).
  double spawn_back_match_max_px = FrontEndConfig{}.spawn_back_match_max_px;
  // Image front end: FrontEndConfig::spawn_requires_plane_fit (new primitives without a plane fit erased).
  bool spawn_requires_plane_fit = FrontEndConfig{}.spawn_requires_plane_fit;
  // Image front end: FrontEndConfig::inverse_warp_masked (masked templates matched by warping the image).
  bool inverse_warp_masked = FrontEndConfig{}.inverse_warp_masked;
  double inverse_warp_ncc_min = FrontEndConfig{}.inverse_warp_ncc_min;  // FrontEndConfig::inverse_warp_ncc_min
  double match_sigma_floor_rad = FrontEndConfig{}.match_sigma_floor_rad;
  // Image front end: FrontEndConfig::match_floor_tilt_power (a tracked match's floor / cos(tilt)^k; 0: off).
  double match_floor_tilt_power = FrontEndConfig{}.match_floor_tilt_power;
  // Image front end: FrontEndConfig::normal_refit_residual_floor (0: off) and refit_supersedes_spawn_fit.
  double normal_refit_residual_floor = FrontEndConfig{}.normal_refit_residual_floor;
  bool refit_supersedes_spawn_fit = FrontEndConfig{}.refit_supersedes_spawn_fit;
  // Image front end: FrontEndConfig::normal_spawn_residual_floor (0: off).
  double normal_spawn_residual_floor = FrontEndConfig{}.normal_spawn_residual_floor;
  // Image front end: FrontEndConfig::max_match_sigma_rad (0: off).
  double max_match_sigma_rad = FrontEndConfig{}.max_match_sigma_rad;
  // Image front end: FrontEndConfig::direct_fit_max_px (0: always search the window).
  double direct_fit_max_px = FrontEndConfig{}.direct_fit_max_px;
  // Image front end: FrontEndConfig::subpixel_iterations and require_converged_fit.
  int subpixel_iterations = FrontEndConfig{}.subpixel_iterations;
  bool require_converged_fit = FrontEndConfig{}.require_converged_fit;
  // Image front end: FrontEndConfig::view_correlated_error_scale (0: off) and view_correlation_deg.
  double view_correlated_error_scale = FrontEndConfig{}.view_correlated_error_scale;
  double view_correlation_deg = FrontEndConfig{}.view_correlation_deg;
  // Image front end: FrontEndConfig::deformation_error_scale (0: off) and deformation_error_power.
  double deformation_error_scale = FrontEndConfig{}.deformation_error_scale;
  double deformation_error_power = FrontEndConfig{}.deformation_error_power;
  // Image front end: FrontEndConfig::confirm_min_depth_information (0: no provisional primitives) and
  // provisional_max_updates (0: keep them flagged). core/frontend/EXPERIMENTS.md, "Confirmation by parallax".
  double confirm_depth_information = FrontEndConfig{}.confirm_min_depth_information;
  std::uint32_t provisional_max_updates = FrontEndConfig{}.provisional_max_updates;
  bool erase_provisional_rejected = FrontEndConfig{}.erase_provisional_rejected;
  std::uint32_t coverage_every = 10;   // progress line: ground-truth coverage every N images
  std::size_t oracle_sites = 70000;
  bool model_free_mask = false;        // also block cells under the model's primitives (GridDriver)
  bool live = true;                    // live progress line on stderr
  bool gate_diagnostics = false;       // image front end: classify tracked observations against ground truth
  bool tail_oracle = false;            // image front end: refuse the matches ground truth puts in the tail
  bool normal_oracle = false;          // image front end: every primitive adopts the mesh's normal before each update
  bool normal_diagnostics = false;     // image front end: print the normals against the truth by source at the end
};

// The world and its ground truth, built once and shared by the runs of --compare.
struct SimSetup {
  sim::SceneConfig scene;
  std::unique_ptr<sim::SimWorld> world;
  std::unique_ptr<sim::GroundTruth> ground_truth;
};

// SplitPath's epsilon (cells) for the options and the grid's cell size.
double split_epsilon_for(const MissionOptions& options, double cell_size);

// Throws sim::SimError for a bad scene or mesh.
SimSetup build_setup(const sim::SceneConfig& scene, std::uint64_t seed, std::size_t ground_truth_samples = 50000);

// Runs a mission; the final model stays in mission_pool() until the next run. Throws sim::SimError
// for simulator errors; planner failures end the mission with summary.failed set.
MissionSummary run_mission(const SimSetup& setup, const MissionOptions& options, MissionTrace* trace);

const PrimitivePoolView& mission_pool();
const char* to_string(MeasurementKind kind);

}  // namespace vantage::simtarget
