#include "sim_hal/raycast_camera.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <thread>

#include "core/geometry/projection.hpp"
#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

constexpr int kTile = 4;
constexpr std::size_t kMaxLights = 8;  // 4 x 4 pixels = one rtcIntersect16 packet

}  // namespace

RaycastCamera::RaycastCamera(const EmbreeScene& scene, const RaycastCameraConfig& config,
                             const SimPoseSource* pose_source, const hal::Clock* clock)
    : scene_(scene), config_(config), pose_source_(pose_source), clock_(clock), texture_(config.shading.albedo) {
  const PinholeIntrinsics& k = config_.intrinsics;
  if (!ok(k.validate())) throw SimError("raycast camera: invalid intrinsics");
  if (config_.threads < 1) throw SimError("raycast camera: threads must be >= 1");
  if (!(config_.shading.ambient >= 0.0) || !(config_.shading.pixel_noise_sigma >= 0.0)) {
    throw SimError("raycast camera: ambient and pixel noise must be >= 0");
  }
  for (const auto& light : config_.shading.lights) {
    if (!light.direction_world.allFinite() || !(light.direction_world.norm() > 0.0) || !(light.intensity >= 0.0)) {
      throw SimError("raycast camera: bad light (direction must be non-zero, intensity >= 0)");
    }
  }
  if (config_.shading.lights.size() > kMaxLights) throw SimError("raycast camera: at most 8 lights");
  if (config_.shading.samples_per_axis < 1 || config_.shading.samples_per_axis > kMaxPixelSamplesPerAxis) {
    throw SimError("raycast camera: samples_per_axis must be in [1, " + std::to_string(kMaxPixelSamplesPerAxis) + "]");
  }
  if (config_.shading.normals != NormalMode::kFlat && config_.shading.normals != NormalMode::kSmooth) {
    throw SimError("raycast camera: normals must be flat or smooth");
  }
  for (auto& light : config_.shading.lights) light.direction_world.normalize();
  object_bounds_ = scene_.mesh().bounds();
  // Per-pixel undistorted ray (x, y, 1) in the camera frame: the ray's parameter t is then camera z.
  ray_dir_cam_.resize(static_cast<std::size_t>(k.width_px) * k.height_px * 2);
  const Viewpoint identity;
  for (int v = 0; v < k.height_px; ++v) {
    for (int u = 0; u < k.width_px; ++u) {
      const Eigen::Vector3d d = back_project_ray_world(Eigen::Vector2d(u, v), identity, k);
      const std::size_t i = static_cast<std::size_t>(v) * k.width_px + u;
      ray_dir_cam_[2 * i] = static_cast<float>(d.x() / d.z());
      ray_dir_cam_[2 * i + 1] = static_cast<float>(d.y() / d.z());
    }
  }
  // The same through the pixels' corners (u - 0.5, v - 0.5), u in [0, width], v in [0, height]: pixel-area
  // samples interpolate between the four corners of their pixel.
  if (config_.shading.samples_per_axis > 1) {
    ray_dir_corner_cam_.resize(static_cast<std::size_t>(k.width_px + 1) * (k.height_px + 1) * 2);
    for (int v = 0; v <= k.height_px; ++v) {
      for (int u = 0; u <= k.width_px; ++u) {
        const Eigen::Vector3d d = back_project_ray_world(Eigen::Vector2d(u - 0.5, v - 0.5), identity, k);
        const std::size_t i = static_cast<std::size_t>(v) * (k.width_px + 1) + u;
        ray_dir_corner_cam_[2 * i] = static_cast<float>(d.x() / d.z());
        ray_dir_corner_cam_[2 * i + 1] = static_cast<float>(d.y() / d.z());
      }
    }
  }
}

void RaycastCamera::set_threads(int threads) { config_.threads = std::max(1, threads); }

