#pragma once
// What a mission records for its progress line, its comparison row and its report. Plain data filled
// by the mission loop (targets/sim/mission.cpp); no planning logic here.
#include <cstdint>
#include <string>
#include <vector>

#include "core/frontend/image_front_end.hpp"
#include "core/grid/grid_geometry.hpp"
#include "core/planning/sensing_executive.hpp"

namespace vantage::simtarget {

struct ImageRecord {
  std::uint32_t image = 0;          // images taken so far, this one included
  std::uint32_t nbv_iteration = 0;  // the plan this image belongs to
  double average_sigma = 0.0;       // PrecisionLevel after the update
  double utility = 0.0;             // U(M_nu*, M) after the update
  double coverage = -1.0;           // ground truth coverage when evaluated for this image, else < 0
  GridCell cell{};
};

struct ReplanRecord {
  std::uint32_t at_image = 0;       // images taken when the plan was renewed
  ReplanReason reason = ReplanReason::kNone;
  GridCell nbv{};
  double utility_after = 0.0;       // U right after PredictModel
};

struct MissionTrace {
  GridGeometry geometry;
  std::vector<std::uint8_t> free;         // the planner's free mask at the end
  std::vector<float> first_cost;          // cost after the first grid evaluation
  std::vector<float> final_cost;          // cost after the last grid evaluation
  std::vector<GridCell> initial_cells;    // cells of the two initial views
  std::vector<GridCell> path;             // executed cells in order, the start cell first
  std::vector<ImageRecord> images;
  std::vector<ReplanRecord> replans;
};

// A precise primitive counts toward verified coverage when its distance to the surface is within this many
// of its own standard deviations along that direction: 99.7 % of a consistent estimate's errors are.
inline constexpr double kVerifiedSigmas = 3.0;

struct MissionSummary {
  std::string scene;
  std::string planner;
  std::string measurement;
  std::uint32_t images = 0;
  std::uint32_t nbv_iterations = 0;
  double path_length = 0.0;               // scene units
  double coverage = 0.0;                  // ground truth, [0, 1]: visible samples near a primitive with sigma < target
  double model_coverage = 0.0;            // ground truth, [0, 1]: visible samples near any primitive
  // ground truth, [0, 1]: coverage counting only the precise primitives (sigma < target) whose distance to
  // the surface is within kVerifiedSigmas of their own standard deviation along it (sim_hal/README.md (f))
  double verified_coverage = 0.0;
  std::size_t precise = 0;                // alive primitives with sigma < target
  std::size_t precise_verified = 0;       // of which within kVerifiedSigmas of the surface
  double mean_sigma = 0.0;                // PrecisionLevel, units
  double accuracy_rms = 0.0;              // ground truth, units
  double accuracy_p95 = 0.0;
  // The same over primitives a view has confirmed (not primitive_flags::kProvisional), the count and RMS of
  // the provisional ones, and the RMS over primitives with at least 2 accepted updates (tail-robust).
  double accuracy_rms_confirmed = 0.0;
  double accuracy_p95_confirmed = 0.0;
  std::size_t provisional = 0;
  double accuracy_rms_provisional = 0.0;
  std::size_t provisional_unobserved = 0;    // of which no update accepted since the spawn
  double accuracy_rms_unobserved = 0.0;
  std::size_t gross = 0;                     // primitives more than 1 unit from the surface
  std::size_t gross_provisional = 0;         // of which provisional
  double accuracy_rms_updated2 = 0.0;
  std::size_t primitives = 0;
  bool reached_goal = false;
  std::string end_reason;                 // done reason or failure text
  bool failed = false;
  double planning_seconds = 0.0;          // grid evaluations + planning steps
  double measurement_seconds = 0.0;       // model updates
  double render_seconds = 0.0;            // ray casting
  double wall_seconds = 0.0;
  std::uint32_t grid_evaluations = 0;
  std::uint32_t rejected_images = 0;
  std::uint32_t unreachable_nbv = 0;
  std::uint32_t split_fallbacks = 0;
  std::uint32_t stagnations = 0;
  double split_epsilon_cells = 0.0;       // SplitPath's epsilon used (from the image spacing)
  double coverage_target = 0.99;
  double sigma_target = 0.008;
  std::uint32_t budget = 0;
  std::uint64_t seed = 0;
  // The image front end's tracked observations (zero with the oracle): predicted in view, matched, and
  // why the others failed (FrontEndStats).
  std::uint64_t tracks_predicted = 0;
  std::uint64_t tracks_matched = 0;
  std::uint64_t tracks_inverse_warped = 0;  // of the matched: by the inverse warp (--inverse-warp-masked)
  std::uint64_t photometric_normals = 0;    // of the matched: matched again with a photometric normal
  std::uint64_t photometric_refits_unconverged = 0;  // photometric normals dropped (--require-converged-fit)
  TrackFailureCounts track_failures;
  // Its seeds: searched along an epipolar line, matched, and refused because the best peak lay past the
  // depth range (FrontEndConfig::epipolar_guard_fraction).
  std::uint64_t seeds_tried = 0;
  std::uint64_t seeds_matched = 0;
  std::uint64_t seeds_beyond_depth_range = 0;
  std::uint64_t seeds_rejected_back_match = 0;
  std::uint64_t seeds_rejected_no_plane_fit = 0;  // FrontEndConfig::spawn_requires_plane_fit
  // Every innovation the EKF's gate tested (image front end or oracle): the consistency check without
  // ground truth (core/estimation/nis_histogram.hpp).
  NisHistogram innovations;
};

}  // namespace vantage::simtarget
