#pragma once
// vantage-onboard's configuration file (YAML). Every field has a default except where noted; a wrong
// field is reported as "<file>: <field>: <problem>" and nothing runs. See README.md for a full example.
#include <string>

#include "core/frontend/image_front_end.hpp"
#include "core/grid/grid_geometry.hpp"
#include "hal/mavlink/mavlink_motion.hpp"
#include "hal/v4l2/gray_convert.hpp"

namespace vantage::onboard {

enum class CameraDriver { kV4l2, kLibcamera, kSim };
const char* to_string(CameraDriver driver);

struct CameraSettings {
  CameraDriver driver = CameraDriver::kV4l2;
  std::string device = "/dev/video0";  // v4l2
  std::string camera_id;               // libcamera; empty = first camera
  hal::PixelFormat format = hal::PixelFormat::kYuyv;
  int width_px = 640;
  int height_px = 480;
  double frame_rate_hz = 30.0;
  int buffers = 4;
  int timeout_ms = 1000;        // one grab
  std::string calibration;      // camera_info YAML (required for v4l2 and libcamera), relative to the config file
  std::string scene;            // sim only: sim_hal scene TOML; empty = the paper's bunny
};

struct MavlinkSettings {
  std::string endpoint = "udp:127.0.0.1:14540";  // udp:HOST:PORT or serial:PATH:BAUD
  std::string signing_key_file;  // 64 hex digits (a 32-byte key); empty = unsigned
  hal::mavlink::MavlinkMotionConfig motion;
  double arrive_timeout_s = 60.0;  // one move
};

struct MissionSettings {
  GridGeometry grid;                 // cells_per_side must be kOnboardGridSide
  double viewing_distance_m = 40.0;  // the initial views: this far from the centre, on the -y side
  double keep_out_radius_m = 0.0;    // grid cells within this radius of the centre are never entered
  unsigned max_images = 60;
  double rho_sigma = 0.008;
  double eta_utility = 0.0;
  double split_epsilon_cells = 0.75;
  double depth_min_m = 0.0;          // the front end's epipolar search range (camera z);
  double depth_max_m = 0.0;          // 0: targets::default_search_depth_range
  // FrontEndConfig::inverse_warp_masked: masked templates matched by warping the image (more coverage,
  // less consistent covariances; core/frontend/EXPERIMENTS.md).
  bool inverse_warp_masked = FrontEndConfig{}.inverse_warp_masked;
  // FrontEndConfig::inverse_warp_ncc_min: the NCC such a match must reach (a signal-to-noise threshold,
  // so it depends on the camera and the scene's texture).
  double inverse_warp_ncc_min = FrontEndConfig{}.inverse_warp_ncc_min;
  // FrontEndConfig::spawn_normal_fit_along_rays: a new primitive's normal fitted along the spawn camera's
  // rays (false: the scatter fit of sessions before 21).
  bool spawn_normal_fit_along_rays = FrontEndConfig{}.spawn_normal_fit_along_rays;
  // FrontEndConfig::epipolar_guard_fraction: how far past the depth range a new primitive's epipolar
  // search looks (a fraction of the range's inverse-depth span; a surface found there spawns nothing).
  double epipolar_guard_fraction = FrontEndConfig{}.epipolar_guard_fraction;
  // FrontEndConfig::spawn_back_match_max_px: a new primitive's match must match back to its seed within
  // this many pixels (the left-right check; 0: off).
  double spawn_back_match_max_px = FrontEndConfig{}.spawn_back_match_max_px;
  // FrontEndConfig::spawn_requires_plane_fit: a new primitive whose neighbours fit no plane is erased before
  // it is tracked (more accurate primitives, less coverage early in a mission).
  bool spawn_requires_plane_fit = FrontEndConfig{}.spawn_requires_plane_fit;
  // FrontEndConfig::max_match_sigma_rad: a tracked match whose modelled sd exceeds this angle times the
  // focal length is not used (0: off; more trustworthy sigmas, less coverage early in a mission).
  double max_match_sigma_rad = FrontEndConfig{}.max_match_sigma_rad;
  // FrontEndConfig::subpixel_iterations and require_converged_fit: a tracked match whose subpixel fit did not
  // converge within that many steps is not used (off: it is taken as it stands).
  int subpixel_iterations = FrontEndConfig{}.subpixel_iterations;
  bool require_converged_fit = FrontEndConfig{}.require_converged_fit;
  // FrontEndConfig::match_sigma_floor_rad: the standard deviation added to every match's own, as an angle.
  double match_sigma_floor_rad = FrontEndConfig{}.match_sigma_floor_rad;
  // FrontEndConfig::match_floor_tilt_power: a tracked match's floor / cos(tilt)^k (0: off).
  double match_floor_tilt_power = FrontEndConfig{}.match_floor_tilt_power;
  // FrontEndConfig::view_correlated_error_scale (0: off) and view_correlation_deg: a match error shared by a
  // primitive's matches from nearby views, as a multiple of its patch noise, decorrelating over that angle.
  double view_correlated_error_scale = FrontEndConfig{}.view_correlated_error_scale;
  double view_correlation_deg = FrontEndConfig{}.view_correlation_deg;
  // FrontEndConfig::deformation_error_scale (0: off) and deformation_error_power: the view-correlated error of
  // a match whose warp stretches the reference patch unevenly.
  double deformation_error_scale = FrontEndConfig{}.deformation_error_scale;
  double deformation_error_power = FrontEndConfig{}.deformation_error_power;
};

struct OnboardConfig {
  std::string source;  // the file it came from
  CameraSettings camera;
  MavlinkSettings mavlink;
  MissionSettings mission;
};

// Empty on success; else one line naming file and field.
std::string load_onboard_config(const std::string& path, OnboardConfig* out);
std::string parse_onboard_config(const std::string& yaml_text, const std::string& source, const std::string& base_dir,
                                 OnboardConfig* out);
// A signing key file: 64 hex digits (whitespace around them allowed).
std::string load_signing_key(const std::string& path, hal::mavlink::SigningKey* key);

}  // namespace vantage::onboard
