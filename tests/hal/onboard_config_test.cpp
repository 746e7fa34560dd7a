// vantage-onboard's YAML configuration: defaults, every section, and one-line errors naming the field.
#include <catch2/catch.hpp>

#include <cstdio>
#include <fstream>
#include <string>

#include "targets/onboard/onboard_config.hpp"

using namespace vantage;
using namespace vantage::onboard;

namespace {

std::string error_for(const std::string& yaml) {
  OnboardConfig config;
  config.mavlink.endpoint = "untouched";
  const std::string error = parse_onboard_config(yaml, "onboard.yaml", "/etc/vantage", &config);
  CHECK(config.mavlink.endpoint == "untouched");
  return error;
}

}  // namespace

TEST_CASE("a full onboard configuration is read", "[onboard]") {
  const std::string yaml = R"(
camera:
  driver: v4l2
  device: /dev/video2
  format: NV12
  width: 1280
  height: 720
  frame_rate_hz: 15
  buffers: 6
  calibration: cam.yaml
mavlink:
  endpoint: serial:/dev/ttyAMA0:921600
  signing_key_file: /secrets/key.hex
  link_id: 7
  link_loss_timeout_s: 2.5
  world_origin_ned: [1, 2, -3]
mission:
  cell_size_m: 0.5
  elevation_m: 2
  center_xy: [4, 5]
  viewing_distance_m: 10
  keep_out_radius_m: 3
  max_images: 120
  inverse_warp_masked: true
  inverse_warp_ncc_min: 0.95
  spawn_normal_fit_along_rays: false
  epipolar_guard_fraction: 1.5
  spawn_back_match_max_px: 0.75
  spawn_requires_plane_fit: true
  max_match_sigma_rad: 4.3e-4
  subpixel_iterations: 6
  require_converged_fit: true
  match_sigma_floor_rad: 1.4e-4
  match_floor_tilt_power: 1
  view_correlated_error_scale: 2
  view_correlation_deg: 20
  deformation_error_scale: 60
  deformation_error_power: 2.5
)";
  OnboardConfig c;
  REQUIRE(parse_onboard_config(yaml, "onboard.yaml", "/etc/vantage", &c) == "");
  CHECK(c.camera.driver == CameraDriver::kV4l2);
  CHECK(c.camera.device == "/dev/video2");
  CHECK(c.camera.format == hal::PixelFormat::kNv12);
  CHECK(c.camera.width_px == 1280);
  CHECK(c.camera.buffers == 6);
  CHECK(c.camera.calibration == "/etc/vantage/cam.yaml");
  CHECK(c.mavlink.endpoint == "serial:/dev/ttyAMA0:921600");
  CHECK(c.mavlink.signing_key_file == "/secrets/key.hex");
  CHECK(c.mavlink.motion.signing_link_id == 7);
  CHECK(c.mavlink.motion.link_loss_timeout_s == 2.5);
  CHECK(c.mavlink.motion.frame.world_origin_ned == Eigen::Vector3d(1, 2, -3));
  CHECK(c.mission.grid.cell_size_m == 0.5);
  CHECK(c.mission.grid.center_xy == Eigen::Vector2d(4, 5));
  CHECK(c.mission.keep_out_radius_m == 3);
  CHECK(c.mission.max_images == 120u);
  CHECK(c.mission.inverse_warp_masked);
  CHECK(c.mission.inverse_warp_ncc_min == 0.95);
  CHECK_FALSE(c.mission.spawn_normal_fit_along_rays);
  CHECK(c.mission.epipolar_guard_fraction == 1.5);
  CHECK(c.mission.spawn_back_match_max_px == 0.75);
  CHECK(c.mission.spawn_requires_plane_fit);
  CHECK(c.mission.max_match_sigma_rad == 4.3e-4);
  CHECK(c.mission.subpixel_iterations == 6);
  CHECK(c.mission.require_converged_fit);
  CHECK(c.mission.match_sigma_floor_rad == 1.4e-4);
  CHECK(c.mission.match_floor_tilt_power == 1.0);
  CHECK(c.mission.view_correlated_error_scale == 2.0);
  CHECK(c.mission.view_correlation_deg == 20.0);
  CHECK(c.mission.deformation_error_scale == 60.0);
  CHECK(c.mission.deformation_error_power == 2.5);
  OnboardConfig defaults;
  REQUIRE(parse_onboard_config("camera:\n  driver: sim\n", "onboard.yaml", "", &defaults) == "");
  CHECK_FALSE(defaults.mission.inverse_warp_masked);
  CHECK(defaults.mission.inverse_warp_ncc_min == FrontEndConfig{}.inverse_warp_ncc_min);
  CHECK(defaults.mission.spawn_normal_fit_along_rays);
  CHECK(defaults.mission.epipolar_guard_fraction == FrontEndConfig{}.epipolar_guard_fraction);
  CHECK(defaults.mission.spawn_back_match_max_px == FrontEndConfig{}.spawn_back_match_max_px);
  CHECK(defaults.mission.spawn_requires_plane_fit == FrontEndConfig{}.spawn_requires_plane_fit);
  CHECK(defaults.mission.max_match_sigma_rad == FrontEndConfig{}.max_match_sigma_rad);
  CHECK(defaults.mission.subpixel_iterations == FrontEndConfig{}.subpixel_iterations);
  CHECK(defaults.mission.require_converged_fit == FrontEndConfig{}.require_converged_fit);
  CHECK(defaults.mission.match_sigma_floor_rad == FrontEndConfig{}.match_sigma_floor_rad);
  CHECK(defaults.mission.match_floor_tilt_power == FrontEndConfig{}.match_floor_tilt_power);
  CHECK(defaults.mission.view_correlated_error_scale == FrontEndConfig{}.view_correlated_error_scale);
  CHECK(defaults.mission.view_correlation_deg == FrontEndConfig{}.view_correlation_deg);
  CHECK(defaults.mission.deformation_error_scale == FrontEndConfig{}.deformation_error_scale);
  CHECK(defaults.mission.deformation_error_power == FrontEndConfig{}.deformation_error_power);
}