hal::CaptureStatus RaycastCamera::grab(MutableGrayImageView& out, hal::FrameInfo& info, std::int32_t /*timeout_ms*/) {
  if (pose_source_ == nullptr) return hal::CaptureStatus::kNotStarted;
  const PinholeIntrinsics& k = config_.intrinsics;
  const std::int32_t stride = std::max(out.stride_bytes, k.width_px);
  const std::size_t capacity = static_cast<std::size_t>(std::max(out.stride_bytes, out.width_px)) *
                               static_cast<std::size_t>(std::max(out.height_px, 0));
  if (out.pixels == nullptr || capacity < static_cast<std::size_t>(stride) * k.height_px) {
    return hal::CaptureStatus::kBufferTooSmall;
  }
  MutableGrayImageView target{out.pixels, k.width_px, k.height_px, stride};
  if (!ok(render(pose_source_->camera_pose(), target, nullptr, sequence_))) return hal::CaptureStatus::kCorruptFrame;
  out = target;
  info.sequence = sequence_++;
  info.timestamp_ns = clock_ != nullptr ? clock_->now_ns() : 0;
  return hal::CaptureStatus::kOk;
}

Status RaycastCamera::render(const Viewpoint& view, MutableGrayImageView out, DepthImage* depth,
                             std::uint64_t noise_stream) const {
  const Status pose_status = view.validate();
  if (!ok(pose_status)) return pose_status;
  const PinholeIntrinsics& k = config_.intrinsics;
  if (out.pixels == nullptr || out.width_px < k.width_px || out.height_px < k.height_px ||
      out.stride_bytes < k.width_px) {
    return Status::kInvalidArgument;
  }
  if (depth != nullptr && (depth->width_px != k.width_px || depth->height_px != k.height_px ||
                           depth->camera_z.size() != static_cast<std::size_t>(k.width_px) * k.height_px)) {
    depth->resize(k.width_px, k.height_px);
  }
  const int thread_count = std::max(1, config_.threads);
  if (thread_count == 1) {
    render_rows(view, out, depth, noise_stream, 0, 1);
    return Status::kOk;
  }
  std::vector<std::thread> workers;
  workers.reserve(static_cast<std::size_t>(thread_count - 1));
  for (int t = 1; t < thread_count; ++t) {
    workers.emplace_back([&, t] { render_rows(view, out, depth, noise_stream, t, thread_count); });
  }
  render_rows(view, out, depth, noise_stream, 0, thread_count);
  for (auto& w : workers) w.join();
  return Status::kOk;
}

