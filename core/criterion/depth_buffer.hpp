#pragma once
// A software depth buffer for occlusion without a GPU (paper section IV-B: "aspects such as resolution,
// field of view and occlusions"). Primitives are splatted as planar discs; the buffer keeps, per pixel,
// the inverse camera depth 1/z of the closest splat (0 = nothing), evaluated on each disc's own plane at
// the pixel centre, so neighbouring samples of one tilted surface agree at any pixel.
//
// Resolution is compile-time (DepthBuffer<W, H>); the camera's intrinsics are scaled to it, with the
// lens distortion ignored (the buffer is an undistorted pinhole with the camera's field of view), so a
// primitive within a distortion's displacement of the image border may be judged in or out differently
// from the real image.
//
// Visibility of a primitive (is_visible): in front of the camera, front-facing (normal towards the
// camera), centre inside the image, and its depth at its centre pixel within
//   tolerance = tolerance_radii * radius + kRelativeDepthTolerance * depth
// of the closest splat there. Callers splat every occluder first, then test.
#include <array>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"

namespace vantage {

// A pinhole at the buffer's resolution: pixel (i, j) has its centre at (u, v) = (i, j), buffer pixels.
struct BufferCamera {
  float fx_px = 0.0f;
  float fy_px = 0.0f;
  float cx_px = 0.0f;
  float cy_px = 0.0f;
  std::int32_t width_px = 0;
  std::int32_t height_px = 0;
};

inline constexpr float kDefaultToleranceRadii = 2.0f;
inline constexpr float kRelativeDepthTolerance = 1e-4f;  // float rounding of 1/z and plane evaluation
// Views this close to the disc's plane (cosine between viewing ray and normal) splat a constant depth:
// the plane's depth gradient would explode at grazing incidence.
inline constexpr float kGrazingCosine = 0.15f;
inline constexpr float kNearDepth = 1e-6f;  // matches kMinDepth of core/geometry/projection.hpp

// The per-disc quantities both the public API and the criterion's vectorized loop use.
namespace splat_math {

// Depth gradients of 1/z across the image (per buffer pixel) of the disc's plane n_cam . X = k, with
// k = n_cam . X_cam; zero at grazing incidence (k^2 < kGrazingCosine^2 |X_cam|^2).
inline void inverse_depth_gradient(float ncx, float ncy, float k, float dist2, float fx, float fy, float* du,
                                   float* dv) {
  const bool grazing = k * k < kGrazingCosine * kGrazingCosine * dist2;
  const float inv_k = grazing ? 0.0f : 1.0f / (k != 0.0f ? k : 1.0f);
  *du = ncx * inv_k / fx;
  *dv = ncy * inv_k / fy;
}

// 1/z threshold: the disc, at inverse depth iz_pixel at its centre pixel, is visible when the buffer's
// value there is <= this, i.e. when the closest surface is at most
//   tolerance = tolerance_radii * radius + kRelativeDepthTolerance * z_pixel
// in front of it: 1 / (z_pixel - tolerance) = iz_pixel / (1 - rel - tolerance_radii * radius * iz_pixel).
// Infinity-like (3e38) when the tolerance reaches the camera.
inline float visibility_threshold(float iz_pixel, float radius, float tolerance_radii) {
  const float t = iz_pixel / (1.0f - kRelativeDepthTolerance - tolerance_radii * radius * iz_pixel);
  return t > 0.0f ? t : 3.0e38f;
}

}  // namespace splat_math

// Discs for DepthBufferView::splat_batch, world frame, structure of arrays (one lane per disc).
inline constexpr std::int32_t kDiscBatchSize = 4;
struct DiscBatch {
  std::array<float, kDiscBatchSize> x{}, y{}, z{}, nx{}, ny{}, nz{}, radius{};
  std::int32_t count = 0;

  bool full() const { return count >= kDiscBatchSize; }
  // Appends a disc (the caller flushes a full batch first).
  void push(const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world, float disc_radius) {
    x[count] = X_world.x();
    y[count] = X_world.y();
    z[count] = X_world.z();
    nx[count] = normal_world.x();
    ny[count] = normal_world.y();
    nz[count] = normal_world.z();
    radius[count] = disc_radius;
    ++count;
  }
};

class DepthBufferView {
 public:
  DepthBufferView(const DepthBufferView&) = delete;
  DepthBufferView& operator=(const DepthBufferView&) = delete;

  // Sets the camera (the intrinsics scaled to this buffer's resolution) and clears. On error the buffer
  // keeps its previous camera and contents: kNonFiniteInput (NaN/Inf in pose or intrinsics),
  // kInvalidArgument (pose not a rotation, bad intrinsics), kInvalidImage (intrinsics of zero size).
  Status configure(const Viewpoint& view, const PinholeIntrinsics& intrinsics);
  // Empties every pixel (keeps the camera).
  void clear();