TEST_CASE("onboard configuration errors name the file and field", "[onboard]") {
  CHECK(error_for("camera:\n  driver: usb\n") == "onboard.yaml: camera.driver: 'usb' is not v4l2, libcamera or sim");
  CHECK(error_for("camera:\n  driver: v4l2\n") ==
        "onboard.yaml: camera.calibration: required for a real camera (a camera_info YAML file)");
  CHECK(error_for("camera:\n  driver: sim\n  format: RGGB\n") ==
        "onboard.yaml: camera.format: 'RGGB' is not GREY, YUYV, UYVY, NV12, RGB3, BGR3, XR24 or MJPG");
  CHECK(error_for("camera:\n  driver: sim\n  width: 4000\n") == "onboard.yaml: camera.width: 4000 is outside [16, 1280]");
  CHECK(error_for("camera:\n  driver: sim\n  buffers: two\n") == "onboard.yaml: camera.buffers: must be a number");
  CHECK(error_for("camera:\n  driver: sim\n  colour: red\n") == "onboard.yaml: camera.colour: unknown field");
  CHECK(error_for("camera:\n  driver: sim\nmavlink:\n  endpoint: udp:localhost\n")
            .find("onboard.yaml: mavlink.endpoint: endpoint 'udp:localhost'") == 0);
  CHECK(error_for("camera:\n  driver: sim\nmavlink:\n  heartbeat_period_s: 4\n  link_loss_timeout_s: 3\n") ==
        "onboard.yaml: mavlink: link_loss_timeout_s must exceed heartbeat_period_s and be at most 60");
  CHECK(error_for("camera:\n  driver: sim\nmavlink:\n  world_origin_ned: [1, 2]\n") ==
        "onboard.yaml: mavlink.world_origin_ned: must be a list of 3 numbers");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  cells_per_side: 40\n").find("onboard.yaml: mission.cells_per_side: this build holds a 60x60") == 0);
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  viewing_distance_m: 70\n") ==
        "onboard.yaml: mission.viewing_distance_m: the initial views would lie outside the grid");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  depth_min_m: 30\n  depth_max_m: 20\n") ==
        "onboard.yaml: mission.depth_max_m: must be larger than depth_min_m");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  depth_min_m: -1\n").find("onboard.yaml: mission.depth_min_m: ") == 0);
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  inverse_warp_masked: sometimes\n") ==
        "onboard.yaml: mission.inverse_warp_masked: must be true or false");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  spawn_normal_fit_along_rays: 1.5\n") ==
        "onboard.yaml: mission.spawn_normal_fit_along_rays: must be true or false");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  epipolar_guard_fraction: -0.5\n") ==
        "onboard.yaml: mission.epipolar_guard_fraction: -0.5 is outside [0, 4]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  spawn_back_match_max_px: -1\n") ==
        "onboard.yaml: mission.spawn_back_match_max_px: -1 is outside [0, 100]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  max_match_sigma_rad: 0.01\n") ==
        "onboard.yaml: mission.max_match_sigma_rad: 0.01 is outside [0, 0.009]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  subpixel_iterations: 21\n") ==
        "onboard.yaml: mission.subpixel_iterations: 21 is outside [0, 20]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  match_sigma_floor_rad: 0\n") ==
        "onboard.yaml: mission.match_sigma_floor_rad: 0 is outside [1e-06, 0.009]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  match_floor_tilt_power: 5\n") ==
        "onboard.yaml: mission.match_floor_tilt_power: 5 is outside [0, 4]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  view_correlation_deg: 0\n") ==
        "onboard.yaml: mission.view_correlation_deg: 0 is outside [0.1, 180]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  deformation_error_scale: -1\n") ==
        "onboard.yaml: mission.deformation_error_scale: -1 is outside [0, 10000]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  deformation_error_power: 9\n") ==
        "onboard.yaml: mission.deformation_error_power: 9 is outside [0.1, 8]");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  epipolar_guard_fraction: wide\n") ==
        "onboard.yaml: mission.epipolar_guard_fraction: must be a number");
  CHECK(error_for("camera:\n  driver: sim\nmission:\n  inverse_warp_ncc_min: 1\n") ==
        "onboard.yaml: mission.inverse_warp_ncc_min: 1 is outside [0.01, 0.999]");
  CHECK(error_for("camera: [unclosed\n").find("onboard.yaml: line ") == 0);
  CHECK(error_for("robot: {}\n") == "onboard.yaml: robot: unknown section");
}

TEST_CASE("signing key files must hold 64 hex digits", "[onboard]") {
  const std::string good = "vantage_onboard_test_key.hex";
  {
    std::ofstream f(good);
    f << "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1F\n";
  }
  hal::mavlink::SigningKey key{};
  REQUIRE(load_signing_key(good, &key) == "");
  CHECK(key[1] == 1);
  CHECK(key[31] == 0x1F);
  {
    std::ofstream f(good);
    f << "0001";
  }
  CHECK(load_signing_key(good, &key) == good + ": must hold exactly 64 hex digits (a 32-byte key)");
  std::remove(good.c_str());
  CHECK(load_signing_key("/nonexistent.hex", &key) == "/nonexistent.hex: cannot open the signing key file");
}
