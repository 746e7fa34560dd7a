// vantage-onboard: the planner on the robot. Reads a YAML configuration, opens the configured camera
// (V4L2, libcamera, or the simulator's camera for SITL), talks MAVLink 2 to the autopilot and runs one
// next-best-view mission. Exit codes: 0 done, 1 mission failed, 2 configuration, 3 camera, 4 vehicle.
#include <cstdio>
#include <cstring>
#include <string>

#include "hal/calibration/camera_info.hpp"
#include "hal/mavlink/link.hpp"
#include "hal/mavlink/mavlink_motion.hpp"
#include "hal/steady_clock.hpp"
#include "hal/v4l2/v4l2_camera.hpp"
#include "targets/onboard/mission.hpp"
#include "targets/onboard/onboard_config.hpp"
#ifdef VANTAGE_ONBOARD_LIBCAMERA
#include "hal/libcamera/libcamera_camera.hpp"
#endif
#ifdef VANTAGE_ONBOARD_SIM_CAMERA
#include "targets/onboard/sitl_camera.hpp"
#endif

namespace {

using namespace vantage;
using namespace vantage::onboard;

// Drivers live as long as the process; static so their fixed buffers are not on the stack.
hal::V4l2Camera g_v4l2;
#ifdef VANTAGE_ONBOARD_LIBCAMERA
hal::LibcameraCamera g_libcamera;
#endif
hal::mavlink::UdpLink g_udp;
hal::mavlink::SerialLink g_serial;
hal::SteadyClock g_clock;

int fail(int code, const std::string& line) {
  std::fprintf(stderr, "vantage-onboard: %s\n", line.c_str());
  return code;
}

void print_usage() {
  std::printf("usage: vantage-onboard [--config] FILE.yaml\n"
              "       vantage-onboard --footprint   (print the static memory footprint and exit)\n");
}

void print_banner() {
#ifdef VANTAGE_ONBOARD_LIBCAMERA
  std::printf("vantage-onboard: cameras: v4l2, libcamera");
#else
  std::printf("vantage-onboard: cameras: v4l2 (built without libcamera: VANTAGE_WITH_LIBCAMERA=OFF)");
#endif
#ifdef VANTAGE_ONBOARD_SIM_CAMERA
  std::printf(", sim (SITL)\n");
#else
  std::printf("\n");
#endif
  const StaticFootprint f = static_footprint();
  std::printf("static memory: %zu bytes (model pool %zu, front end %zu, view grid %zu, executive %zu, frames %zu)\n",
              f.total(), f.pool_bytes, f.front_end_bytes, f.grid_bytes, f.executive_bytes, f.frame_bytes);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::string config_path;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      print_usage();
      return 0;
    }
    if (arg == "--footprint") {
      print_banner();
      return 0;
    }
    if (arg == "--config" && i + 1 < argc) {
      config_path = argv[++i];
    } else if (config_path.empty() && arg.rfind("--", 0) != 0) {
      config_path = arg;
    } else {
      return fail(kExitConfig, "unknown argument '" + arg + "' (see --help)");
    }
  }
  if (config_path.empty()) return fail(kExitConfig, "no configuration file given (see --help)");
  print_banner();

  OnboardConfig config;
  std::string error = load_onboard_config(config_path, &config);
  if (!error.empty()) return fail(kExitConfig, error);

  PinholeIntrinsics intrinsics;
  if (config.camera.driver != CameraDriver::kSim) {
    std::string note;
    error = hal::load_camera_info(config.camera.calibration, &intrinsics, &note);
    if (!error.empty()) return fail(kExitConfig, error);
    if (!note.empty()) std::printf("calibration: %s\n", note.c_str());
  }

  // The link comes first only for the sim camera, which renders at the vehicle's pose; real cameras are
  // opened before anything talks to the vehicle, so a missing camera stops us at once.
  hal::mavlink::Endpoint endpoint;
  (void)hal::mavlink::parse_endpoint(config.mavlink.endpoint, &endpoint);
  hal::mavlink::ByteLink* link = nullptr;
  hal::mavlink::MavlinkMotionConfig motion_config = config.mavlink.motion;
  if (!config.mavlink.signing_key_file.empty()) {
    error = load_signing_key(config.mavlink.signing_key_file, &motion_config.signing_key);
    if (!error.empty()) return fail(kExitConfig, error);
    motion_config.signing = true;
  }

  hal::Camera* camera = nullptr;
  CameraReopen reopen;
  switch (config.camera.driver) {
    case CameraDriver::kV4l2: {
      hal::V4l2Config vc;
      vc.device = config.camera.device;
      vc.format = config.camera.format;
      vc.width_px = config.camera.width_px;
      vc.height_px = config.camera.height_px;
      vc.frame_rate_hz = config.camera.frame_rate_hz;
      vc.buffer_count = config.camera.buffers;
      vc.intrinsics = intrinsics;
      error = g_v4l2.open(vc);
      if (!error.empty()) return fail(kExitCamera, "camera: " + error);
      std::printf("camera: %s (%s, %s %dx%d at %.1f Hz)\n", g_v4l2.name(), g_v4l2.card(), hal::to_string(vc.format),
                  vc.width_px, vc.height_px, g_v4l2.frame_rate_hz());
      camera = &g_v4l2;
      reopen = [] { return g_v4l2.reopen(); };
      break;
    }
    case CameraDriver::kLibcamera: {
#ifdef VANTAGE_ONBOARD_LIBCAMERA
      hal::LibcameraConfig lc;
      lc.camera_id = config.camera.camera_id;
      lc.format = config.camera.format;
      lc.width_px = config.camera.width_px;
      lc.height_px = config.camera.height_px;
      lc.buffer_count = config.camera.buffers;
      lc.intrinsics = intrinsics;
      error = g_libcamera.open(lc);
      if (!error.empty()) return fail(kExitCamera, "camera: " + error);
      std::printf("camera: %s\n", g_libcamera.name());
      camera = &g_libcamera;
      break;
#else
      return fail(kExitCamera, "camera: " + config.source + ": camera.driver: libcamera is not in this build (VANTAGE_WITH_LIBCAMERA=OFF)");
#endif
    }
    case CameraDriver::kSim:
      break;  // after the link, below
  }

  if (endpoint.kind == hal::mavlink::Endpoint::Kind::kUdp) {
    error = g_udp.open(endpoint.host_or_path, static_cast<std::uint16_t>(endpoint.port_or_baud));
    link = &g_udp;
  } else {
    error = g_serial.open(endpoint.host_or_path, endpoint.port_or_baud);
    link = &g_serial;
  }
  if (!error.empty()) return fail(kExitVehicle, "vehicle: " + error);
  static hal::mavlink::MavlinkMotion motion(*link, g_clock, motion_config);

  if (config.camera.driver == CameraDriver::kSim) {
#ifdef VANTAGE_ONBOARD_SIM_CAMERA
    error = open_sim_camera(config.camera.scene, motion, g_clock, &camera);
    if (!error.empty()) return fail(kExitCamera, "camera: " + error);
    std::printf("camera: %s (rendering at the pose the vehicle reports)\n", camera->name());
#else
    return fail(kExitCamera, "camera: " + config.source + ": camera.driver: sim is only in host builds with the simulator");
#endif
  }

  std::string summary;
  const int code = run_mission(config, *camera, reopen, motion, g_clock, &summary);
  const hal::mavlink::MotionLinkStats& s = motion.stats();
  const hal::mavlink::ParserStats& p = motion.parser_stats();
  std::printf("link: %llu heartbeats, %llu poses, %llu setpoints sent, %llu frames, %llu CRC errors, %llu signature rejects\n",
              static_cast<unsigned long long>(s.heartbeats), static_cast<unsigned long long>(s.poses),
              static_cast<unsigned long long>(s.setpoints_sent), static_cast<unsigned long long>(p.frames),
              static_cast<unsigned long long>(p.crc_errors),
              static_cast<unsigned long long>(s.signature_rejected + s.replay_rejected + s.unsigned_rejected));
  if (code == kExitDone) {
    std::printf("%s\n", summary.c_str());
    return code;
  }
  return fail(code, summary);
}
