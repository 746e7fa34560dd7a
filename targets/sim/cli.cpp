#include "targets/sim/cli.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <unistd.h>

#include "core/planning/planner_policy.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/sim_error.hpp"
#include "targets/common/tracking_summary.hpp"
#include "targets/sim/mission.hpp"
#include "targets/sim/report.hpp"

namespace vantage::simtarget {

namespace {

int exit_code(const MissionSummary& s) { return s.reached_goal ? 0 : (s.failed ? 3 : 2); }

std::string compare_table(const std::vector<MissionSummary>& runs) {
  std::ostringstream out;
  char line[512];
  std::snprintf(line, sizeof line, "%-9s %-8s %7s %9s %11s %9s %9s %9s %10s %12s %14s  %s\n", "planner", "goal",
                "images", "NBV iter", "path", "coverage", "verified", "model cov", "avg sigma", "accuracy", "plan s/iter",
                "end");
  out << line;
  for (const MissionSummary& s : runs) {
    const double per_iteration = s.nbv_iterations > 0 ? s.planning_seconds / s.nbv_iterations : 0.0;
    std::snprintf(line, sizeof line, "%-9s %-8s %7u %9u %11.1f %8.1f%% %8.1f%% %8.1f%% %10.5f %12.5f %14.3f  %s\n",
                  s.planner.c_str(), s.reached_goal ? "reached" : "no", s.images, s.nbv_iterations, s.path_length,
                  100.0 * s.coverage, 100.0 * s.verified_coverage, 100.0 * s.model_coverage, s.mean_sigma,
                  s.accuracy_rms, per_iteration, s.end_reason.c_str());
    out << line;
  }
  return out.str();
}

}  // namespace

int run_cli(int argc, const char* const* argv) {
  CLI::App app{"vantage-sim: next-best-view sensing strategy in simulation (Dunn, van den Berg, Frahm, IROS 2009)"};
  std::string scene_file, mesh_path, planner_name = "nbv", out_dir, measurement = "image";
  bool compare = false, quiet = false;
  MissionOptions options;
  app.add_option("--scene", scene_file, "TOML scene file (sim_hal/scenes/bunny.toml documents the fields)")
      ->check(CLI::ExistingFile);
  app.add_option("--mesh", mesh_path, "mesh file (any format assimp reads); overrides the scene's mesh");
  app.add_option("--planner", planner_name, "nbv (ours), reactive, direct, orbit or random")
      ->check(CLI::IsMember({"nbv", "reactive", "direct", "orbit", "random"}));
  app.add_flag("--compare", compare, "run every planner on the same scene and seed and print one table");
  app.add_option("--out", out_dir, "write the report (figures, PLY, summary.json) into this folder");
  app.add_option("--budget", options.budget, "image budget, the two initial images included")
      ->check(CLI::Range(3u, 100000u));
  app.add_option("--measurement", measurement, "image (the image front end) or oracle (ground-truth matches)")
      ->check(CLI::IsMember({"image", "oracle"}));
  app.add_option("--seed", options.seed, "seed of the scene noise, the oracle and the random planner");
  app.add_option("--coverage-target", options.coverage_target, "stop at this ground-truth coverage")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--sigma-target", options.sigma_target, "stop when the average sigma is below this (rho)")
      ->check(CLI::PositiveNumber);
  app.add_option("--eta", options.eta_utility, "replan when the utility U falls below this");
  app.add_option("--eta-relative", options.eta_relative,
                 "also replan when U falls below this fraction of U right after PredictModel (0: off)")
      ->check(CLI::Range(0.0, 0.999));
  app.add_option("--image-spacing", options.image_spacing,
                 "sampling rate along a path: about one image per this many units (default 4)")
      ->check(CLI::Range(0.01, 1000.0));
  app.add_option("--epsilon", options.split_epsilon_cells,
                 "SplitPath band half-width and halting distance, cells (overrides --image-spacing)")
      ->check(CLI::Range(0.5, 1000.0));
  app.add_flag("--capture-on-segments", options.capture_on_segments,
               "also sense at the intermediate cells of the PathQry segments between waypoints");
  app.add_option("--unconsumed-after", options.unconsumed_after,
                 "leave a primitive out of the criterion after this many rejected observations in a row "
                 "(0: off, default 3)")
      ->check(CLI::Range(0u, 255u));
  app.add_flag("--keep-unsearchable", options.keep_unsearchable,
               "image front end: keep an unconsumed primitive whose 3-sigma ellipse exceeds the search window "
               "(default: erase it so its region is spawned again)");
  app.add_flag("--inverse-warp-masked", options.inverse_warp_masked,
               "image front end: match a primitive whose warped template would be masked by warping the image "
               "instead (default off: more coverage, less consistent estimates; core/frontend/EXPERIMENTS.md)");
  app.add_option("--inverse-warp-ncc-min", options.inverse_warp_ncc_min,
                 "image front end: the NCC an inverse-warp match must reach (with --inverse-warp-masked)")
      ->check(CLI::Range(0.01, 0.999))
      ->capture_default_str();
  app.add_option("--epipolar-guard", options.epipolar_guard_fraction,
                 "image front end: how far past the depth range a new primitive's epipolar search looks, as a "
                 "fraction of the range's inverse-depth span (a best peak there spawns nothing; 0: off)")
      ->check(CLI::Range(0.0, vantage::kMaxEpipolarGuardFraction))
      ->capture_default_str();
  app.add_option("--spawn-back-match-px", options.spawn_back_match_max_px,
                 "image front end: a new primitive's match must match back to within this many pixels of its "
                 "seed along the reverse epipolar line (the left-right check; 0: off)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_flag("--spawn-requires-plane-fit", options.spawn_requires_plane_fit,
               "image front end: erase a new primitive whose neighbours fit no plane (a depth edge, or alone) "
               "before it is tracked (default off: more accurate primitives, less coverage at 270 images)");
  // rays / scatter, mapped onto the bool after parsing.
  std::string spawn_normal_fit = options.spawn_normal_fit_along_rays ? "rays" : "scatter";
  app.add_option("--spawn-normal-fit", spawn_normal_fit,
                 "image front end: a new primitive's normal from its neighbours, fitted along the spawn camera's "
                 "rays (rays) or by the scatter's smallest axis (scatter)")
      ->check(CLI::IsMember({"rays", "scatter"}))
      ->capture_default_str();
  app.add_flag("--presmooth", options.presmooth,
               "image front end: low-pass every frame (3x3 binomial) before seeding and matching (default off)");
  app.add_option("--match-floor-rad", options.match_sigma_floor_rad,
                 "image front end: standard deviation added to every match's own, as an angle (rad; times the "
                 "focal length in px per axis: 1.5e-4, the default, is 0.087 px at the paper's 640x480 camera)")
      ->check(CLI::Range(1e-6, 9e-3))
      ->capture_default_str();
  app.add_option("--match-floor-tilt-power", options.match_floor_tilt_power,
                 "image front end: a tracked match's floor grows as 1 / cos(tilt)^K, the tilt the surface's in the "
                 "creating view or this one, whichever is larger (0: off, the default; 1 with --match-floor-rad 1.1e-4 and "
                 "--require-converged-fit: more precise verified coverage, less coverage)")
      ->check(CLI::Range(0.0, vantage::kMaxMatchFloorTiltPower))
      ->capture_default_str();
  app.add_option("--refit-residual-floor", options.normal_refit_residual_floor,
                 "image front end: a normal refit's tilt variance is at least this times its residual variance "
                 "over its points' spread (0: off, the default; 1: more verified coverage at 600 images, less at 270)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--spawn-residual-floor", options.normal_spawn_residual_floor,
                 "image front end: a new primitive's plane fit claims a tilt variance of at least this times its "
                 "residual variance over its points' spread, below the facing prior's (0: off; 1, the default: more "
                 "honest new normals; with --refit-residual-floor 1 also more verified coverage at 600 images)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--max-match-sigma-rad", options.max_match_sigma_rad,
                 "image front end: a tracked match whose modelled standard deviation exceeds this angle (rad; times "
                 "the focal length: 7e-4, the default, is 0.41 px at 640x480) is not used (0: off; lower: fewer "
                 "matches, more consistent primitives)")
      ->check(CLI::Range(0.0, 9e-3))
      ->capture_default_str();
  app.add_option("--view-correlated-error", options.view_correlated_error_scale,
                 "image front end: a match error shared by a primitive's matches from nearby views, as this multiple "
                 "of its patch noise's covariance (0, the default: off; 2: the missions' measured share)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--view-correlation-deg", options.view_correlation_deg,
                 "image front end: the angle over which that error decorrelates, exp(-angle / this) (degrees)")
      ->check(CLI::Range(0.1, 180.0))
      ->capture_default_str();
  app.add_option("--deformation-error", options.deformation_error_scale,
                 "image front end: the view-correlated error of a match whose warp stretches the reference patch "
                 "unevenly, this times (singular value ratio - 1)^power times the match floor (0, the default: "
                 "off; 60 with --match-floor-rad 1e-4: every tracked row of the consistency test in its band)")
      ->check(CLI::Range(0.0, 1e4))
      ->capture_default_str();
  app.add_option("--deformation-error-power", options.deformation_error_power,
                 "image front end: the power of (singular value ratio - 1) in that error")
      ->check(CLI::Range(0.1, vantage::kMaxDeformationErrorPower))
      ->capture_default_str();
  app.add_flag("--refit-supersedes-spawn-fit", options.refit_supersedes_spawn_fit,
               "image front end: a normal refit replaces the spawn's plane fit whatever that claims (more verified "
               "coverage, a 640x480 plane's NEES below its band; default off)");
  // The floor was a fixed pixel figure until session 12: an old script gets told what replaced it.
  double retired_floor_px = 0.0;
  CLI::Option* retired_floor = app.add_option("--match-floor-px", retired_floor_px)->group("");
  app.add_option("--direct-fit-px", options.direct_fit_max_px,
                 "image front end: match a primitive whose prior 3-sigma ellipse is within this many pixels by the "
                 "subpixel fit from its prediction, searching only if that fails (default 1; 0: always search)")
      ->check(CLI::Range(0.0, 12.0));
  app.add_option("--subpixel-iterations", options.subpixel_iterations,
                 "image front end: Gauss-Newton steps of the subpixel fit (default 3; 0: the NCC parabola only)")
      ->check(CLI::Range(0, 20));
  app.add_flag("--require-converged-fit", options.require_converged_fit,
               "image front end: a tracked match whose subpixel fit did not converge is not used (with "
               "--subpixel-iterations 6: more precise verified coverage, planes' NEES below band; default off)");
  app.add_option("--confirm-depth-information", options.confirm_depth_information,
                 "image front end: a new primitive stays provisional until an update divides its seed-ray variance "
                 "by 1 + this (default 1; 0: off)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--provisional-max-updates", options.provisional_max_updates,
                 "image front end: erase a provisional primitive at this many accepted updates (default 0: keep)")
      ->check(CLI::Range(0u, 255u));
  app.add_flag("--erase-provisional-rejected", options.erase_provisional_rejected,
               "image front end: erase a provisional primitive whose match fails or is gated in a view where its "
               "depth would show");
  app.add_option("--oracle-sites", options.oracle_sites, "candidate primitive sites of the oracle")
      ->check(CLI::Range(100u, 1000000u));
  std::size_t gt_samples = 50000;
  app.add_option("--gt-samples", gt_samples, "ground-truth surface samples (coverage and the visible set)")
      ->check(CLI::Range(100u, 10000000u));
  app.add_flag("--model-free-mask", options.model_free_mask,
               "also treat cells under the model's primitives as occupied (paths may get blocked mid-way)");
  app.add_flag("--quiet", quiet, "no live progress line");
  app.add_flag("--gate-diagnostics", options.gate_diagnostics,
               "image front end: classify its tracked observations (gated or not) against ground truth, print a summary");
  app.add_flag("--tail-oracle", options.tail_oracle,
               "image front end: refuse every tracked match ground truth puts beyond the chi2(2) 99% quantile "
               "(a diagnostic: what a perfect test for the matches' tail would buy)");
  app.add_flag("--normal-oracle", options.normal_oracle,
               "image front end: before each update every primitive adopts the mesh's normal at its seed (a "
               "diagnostic: what normals as good as the truth would buy)");
  app.add_flag("--normal-diagnostics", options.normal_diagnostics,
               "image front end: at the end, print each normal source's normals against the mesh's (angle, "
               "claimed tilt sd, their primitives' NEES)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 1;
  }
  if (retired_floor->count() > 0) {
    std::cerr << "vantage-sim: --match-floor-px was replaced by --match-floor-rad, the floor as an angle "
                 "(RAD = PX / the focal length in px; 0.05 px at the 640x480 camera is 8.6e-5)\n";
    return 1;
  }
  options.live = !quiet;
  options.spawn_normal_fit_along_rays = spawn_normal_fit == "rays";
  options.measurement = measurement == "oracle" ? MeasurementKind::kOracle : MeasurementKind::kImage;
  if (options.gate_diagnostics && options.measurement != MeasurementKind::kImage) {
    // The diagnostics classify the image front end's matches; the oracle's observations are ground truth.
    std::cerr << "vantage-sim: --gate-diagnostics needs --measurement image (got " << measurement << ")\n";
    return 1;
  }
  if (options.tail_oracle && options.measurement != MeasurementKind::kImage) {
    std::cerr << "vantage-sim: --tail-oracle needs --measurement image (got " << measurement << ")\n";
    return 1;
  }
  if (options.normal_oracle && options.measurement != MeasurementKind::kImage) {
    std::cerr << "vantage-sim: --normal-oracle needs --measurement image (got " << measurement << ")\n";
    return 1;
  }
  if (options.normal_diagnostics && options.measurement != MeasurementKind::kImage) {
    std::cerr << "vantage-sim: --normal-diagnostics needs --measurement image (got " << measurement << ")\n";
    return 1;
  }
  if (options.tail_oracle && options.gate_diagnostics) {
    // The front end shows one observer; each of the two needs to see every observation.
    std::cerr << "vantage-sim: --tail-oracle and --gate-diagnostics cannot be used together\n";
    return 1;
  }
  if (!parse_planner_policy(planner_name.c_str(), &options.planner)) {
    std::cerr << "vantage-sim: --planner " << planner_name << ": unknown planner\n";
    return 1;
  }

  try {
    sim::SceneConfig scene = scene_file.empty() ? sim::SceneConfig::paper_defaults() : sim::load_scene_config(scene_file);
    if (!mesh_path.empty()) {
      scene.mesh_path = mesh_path;
      scene.source += " + --mesh " + mesh_path;
    }
    options.scene_name = scene_file.empty() ? "paper bunny (defaults), mesh " + scene.mesh_path
                                            : scene_file + ", mesh " + scene.mesh_path;
    // The report folder must be writable before any work is done.
    std::vector<PlannerPolicy> planners;
    if (compare) {
      for (const PlannerPolicy p : kAllPlannerPolicies) planners.push_back(p);
    } else {
      planners.push_back(options.planner);
    }
    if (!out_dir.empty()) {
      for (const PlannerPolicy p : planners) {
        const std::string dir = compare ? (std::filesystem::path(out_dir) / to_string(p)).string() : out_dir;
        std::string error;
        if (!prepare_output_dir(dir, &error)) {
          std::cerr << "vantage-sim: " << error << "\n";
          return 1;
        }
      }
    }
    std::cerr << "vantage-sim: loading " << scene.mesh_path << " and computing the ground truth ...\n";
    const SimSetup setup = build_setup(scene, options.seed, gt_samples);
    std::vector<MissionSummary> runs;
    for (const PlannerPolicy p : planners) {
      options.planner = p;
      MissionTrace trace;
      const MissionSummary summary = run_mission(setup, options, &trace);
      runs.push_back(summary);
      std::cout << to_string(p) << ": " << (summary.reached_goal ? "goals reached" : summary.end_reason) << " after "
                << summary.images << " images, " << summary.nbv_iterations << " NBV iterations, path "
                << summary.path_length << ", coverage " << 100.0 * summary.coverage << "% (model "
                << 100.0 * summary.model_coverage << "%), avg sigma "
                << summary.mean_sigma << ", accuracy rms " << summary.accuracy_rms << ", planning "
                << summary.planning_seconds << " s, wall " << summary.wall_seconds << " s\n";
      std::cout << "  accuracy: rms " << summary.accuracy_rms << " p95 " << summary.accuracy_p95 << "; confirmed rms "
                << summary.accuracy_rms_confirmed << " p95 " << summary.accuracy_p95_confirmed << "; provisional "
                << summary.provisional << " of " << summary.primitives << " (rms " << summary.accuracy_rms_provisional
                << "; never observed " << summary.provisional_unobserved << ", rms " << summary.accuracy_rms_unobserved
                << "); >= 2 updates rms " << summary.accuracy_rms_updated2 << "; > 1 unit off "
                << summary.gross << " (provisional " << summary.gross_provisional << ")\n";
      std::cout << "  verified: coverage " << 100.0 * summary.verified_coverage << "%; " << summary.precise_verified
                << " of the " << summary.precise << " primitives with sigma < target lie within " << kVerifiedSigmas
                << " of their sigmas of the surface\n";
      if (summary.measurement == to_string(MeasurementKind::kImage)) {
        std::cout << "  " << targets::tracking_summary(summary.tracks_predicted, summary.tracks_matched,
                                                   summary.tracks_inverse_warped, summary.track_failures) << "\n";
        std::cout << "  " << targets::seeding_summary(summary.seeds_tried, summary.seeds_matched,
                                                  summary.seeds_beyond_depth_range,
                                                  summary.seeds_rejected_back_match,
                                                  summary.seeds_rejected_no_plane_fit) << "\n";
      }
      std::cout << "  " << targets::innovation_summary(summary.innovations) << "\n";
      if (!out_dir.empty()) {
        const std::string dir = compare ? (std::filesystem::path(out_dir) / to_string(p)).string() : out_dir;
        std::string error;
        if (!write_report(dir, trace, summary, mission_pool(), setup.scene.intrinsics, setup.scene.viewing_distance,
                          &error)) {
          std::cerr << "vantage-sim: report: " << error << "\n";
        } else {
          std::cout << "report written to " << dir << "\n";
        }
      }
    }
    if (compare) {
      const std::string table = compare_table(runs);
      std::cout << "\n" << table;
      if (!out_dir.empty()) {
        std::ofstream(std::filesystem::path(out_dir) / "compare.txt") << table;
      }
      for (const MissionSummary& s : runs) {
        if (s.failed) return 3;
      }
      return 0;
    }
    return exit_code(runs.front());
  } catch (const sim::SimError& e) {
    std::cerr << "vantage-sim: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace vantage::simtarget
