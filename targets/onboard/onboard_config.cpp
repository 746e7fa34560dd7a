#include "targets/onboard/onboard_config.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "targets/onboard/onboard_grid.hpp"

namespace vantage::onboard {
namespace {

struct Failure {
  std::string field;
  std::string problem;
};

class Section {
 public:
  Section(const YAML::Node& node, std::string name, std::set<std::string> known)
      : node_(node), name_(std::move(name)) {
    if (!node_ || node_.IsNull()) return;
    if (!node_.IsMap()) throw Failure{name_, "must be a mapping"};
    for (const auto& item : node_) {
      const std::string key = item.first.as<std::string>();
      if (known.count(key) == 0) throw Failure{name_ + "." + key, "unknown field"};
    }
  }
  std::string field(const std::string& key) const { return name_ + "." + key; }
  // An undefined node when the section or the key is absent (then the default stays).
  YAML::Node get(const std::string& key) const {
    if (!node_ || node_.IsNull()) return YAML::Node(YAML::NodeType::Undefined);
    const YAML::Node& section = node_;
    return section[key];
  }

  void text(const std::string& key, std::string* out) const {
    const YAML::Node n = get(key);
    if (!n) return;
    if (!n.IsScalar()) throw Failure{field(key), "must be text"};
    *out = n.Scalar();
  }
  void number(const std::string& key, double* out, double lo, double hi) const {
    const YAML::Node n = get(key);
    if (!n) return;
    double v = 0.0;
    try {
      if (!n.IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "");
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      throw Failure{field(key), "must be a number"};
    }
    if (!std::isfinite(v) || v < lo || v > hi) {
      std::ostringstream s;
      s << v << " is outside [" << lo << ", " << hi << "]";
      throw Failure{field(key), s.str()};
    }
    *out = v;
  }
  template <typename Int>
  void integer(const std::string& key, Int* out, double lo, double hi) const {
    double v = static_cast<double>(*out);
    number(key, &v, lo, hi);
    if (v != std::floor(v)) throw Failure{field(key), "must be a whole number"};
    *out = static_cast<Int>(v);
  }
  void boolean(const std::string& key, bool* out) const {
    const YAML::Node n = get(key);
    if (!n) return;
    try {
      if (!n.IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "");
      *out = n.as<bool>();
    } catch (const YAML::Exception&) {
      throw Failure{field(key), "must be true or false"};
    }
  }
  void vector(const std::string& key, double* out, std::size_t count) const {
    const YAML::Node n = get(key);
    if (!n) return;
    if (!n.IsSequence() || n.size() != count) throw Failure{field(key), "must be a list of " + std::to_string(count) + " numbers"};
    for (std::size_t i = 0; i < count; ++i) {
      try {
        out[i] = n[i].as<double>();
      } catch (const YAML::Exception&) {
        throw Failure{field(key), "must be a list of " + std::to_string(count) + " numbers"};
      }
      if (!std::isfinite(out[i])) throw Failure{field(key), "must be finite"};
    }
  }

