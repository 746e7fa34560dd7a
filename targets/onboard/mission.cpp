#include "targets/onboard/mission.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "core/frontend/image_front_end.hpp"
#include "core/planning/sensing_executive.hpp"
#include "targets/common/search_depth_range.hpp"
#include "targets/common/tracking_summary.hpp"
#include "targets/onboard/onboard_grid.hpp"

namespace vantage::onboard {
namespace {

using FrameBuffer = GrayImageBuffer<kFrontEndMaxWidth, kFrontEndMaxHeight>;
using WallClock = std::chrono::steady_clock;

double seconds_since(WallClock::time_point t0) { return std::chrono::duration<double>(WallClock::now() - t0).count(); }

// Where the mission's time goes (printed with every image).
struct Timing {
  double grid_s = 0.0;
  double update_s = 0.0;
  double motion_s = 0.0;
  double capture_s = 0.0;
};

// Static storage for the heap-free core (several MB): never on the stack, never on the heap.
PrimitivePool<kDefaultPrimitiveCapacity> g_pool;
ImageFrontEnd g_front_end;
OnboardGrid g_grid;
SensingExecutive g_executive(g_pool, g_front_end, g_grid, nullptr);
FrameBuffer g_first_frame;
FrameBuffer g_frame;

std::string seconds_text(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g s", s);
  return text;
}

struct MissionError {
  int code;
  std::string text;
};

class Rig {
 public:
  Rig(const OnboardConfig& config, hal::Camera& camera, const CameraReopen& reopen, hal::mavlink::MavlinkMotion& motion,
      const hal::Clock& clock)
      : config_(config), camera_(camera), reopen_(reopen), motion_(motion), clock_(clock) {}