  // Splats a disc (centre, unit normal, radius; world frame, scene units), front- or back-facing: the
  // caller decides what occludes. Returns false (nothing written) when it is behind the camera, not
  // finite, or misses the image.
  bool splat(const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world, float radius);
  // splat() of each of the batch's discs in order, the projections computed four lanes at once with
  // splat()'s arithmetic operation for operation (so the same pixels and values); empties the batch and
  // returns how many discs were written.
  std::int32_t splat_batch(DiscBatch& batch);
  // is_visible() of each of the batch's discs ((*visible)[lane] for lane < count, the rest false), the
  // projections four lanes at once with the same arithmetic.
  void is_visible_batch(const DiscBatch& batch, std::array<bool, kDiscBatchSize>* visible) const;
  // See the file comment. False for non-finite input.
  bool is_visible(const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world, float radius) const;

  // Tolerance in disc radii (default kDefaultToleranceRadii); negative or non-finite values are refused.
  Status set_tolerance_radii(float radii);
  float tolerance_radii() const { return tolerance_radii_; }

  bool configured() const { return configured_; }
  std::int32_t width() const { return width_; }
  std::int32_t height() const { return height_; }
  const BufferCamera& camera() const { return camera_; }
  // 1/z of the closest splat at buffer pixel (x, y); 0 when empty or outside.
  float inverse_depth_at(std::int32_t x, std::int32_t y) const {
    return (x >= 0 && y >= 0 && x < width_ && y < height_) ? data_[y * width_ + x] : 0.0f;
  }

  // The camera pose the buffer was configured with, as float (camera = R^T (X - position)).
  const Eigen::Matrix3f& R_cam_world() const { return R_cam_world_; }
  const Eigen::Vector3f& position_world() const { return position_world_; }

  // Low level, for the criterion's fast path: writes the disc whose centre projects to (u, v) (buffer
  // pixels) at inverse depth iz_centre, with gradients du, dv and footprint half-size radius_px, over
  // the pixels whose centres lie within the footprint square, plus the centre pixel.
  void splat_projected(float u, float v, float iz_centre, float du, float dv, float radius_px) {
    const float half_w = static_cast<float>(width_) - 0.5f;
    const float half_h = static_cast<float>(height_) - 0.5f;
    // Fast path: footprint inside one pixel whose centre is in the image.
    if (radius_px < 0.5f && u >= -0.5f && v >= -0.5f && u < half_w && v < half_h) {
      const std::int32_t i = static_cast<std::int32_t>(u + 0.5f);
      const std::int32_t j = static_cast<std::int32_t>(v + 0.5f);
      const float iz = iz_centre + du * (static_cast<float>(i) - u) + dv * (static_cast<float>(j) - v);
      float& cell = data_[j * width_ + i];
      cell = iz > cell ? iz : cell;
      return;
    }
    splat_projected_general(u, v, iz_centre, du, dv, radius_px);
  }
  float* inverse_depth_data() { return data_; }
  const float* inverse_depth_data() const { return data_; }
  // Index of one extra cell after the image, never read: branch-free writers aim masked lanes at it.
  std::int32_t spare_index() const { return width_ * height_; }

 protected:
  DepthBufferView(float* data, std::int32_t width, std::int32_t height)
      : data_(data), width_(width), height_(height) {}
  ~DepthBufferView() = default;

 private:
  void splat_projected_general(float u, float v, float iz_centre, float du, float dv, float radius_px);

  float* data_;
  std::int32_t width_;
  std::int32_t height_;
  BufferCamera camera_{};
  Eigen::Matrix3f R_cam_world_ = Eigen::Matrix3f::Identity();
  Eigen::Vector3f position_world_ = Eigen::Vector3f::Zero();
  float tolerance_radii_ = kDefaultToleranceRadii;
  bool configured_ = false;
};

// The paper's GPU rendered at the camera's resolution; 160x120 (a quarter of VGA per side) keeps a
// 70K-primitive model at a few primitives per pixel, enough to resolve self-occlusion of the object.
// The owners' arrays are base classes constructed before the views that receive pointers to them.
template <std::int32_t W, std::int32_t H>
struct DepthBufferStorage {
  std::array<float, static_cast<std::size_t>(W) * static_cast<std::size_t>(H) + 1> pixels_{};  // + spare
};

template <std::int32_t W = 160, std::int32_t H = 120>
class DepthBuffer : private DepthBufferStorage<W, H>, public DepthBufferView {
 public:
  static_assert(W > 0 && H > 0, "depth buffer needs a positive size");
  static constexpr std::int32_t kWidth = W;
  static constexpr std::int32_t kHeight = H;
  DepthBuffer() : DepthBufferView(DepthBufferStorage<W, H>::pixels_.data(), W, H) {}
};

// Scales intrinsics to a buffer of width x height pixels (pixel centres preserved). Caller validates.
BufferCamera scale_to_buffer(const PinholeIntrinsics& intrinsics, std::int32_t width, std::int32_t height);

}  // namespace vantage
