#pragma once
// The simulated camera: Embree 3 ray casting (rtcIntersect16 packets of 4x4 pixels, render_threads
// threads) of the scene at the pose from a SimPoseSource, producing the same 8-bit gray frames as the
// V4L2/libcamera drivers. Pixel (u, v) averages shading.samples_per_axis^2 rays on a regular grid over
// its square (1: the ray through its centre), undistorted with the intrinsics' k1, k2 (so the image is
// distorted like a real lens). Per ray, radiance = 255 * albedo(X) * (ambient + sum_l intensity_l *
// max(0, n . l)), background where it misses; the mean plus optional Gaussian noise is rounded and
// clamped. n is the triangle's geometric normal (NormalMode::kFlat) or the interpolated corner normal
// (kSmooth), turned toward the camera. The depth image is the pixel-centre ray's camera z.
// Deterministic: the noise of pixel i in frame f is a hash of (seed, f, i), independent of the thread split.
#include <cstdint>
#include <string>
#include <vector>

#include "core/common/status.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "sim_hal/depth_image.hpp"
#include "sim_hal/scene/embree_scene.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/shading.hpp"
#include "sim_hal/sim_pose_source.hpp"

namespace vantage::sim {

struct RaycastCameraConfig {
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
  ShadingConfig shading;
  int threads = 2;
  std::uint32_t seed = 1;
};

class RaycastCamera final : public hal::Camera {
 public:
  // pose_source and clock may be null: then grab() reports kNotStarted / timestamps 0. The scene, pose
  // source and clock must outlive the camera. Throws SimError on invalid intrinsics, lights or threads.
  RaycastCamera(const EmbreeScene& scene, const RaycastCameraConfig& config, const SimPoseSource* pose_source,
                const hal::Clock* clock = nullptr);

  // Renders at pose_source->camera_pose(); frame f uses noise stream f (the sequence number).
  hal::CaptureStatus grab(MutableGrayImageView& out, hal::FrameInfo& info, std::int32_t timeout_ms) override;
  const PinholeIntrinsics& intrinsics() const override { return config_.intrinsics; }
  const char* name() const override { return "sim:raycast"; }

  // Direct rendering for tests and ground truth: out must be at least the intrinsics' size (its
  // width/height are set). depth may be null. kInvalidArgument for a small/null buffer, kNonFiniteInput /
  // kInvalidArgument for a bad viewpoint.
  Status render(const Viewpoint& view, MutableGrayImageView out, DepthImage* depth, std::uint64_t noise_stream = 0) const;

  void set_threads(int threads);  // 1 or more
  int threads() const { return config_.threads; }

 private:
  void render_rows(const Viewpoint& view, MutableGrayImageView out, DepthImage* depth, std::uint64_t noise_stream,
                   int thread_index, int thread_count) const;

  const EmbreeScene& scene_;
  RaycastCameraConfig config_;
  const SimPoseSource* pose_source_;
  const hal::Clock* clock_;
  SolidTexture texture_;
  Eigen::AlignedBox3d object_bounds_;  // rays that cannot reach it are not cast
  std::vector<float> ray_dir_cam_;  // per pixel (x, y) of the undistorted ray (x, y, 1), camera frame
  std::vector<float> ray_dir_corner_cam_;  // the same per pixel corner, (width + 1) x (height + 1); N > 1 only
  std::uint32_t sequence_ = 0;
};

}  // namespace vantage::sim