  // Commands the viewpoint and keeps the link serviced until the vehicle is there.
  void move_to(const Viewpoint& view) {
    const hal::MotionFault fault = motion_.command(view);
    if (fault == hal::MotionFault::kLinkLost) throw MissionError{kExitVehicle, "vehicle: link lost: the vehicle was told to hold"};
    if (fault != hal::MotionFault::kNone) throw MissionError{kExitMissionFailed, std::string("vehicle refused a viewpoint: ") + hal::to_string(fault)};
    const std::int64_t deadline = clock_.now_ns() + static_cast<std::int64_t>(config_.mavlink.arrive_timeout_s * 1e9);
    for (;;) {
      motion_.update(0.02);
      if (motion_.fault() == hal::MotionFault::kLinkLost) {
        throw MissionError{kExitVehicle, "vehicle: link lost (no heartbeat for " +
                                             seconds_text(config_.mavlink.motion.link_loss_timeout_s) +
                                             "): the vehicle was told to hold"};
      }
      if (motion_.arrived()) return;
      if (clock_.now_ns() > deadline) throw MissionError{kExitVehicle, "vehicle: did not reach a viewpoint within arrive_timeout_s"};
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

  // A frame taken after arrival (older queued frames are dropped), into buffer.
  GrayImageView grab(FrameBuffer& buffer, Viewpoint* pose) {
    const std::int64_t arrived_ns = clock_.now_ns();
    int failures = 0;
    bool reopened = false;
    for (int attempt = 0; attempt < 32; ++attempt) {
      motion_.update(0.0);
      // Exactly the camera's frame size, stride = width: drivers that keep the caller's stride (the
      // sim camera) and drivers that set it (V4L2, libcamera) then agree.
      const PinholeIntrinsics& k = camera_.intrinsics();
      if (!ok(buffer.resize(k.width_px, k.height_px))) {
        throw MissionError{kExitCamera, std::string("camera: ") + camera_.name() + ": frame larger than the front end takes"};
      }
      MutableGrayImageView view = buffer.view();
      hal::FrameInfo info;
      const hal::CaptureStatus status = camera_.grab(view, info, config_.camera.timeout_ms);
      if (status == hal::CaptureStatus::kOk) {
        if (info.timestamp_ns < arrived_ns) continue;  // queued before we got here
        if (view.width_px != k.width_px || view.height_px != k.height_px) {
          throw MissionError{kExitCamera, std::string("camera: ") + camera_.name() + ": frame size differs from the calibration"};
        }
        *pose = motion_.current_pose().pose;
        return view.as_const();
      }
      if (status == hal::CaptureStatus::kDeviceLost && reopen_ && !reopened) {
        reopened = true;
        const std::string error = reopen_();
        if (!error.empty()) throw MissionError{kExitCamera, "camera: lost and could not reopen: " + error};
        continue;
      }
      if (status == hal::CaptureStatus::kTimeout || status == hal::CaptureStatus::kCorruptFrame) {
        if (++failures < 3) continue;
      }
      throw MissionError{kExitCamera, std::string("camera: ") + camera_.name() + ": " + hal::to_string(status)};
    }
    throw MissionError{kExitCamera, std::string("camera: ") + camera_.name() + ": no frame newer than the arrival"};
  }

  void wait_for_vehicle() {
    motion_.start();
    for (;;) {
      motion_.update(0.02);
      if (motion_.link_up() && motion_.current_pose().valid) return;
      if (motion_.fault() == hal::MotionFault::kLinkLost) {
        throw MissionError{kExitVehicle, "vehicle: no heartbeat and pose within " +
                                             seconds_text(config_.mavlink.motion.link_loss_timeout_s) + " on " +
                                             config_.mavlink.endpoint};
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

 private:
  const OnboardConfig& config_;
  hal::Camera& camera_;
  const CameraReopen& reopen_;
  hal::mavlink::MavlinkMotion& motion_;
  const hal::Clock& clock_;
};

}  // namespace

StaticFootprint static_footprint() {
  return StaticFootprint{sizeof(g_pool), sizeof(g_front_end), sizeof(g_grid), sizeof(g_executive),
                         sizeof(g_first_frame) + sizeof(g_frame)};
}

int run_mission(const OnboardConfig& config, hal::Camera& camera, const CameraReopen& reopen,
                hal::mavlink::MavlinkMotion& motion, const hal::Clock& clock, std::string* summary) {
  const MissionSettings& m = config.mission;
  const PinholeIntrinsics& intrinsics = camera.intrinsics();
  FrontEndConfig fc;
  const targets::SearchDepthRange derived = targets::default_search_depth_range(m.grid, m.viewing_distance_m);
  fc.depth_min = m.depth_min_m > 0.0 ? m.depth_min_m : derived.min_m;
  fc.depth_max = m.depth_max_m > 0.0 ? m.depth_max_m : derived.max_m;
  fc.inverse_warp_masked = m.inverse_warp_masked;
  fc.inverse_warp_ncc_min = static_cast<float>(m.inverse_warp_ncc_min);
  fc.spawn_normal_fit_along_rays = m.spawn_normal_fit_along_rays;
  fc.epipolar_guard_fraction = m.epipolar_guard_fraction;
  fc.spawn_back_match_max_px = m.spawn_back_match_max_px;
  fc.spawn_requires_plane_fit = m.spawn_requires_plane_fit;
  fc.max_match_sigma_rad = m.max_match_sigma_rad;
  fc.subpixel_iterations = m.subpixel_iterations;
  fc.require_converged_fit = m.require_converged_fit;
  fc.match_sigma_floor_rad = m.match_sigma_floor_rad;
  fc.match_floor_tilt_power = m.match_floor_tilt_power;
  fc.view_correlated_error_scale = m.view_correlated_error_scale;
  fc.view_correlation_deg = m.view_correlation_deg;
  fc.deformation_error_scale = m.deformation_error_scale;
  fc.deformation_error_power = m.deformation_error_power;
  if (const Status s = g_front_end.configure(intrinsics, fc); !ok(s)) {
    *summary = config.source + ": mission: the image front end rejects this camera or depth range (" + to_string(s) + ")";
    return kExitConfig;
  }
  if (!ok(g_grid.configure(m.grid, intrinsics, m.keep_out_radius_m))) {
    *summary = config.source + ": mission: the view grid rejects this geometry";
    return kExitConfig;
  }
  g_pool.clear();
  SensingConfig sc;
  sc.rho_sigma = m.rho_sigma;
  sc.eta_utility = m.eta_utility;
  sc.max_images = m.max_images;
  sc.split.epsilon_cells = m.split_epsilon_cells;
  sc.orbit_radius_m = m.viewing_distance_m;
  if (const char* field = sc.invalid_field()) {
    *summary = config.source + ": mission: " + field + " out of range";
    return kExitConfig;
  }

  Rig rig(config, camera, reopen, motion, clock);
  Timing timing;
  try {
    rig.wait_for_vehicle();
    std::printf("vehicle: link up on %s\n", config.mavlink.endpoint.c_str());
    // Two initial views one cell apart at the viewing distance, on the -y side (paper section VI).
    const GridCell first_cell = m.grid.cell_of(m.grid.center_xy + Eigen::Vector2d(0.0, -m.viewing_distance_m));
    const GridCell second_cell{first_cell.ix + 1, first_cell.iy};
    if (!g_grid.is_free_initially(first_cell) || !g_grid.is_free_initially(second_cell)) {
      *summary = config.source + ": mission: the initial views fall in the keep-out zone or off the grid";
      return kExitConfig;
    }
    Viewpoint first_view, second_view;
    if (!ok(g_grid.viewpoint(first_cell, &first_view)) || !ok(g_grid.viewpoint(second_cell, &second_view))) {
      *summary = config.source + ": mission: no viewpoint for the initial cells";
      return kExitConfig;
    }
    Viewpoint first_pose, second_pose;
    rig.move_to(first_view);
    const GrayImageView first = rig.grab(g_first_frame, &first_pose);
    rig.move_to(second_view);
    const GrayImageView second = rig.grab(g_frame, &second_pose);
    const Status begun = g_executive.begin(sc, first, first_pose, second, second_pose);
    if (!ok(begun)) {
      *summary = std::string("mission: could not start from the initial images: ") + to_string(begun);
      return kExitMissionFailed;
    }
    const FrontEndStats& fs = g_front_end.stats();
    std::printf("mission: started from cells (%d,%d) and (%d,%d): %zu primitives (front end: %llu seeds tried, %llu matched)\n",
                first_cell.ix, first_cell.iy, second_cell.ix, second_cell.iy, g_pool.size(),
                static_cast<unsigned long long>(fs.seeds_tried), static_cast<unsigned long long>(fs.seeds_matched));
    for (;;) {
      const SensingAction action = g_executive.next();
      if (action.kind == SensingActionKind::kDone || action.kind == SensingActionKind::kFailed) break;
      switch (action.kind) {
        case SensingActionKind::kEvaluateGrid: {
          const auto t0 = WallClock::now();
          const Status evaluated = g_grid.evaluate(g_pool);
          timing.grid_s += seconds_since(t0);
          if (!ok(evaluated)) {
            *summary = std::string("mission: grid evaluation failed: ") + to_string(evaluated);
            return kExitMissionFailed;
          }
          g_executive.on_grid_evaluated();
          break;
        }
        case SensingActionKind::kMoveTo: {
          const auto t0 = WallClock::now();
          rig.move_to(action.view);
          timing.motion_s += seconds_since(t0);
          g_executive.on_arrived(motion.current_pose().pose);
          break;
        }
        case SensingActionKind::kCapture: {
          auto t0 = WallClock::now();
          rig.move_to(action.view);
          timing.motion_s += seconds_since(t0);
          t0 = WallClock::now();
          Viewpoint pose;
          const GrayImageView image = rig.grab(g_frame, &pose);
          timing.capture_s += seconds_since(t0);
          t0 = WallClock::now();
          g_executive.on_image(image, pose);
          timing.update_s += seconds_since(t0);
          // The innovations so far (NisHistogram): honest covariances read 1 and 5 %.
          const NisSummary innovations = summarize(g_front_end.stats().ekf.nis);
          std::printf("image %u/%u at cell (%d,%d): avg sigma %.5f, %zu primitives, NBV iterations %u, innovation "
                      "scale %.2f with %.1f%% past the 95%% point (s so far: grid %.1f, update %.1f, motion %.1f, "
                      "capture %.1f)\n",
                      g_executive.images(), m.max_images, action.cell.ix, action.cell.iy, g_executive.precision_level(),
                      g_pool.size(), g_executive.nbv_iterations(), innovations.median_scale,
                      100.0 * innovations.fraction_beyond_95, timing.grid_s, timing.update_s, timing.motion_s,
                      timing.capture_s);
          std::fflush(stdout);
          break;
        }
        default:
          break;
      }
    }
  } catch (const MissionError& e) {
    *summary = e.text;
    return e.code;
  }
  const FrontEndStats& tracked = g_front_end.stats();
  std::printf("%s\n", targets::tracking_summary(tracked.tracks_predicted, tracked.tracks_matched,
                                                       tracked.tracks_inverse_warped, tracked.track_failures).c_str());
  std::printf("%s\n", targets::seeding_summary(tracked.seeds_tried, tracked.seeds_matched,
                                                      tracked.seeds_beyond_depth_range,
                                                      tracked.seeds_rejected_back_match,
                                                      tracked.seeds_rejected_no_plane_fit).c_str());
  std::printf("%s\n", targets::innovation_summary(tracked.ekf.nis).c_str());
  const SensingAction last = g_executive.next();
  if (last.kind == SensingActionKind::kDone) {
    *summary = std::string("mission done: ") + to_string(last.done) + ", " + std::to_string(g_executive.images()) +
               " images, " + std::to_string(g_executive.nbv_iterations()) + " NBV iterations";
    return kExitDone;
  }
  *summary = std::string("mission failed: ") + last.reason + " (" + to_string(last.failure) + ")";
  return kExitMissionFailed;
}

}  // namespace vantage::onboard