void RaycastCamera::render_rows(const Viewpoint& view, MutableGrayImageView out, DepthImage* depth,
                                std::uint64_t noise_stream, int thread_index, int thread_count) const {
  const PinholeIntrinsics& k = config_.intrinsics;
  const ShadingConfig& shading = config_.shading;
  // Plain floats in the per-pixel loop: this is the hot path (and stays quick in Debug builds).
  float R[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R[r][c] = static_cast<float>(view.R_world_cam(r, c));
  }
  const float ox = static_cast<float>(view.position_world.x());
  const float oy = static_cast<float>(view.position_world.y());
  const float oz = static_cast<float>(view.position_world.z());
  const float ambient = static_cast<float>(shading.ambient);
  const float noise_sigma = static_cast<float>(shading.pixel_noise_sigma);
  const std::uint8_t background = shading.background_gray;
  float light_dirs[kMaxLights][3];
  float light_gains[kMaxLights];
  const std::size_t light_count = std::min(shading.lights.size(), kMaxLights);
  for (std::size_t l = 0; l < light_count; ++l) {
    for (int a = 0; a < 3; ++a) light_dirs[l][a] = static_cast<float>(shading.lights[l].direction_world[a]);
    light_gains[l] = static_cast<float>(shading.lights[l].intensity);
  }
  const int tiles_x = (k.width_px + kTile - 1) / kTile;
  const int tiles_y = (k.height_px + kTile - 1) / kTile;

  // Tiles outside the projected bounding box of the object need no rays. Only without distortion (a
  // distorted image of the box's corners need not bound the distorted object) and with the whole box
  // in front of the camera; otherwise every tile is cast.
  int tile_x0 = 0, tile_x1 = tiles_x - 1, tile_y0 = 0, tile_y1 = tiles_y - 1;
  if (k.k1 == 0.0 && k.k2 == 0.0) {
    double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
    bool all_in_front = true;
    for (int c = 0; c < 8 && all_in_front; ++c) {
      const Eigen::Vector3d corner = object_bounds_.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
      const Eigen::Vector3d Xc = view.R_world_cam.transpose() * (corner - view.position_world);
      if (!(Xc.z() > 1e-6)) {
        all_in_front = false;
        break;
      }
      const double u = k.fx_px * Xc.x() / Xc.z() + k.cx_px;
      const double v = k.fy_px * Xc.y() / Xc.z() + k.cy_px;
      umin = std::min(umin, u);
      umax = std::max(umax, u);
      vmin = std::min(vmin, v);
      vmax = std::max(vmax, v);
    }
    if (all_in_front) {
      // One pixel of slack for float rounding at the box's edges.
      tile_x0 = static_cast<int>(std::floor(std::max(umin - 1.0, -1.0) / kTile));
      tile_x1 = static_cast<int>(std::floor(std::min(umax + 1.0, static_cast<double>(k.width_px)) / kTile));
      tile_y0 = static_cast<int>(std::floor(std::max(vmin - 1.0, -1.0) / kTile));
      tile_y1 = static_cast<int>(std::floor(std::min(vmax + 1.0, static_cast<double>(k.height_px)) / kTile));
    }
  }

  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(64) RTCRayHit16 packet;
  alignas(64) int valid[16];
  float radiance_sum[16];  // gray before noise, summed over the pixel's samples
  std::size_t pixel_of[16];

  const bool smooth = shading.normals == NormalMode::kSmooth;
  const std::vector<Eigen::Vector3f>& corner_normals = scene_.corner_normals();
  // Gray (before noise) of a hit of packet ray j: albedo at the hit times the Lambertian sum.
  auto shade = [&](int j) {
    const float t = packet.ray.tfar[j];
    const float dx = packet.ray.dir_x[j], dy = packet.ray.dir_y[j], dz = packet.ray.dir_z[j];
    float nx = packet.hit.Ng_x[j], ny = packet.hit.Ng_y[j], nz = packet.hit.Ng_z[j];
    if (nx * dx + ny * dy + nz * dz > 0.0f) {  // shade the side the camera sees
      nx = -nx;
      ny = -ny;
      nz = -nz;
    }
    if (smooth) {
      // Embree's barycentrics: hit = (1 - u - v) p0 + u p1 + v p2.
      const std::size_t c = 3 * static_cast<std::size_t>(packet.hit.primID[j]);
      const float bu = packet.hit.u[j], bv = packet.hit.v[j], bw = 1.0f - bu - bv;
      const Eigen::Vector3f n = bw * corner_normals[c] + bu * corner_normals[c + 1] + bv * corner_normals[c + 2];
      // Corner normals lie on the side of the triangle's winding; turn them to the side the camera sees.
      const float side = n.x() * nx + n.y() * ny + n.z() * nz;
      if (side != 0.0f) {
        const float sign = side > 0.0f ? 1.0f : -1.0f;
        nx = sign * n.x();
        ny = sign * n.y();
        nz = sign * n.z();
      }  // else (a degenerate corner set): the geometric normal
    }
    const float len = std::sqrt(nx * nx + ny * ny + nz * nz);
    if (len > 0.0f) {
      nx /= len;
      ny /= len;
      nz /= len;
    }
    float light = ambient;
    for (std::size_t l = 0; l < light_count; ++l) {
      const float c = nx * light_dirs[l][0] + ny * light_dirs[l][1] + nz * light_dirs[l][2];
      light += light_gains[l] * std::max(0.0f, c);
    }
    return 255.0f * texture_.albedo(ox + t * dx, oy + t * dy, oz + t * dz) * light;
  };

  // Sub-sample s of n x n sits at ((s % n + 0.5) / n, (s / n + 0.5) / n) of the pixel's square, measured
  // from its top-left corner (u - 0.5, v - 0.5). An odd n has the centre among them: that sample uses the
  // exact centre ray and gives the depth; an even n casts the centre ray once more when depth is asked for.
  const int n = shading.samples_per_axis;
  const int sample_count = n * n;
  const int centre_sample = (n % 2 == 1) ? sample_count / 2 : -1;
  const int pass_count = sample_count + ((centre_sample < 0 && depth != nullptr) ? 1 : 0);
  const float inv_sample_count = 1.0f / static_cast<float>(sample_count);
  const std::size_t corner_stride = static_cast<std::size_t>(k.width_px) + 1;

  // Tile rows are interleaved across threads: neighbouring rows cost about the same, so the split is even.
  for (int ty = thread_index; ty < tiles_y; ty += thread_count) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const bool cast = tx >= tile_x0 && tx <= tile_x1 && ty >= tile_y0 && ty <= tile_y1;
      for (int j = 0; j < 16; ++j) {
        const int u = tx * kTile + (j % kTile);
        const int v = ty * kTile + (j / kTile);
        const bool inside = u < k.width_px && v < k.height_px;
        valid[j] = inside ? -1 : 0;
        pixel_of[j] = inside ? static_cast<std::size_t>(v) * k.width_px + u : 0;
        radiance_sum[j] = 0.0f;
      }
      for (int pass = 0; cast && pass < pass_count; ++pass) {
        const bool is_centre = pass == centre_sample || pass == sample_count;
        const bool shaded = pass < sample_count;
        const float a = (static_cast<float>(pass % n) + 0.5f) / static_cast<float>(n);
        const float b = (static_cast<float>(pass / n) + 0.5f) / static_cast<float>(n);
        for (int j = 0; j < 16; ++j) {
          const int u = tx * kTile + (j % kTile);
          const int v = ty * kTile + (j / kTile);
          float cx, cy;
          if (is_centre || valid[j] == 0) {
            const std::size_t i = pixel_of[j];
            cx = ray_dir_cam_[2 * i];
            cy = ray_dir_cam_[2 * i + 1];
          } else {
            // Bilinear between the undistorted rays through the pixel's four corners (exact without
            // distortion; with it, the map's curvature over one pixel is far below a thousandth of one).
            const std::size_t c00 = 2 * (static_cast<std::size_t>(v) * corner_stride + u);
            const std::size_t c10 = c00 + 2;
            const std::size_t c01 = c00 + 2 * corner_stride;
            const std::size_t c11 = c01 + 2;
            const float w00 = (1.0f - a) * (1.0f - b), w10 = a * (1.0f - b), w01 = (1.0f - a) * b, w11 = a * b;
            cx = w00 * ray_dir_corner_cam_[c00] + w10 * ray_dir_corner_cam_[c10] + w01 * ray_dir_corner_cam_[c01] +
                 w11 * ray_dir_corner_cam_[c11];
            cy = w00 * ray_dir_corner_cam_[c00 + 1] + w10 * ray_dir_corner_cam_[c10 + 1] +
                 w01 * ray_dir_corner_cam_[c01 + 1] + w11 * ray_dir_corner_cam_[c11 + 1];
          }
          packet.ray.org_x[j] = ox;
          packet.ray.org_y[j] = oy;
          packet.ray.org_z[j] = oz;
          packet.ray.dir_x[j] = R[0][0] * cx + R[0][1] * cy + R[0][2];
          packet.ray.dir_y[j] = R[1][0] * cx + R[1][1] * cy + R[1][2];
          packet.ray.dir_z[j] = R[2][0] * cx + R[2][1] * cy + R[2][2];
          packet.ray.tnear[j] = 0.0f;
          packet.ray.tfar[j] = std::numeric_limits<float>::infinity();
          packet.ray.time[j] = 0.0f;
          packet.ray.mask[j] = 0xFFFFFFFFu;
          packet.ray.id[j] = static_cast<unsigned>(j);
          packet.ray.flags[j] = 0;
          packet.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID;
          packet.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, scene_.handle(), &context, &packet);
        for (int j = 0; j < 16; ++j) {
          if (valid[j] == 0) continue;
          const bool hit = packet.hit.geomID[j] != RTC_INVALID_GEOMETRY_ID;
          if (shaded) radiance_sum[j] += hit ? shade(j) : static_cast<float>(background);
          if (is_centre && depth != nullptr) {
            depth->camera_z[pixel_of[j]] = hit ? packet.ray.tfar[j] : std::numeric_limits<float>::infinity();
          }
        }
      }
      for (int j = 0; j < 16; ++j) {
        if (valid[j] == 0) continue;
        const std::size_t pixel_index = pixel_of[j];
        // A tile outside the object's box is all background (and every ray would miss).
        float gray = cast ? radiance_sum[j] * inv_sample_count : static_cast<float>(background);
        if (!cast && depth != nullptr) depth->camera_z[pixel_index] = std::numeric_limits<float>::infinity();
        if (noise_sigma > 0.0f) gray += noise_sigma * hashed_gaussian(config_.seed, noise_stream, pixel_index);
        const int u = tx * kTile + (j % kTile);
        const int v = ty * kTile + (j / kTile);
        out.pixels[static_cast<std::size_t>(v) * out.stride_bytes + u] =
            static_cast<std::uint8_t>(std::clamp(gray, 0.0f, 255.0f) + 0.5f);
      }
    }
  }
}

}  // namespace vantage::sim