 private:
  YAML::Node node_;
  std::string name_;
};

std::string resolve(const std::string& base_dir, const std::string& path) {
  if (path.empty() || path[0] == '/' || base_dir.empty()) return path;
  return base_dir + "/" + path;
}

}  // namespace

const char* to_string(CameraDriver driver) {
  switch (driver) {
    case CameraDriver::kV4l2: return "v4l2";
    case CameraDriver::kLibcamera: return "libcamera";
    case CameraDriver::kSim: return "sim";
  }
  return "?";
}

std::string parse_onboard_config(const std::string& yaml_text, const std::string& source, const std::string& base_dir,
                                 OnboardConfig* out) {
  OnboardConfig c;
  c.source = source;
  c.mission.grid.cells_per_side = kOnboardGridSide;
  try {
    YAML::Node root;
    try {
      root = YAML::Load(yaml_text);
    } catch (const YAML::ParserException& e) {
      return source + ": line " + std::to_string(e.mark.line + 1) + ": not valid YAML (" + e.msg + ")";
    }
    if (!root || !root.IsMap()) throw Failure{"(document)", "must be a mapping with camera, mavlink and mission"};
    const YAML::Node& sections = root;  // const access: a missing section stays undefined
    for (const auto& item : root) {
      const std::string key = item.first.as<std::string>();
      if (key != "camera" && key != "mavlink" && key != "mission") throw Failure{key, "unknown section"};
    }

    const Section cam(sections["camera"], "camera",
                      {"driver", "device", "camera_id", "format", "width", "height", "frame_rate_hz", "buffers",
                       "timeout_ms", "calibration", "scene"});
    std::string driver = "v4l2";
    cam.text("driver", &driver);
    if (driver == "v4l2") c.camera.driver = CameraDriver::kV4l2;
    else if (driver == "libcamera") c.camera.driver = CameraDriver::kLibcamera;
    else if (driver == "sim") c.camera.driver = CameraDriver::kSim;
    else throw Failure{"camera.driver", "'" + driver + "' is not v4l2, libcamera or sim"};
    cam.text("device", &c.camera.device);
    cam.text("camera_id", &c.camera.camera_id);
    std::string format = hal::to_string(c.camera.format);
    cam.text("format", &format);
    if (!hal::pixel_format_from_string(format.c_str(), &c.camera.format)) {
      throw Failure{"camera.format", "'" + format + "' is not GREY, YUYV, UYVY, NV12, RGB3, BGR3, XR24 or MJPG"};
    }
    cam.integer("width", &c.camera.width_px, 16, 1280);
    cam.integer("height", &c.camera.height_px, 16, 960);
    cam.number("frame_rate_hz", &c.camera.frame_rate_hz, 0.1, 240);
    cam.integer("buffers", &c.camera.buffers, 2, 8);
    cam.integer("timeout_ms", &c.camera.timeout_ms, 1, 60000);
    cam.text("calibration", &c.camera.calibration);
    cam.text("scene", &c.camera.scene);
    c.camera.calibration = resolve(base_dir, c.camera.calibration);
    c.camera.scene = resolve(base_dir, c.camera.scene);
    if (c.camera.driver != CameraDriver::kSim && c.camera.calibration.empty()) {
      throw Failure{"camera.calibration", "required for a real camera (a camera_info YAML file)"};
    }

    const Section mav(sections["mavlink"], "mavlink",
                      {"endpoint", "signing_key_file", "link_id", "system_id", "component_id", "target_system",
                       "target_component", "heartbeat_period_s", "setpoint_period_s", "link_loss_timeout_s",
                       "pose_rate_hz", "arrive_tolerance_m", "arrive_yaw_tolerance_rad", "arrive_timeout_s",
                       "world_origin_ned"});
    hal::mavlink::MavlinkMotionConfig& m = c.mavlink.motion;
    mav.text("endpoint", &c.mavlink.endpoint);
    hal::mavlink::Endpoint endpoint;
    const std::string endpoint_error = hal::mavlink::parse_endpoint(c.mavlink.endpoint, &endpoint);
    if (!endpoint_error.empty()) throw Failure{"mavlink.endpoint", endpoint_error};
    mav.text("signing_key_file", &c.mavlink.signing_key_file);
    c.mavlink.signing_key_file = resolve(base_dir, c.mavlink.signing_key_file);
    mav.integer("link_id", &m.signing_link_id, 0, 255);
    mav.integer("system_id", &m.system_id, 1, 255);
    mav.integer("component_id", &m.component_id, 1, 255);
    mav.integer("target_system", &m.target_system, 1, 255);
    mav.integer("target_component", &m.target_component, 1, 255);
    mav.number("heartbeat_period_s", &m.heartbeat_period_s, 0.01, 5);
    mav.number("setpoint_period_s", &m.setpoint_period_s, 0.01, 1);
    mav.number("link_loss_timeout_s", &m.link_loss_timeout_s, 0.1, 60);
    mav.number("pose_rate_hz", &m.pose_rate_hz, 0.1, 200);
    mav.number("arrive_tolerance_m", &m.arrive_tolerance_m, 1e-4, 100);
    mav.number("arrive_yaw_tolerance_rad", &m.arrive_yaw_tolerance_rad, 1e-4, 3);
    mav.number("arrive_timeout_s", &c.mavlink.arrive_timeout_s, 0.1, 3600);
    mav.vector("world_origin_ned", m.frame.world_origin_ned.data(), 3);
    if (const char* bad = m.validate(); bad[0] != '\0') throw Failure{"mavlink", bad};

    const Section mis(sections["mission"], "mission",
                      {"cells_per_side", "cell_size_m", "elevation_m", "center_xy", "viewing_distance_m",
                       "keep_out_radius_m", "max_images", "rho_sigma", "eta_utility", "split_epsilon_cells",
                       "depth_min_m", "depth_max_m", "inverse_warp_masked", "inverse_warp_ncc_min",
                       "spawn_normal_fit_along_rays", "epipolar_guard_fraction", "spawn_back_match_max_px",
                       "spawn_requires_plane_fit", "max_match_sigma_rad",
                       "subpixel_iterations", "require_converged_fit", "match_sigma_floor_rad",
                       "match_floor_tilt_power", "view_correlated_error_scale", "view_correlation_deg",
                       "deformation_error_scale", "deformation_error_power"});
    MissionSettings& s = c.mission;
    mis.integer("cells_per_side", &s.grid.cells_per_side, 1, 4096);
    if (s.grid.cells_per_side != kOnboardGridSide) {
      throw Failure{"mission.cells_per_side", "this build holds a " + std::to_string(kOnboardGridSide) + "x" +
                                                  std::to_string(kOnboardGridSide) + " view grid (choose cell_size_m instead)"};
    }
    mis.number("cell_size_m", &s.grid.cell_size_m, 1e-3, 1e4);
    mis.number("elevation_m", &s.grid.elevation_m, -1e4, 1e4);
    mis.vector("center_xy", s.grid.center_xy.data(), 2);
    mis.number("viewing_distance_m", &s.viewing_distance_m, 1e-3, 1e5);
    mis.number("keep_out_radius_m", &s.keep_out_radius_m, 0, 1e5);
    mis.integer("max_images", &s.max_images, 3, 100000);
    mis.number("rho_sigma", &s.rho_sigma, 1e-9, 1e3);
    mis.number("eta_utility", &s.eta_utility, 0, 1e30);
    mis.number("split_epsilon_cells", &s.split_epsilon_cells, 0.01, 100);
    mis.number("depth_min_m", &s.depth_min_m, 0, 1e5);
    mis.number("depth_max_m", &s.depth_max_m, 0, 1e6);
    mis.boolean("inverse_warp_masked", &s.inverse_warp_masked);
    mis.number("inverse_warp_ncc_min", &s.inverse_warp_ncc_min, 0.01, 0.999);
    mis.boolean("spawn_normal_fit_along_rays", &s.spawn_normal_fit_along_rays);
    mis.number("epipolar_guard_fraction", &s.epipolar_guard_fraction, 0, kMaxEpipolarGuardFraction);
    // vantage-sim --spawn-back-match-px's range.
    mis.number("spawn_back_match_max_px", &s.spawn_back_match_max_px, 0, 100);
    mis.boolean("spawn_requires_plane_fit", &s.spawn_requires_plane_fit);
    mis.number("max_match_sigma_rad", &s.max_match_sigma_rad, 0, 9e-3);
    mis.integer("subpixel_iterations", &s.subpixel_iterations, 0, 20);
    mis.boolean("require_converged_fit", &s.require_converged_fit);
    mis.number("match_sigma_floor_rad", &s.match_sigma_floor_rad, 1e-6, 9e-3);  // vantage-sim --match-floor-rad's range
    mis.number("match_floor_tilt_power", &s.match_floor_tilt_power, 0, kMaxMatchFloorTiltPower);
    mis.number("view_correlated_error_scale", &s.view_correlated_error_scale, 0, 100);  // vantage-sim's ranges
    mis.number("view_correlation_deg", &s.view_correlation_deg, 0.1, 180);
    mis.number("deformation_error_scale", &s.deformation_error_scale, 0, 1e4);
    mis.number("deformation_error_power", &s.deformation_error_power, 0.1, kMaxDeformationErrorPower);
    if (s.depth_min_m > 0.0 && s.depth_max_m > 0.0 && s.depth_max_m <= s.depth_min_m) {
      throw Failure{"mission.depth_max_m", "must be larger than depth_min_m"};
    }
    if (s.viewing_distance_m >= 0.5 * s.grid.cells_per_side * s.grid.cell_size_m) {
      throw Failure{"mission.viewing_distance_m", "the initial views would lie outside the grid"};
    }
  } catch (const Failure& f) {
    return source + ": " + f.field + ": " + f.problem;
  } catch (const YAML::Exception& e) {
    return source + ": " + e.what();
  }
  *out = c;
  return {};
}

std::string load_onboard_config(const std::string& path, OnboardConfig* out) {
  std::ifstream file(path);
  if (!file) return path + ": cannot open the configuration file";
  std::stringstream text;
  text << file.rdbuf();
  const std::size_t slash = path.rfind('/');
  const std::string base_dir = slash == std::string::npos ? "." : path.substr(0, slash);
  return parse_onboard_config(text.str(), path, base_dir, out);
}

std::string load_signing_key(const std::string& path, hal::mavlink::SigningKey* key) {
  std::ifstream file(path);
  if (!file) return path + ": cannot open the signing key file";
  std::string hex;
  file >> hex;
  std::string rest;
  file >> rest;
  if (hex.size() != 64 || !rest.empty()) return path + ": must hold exactly 64 hex digits (a 32-byte key)";
  for (std::size_t i = 0; i < 32; ++i) {
    unsigned value = 0;
    for (int j = 0; j < 2; ++j) {
      const char ch = hex[2 * i + static_cast<std::size_t>(j)];
      value <<= 4;
      if (ch >= '0' && ch <= '9') value |= static_cast<unsigned>(ch - '0');
      else if (ch >= 'a' && ch <= 'f') value |= static_cast<unsigned>(ch - 'a' + 10);
      else if (ch >= 'A' && ch <= 'F') value |= static_cast<unsigned>(ch - 'A' + 10);
      else return path + ": must hold exactly 64 hex digits (a 32-byte key)";
    }
    (*key)[i] = static_cast<std::uint8_t>(value);
  }
  return {};
}

}  // namespace vantage::onboard
