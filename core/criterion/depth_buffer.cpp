#include "core/criterion/depth_buffer.hpp"

#include <cmath>
#include <cstring>

#include "core/criterion/splat_general.hpp"

namespace vantage {

namespace {

struct ProjectedDisc {
  float u = 0.0f;
  float v = 0.0f;
  float iz_centre = 0.0f;
  float du = 0.0f;
  float dv = 0.0f;
  float radius_px = 0.0f;
  float facing = 0.0f;  // n . (camera - X): > 0 front-facing
};

}  // namespace

BufferCamera scale_to_buffer(const PinholeIntrinsics& k, std::int32_t width, std::int32_t height) {
  const double sx = static_cast<double>(width) / k.width_px;
  const double sy = static_cast<double>(height) / k.height_px;
  BufferCamera c;
  c.fx_px = static_cast<float>(k.fx_px * sx);
  c.fy_px = static_cast<float>(k.fy_px * sy);
  // Pixel centres at integers: camera pixel u covers [u - 0.5, u + 0.5], so edges scale, centres shift.
  c.cx_px = static_cast<float>((k.cx_px + 0.5) * sx - 0.5);
  c.cy_px = static_cast<float>((k.cy_px + 0.5) * sy - 0.5);
  c.width_px = width;
  c.height_px = height;
  return c;
}

Status DepthBufferView::configure(const Viewpoint& view, const PinholeIntrinsics& intrinsics) {
  if (intrinsics.width_px <= 0 || intrinsics.height_px <= 0) return Status::kInvalidImage;
  const Status intrinsics_status = intrinsics.validate();
  if (!ok(intrinsics_status)) return intrinsics_status;
  const Status view_status = view.validate();
  if (!ok(view_status)) return view_status;
  camera_ = scale_to_buffer(intrinsics, width_, height_);
  R_cam_world_ = view.R_world_cam.transpose().cast<float>();
  position_world_ = view.position_world.cast<float>();
  configured_ = true;
  clear();
  return Status::kOk;
}

void DepthBufferView::clear() {
  const std::int32_t n = width_ * height_;
  for (std::int32_t i = 0; i < n; ++i) data_[i] = 0.0f;
}

Status DepthBufferView::set_tolerance_radii(float radii) {
  if (!std::isfinite(radii)) return Status::kNonFiniteInput;
  if (radii < 0.0f) return Status::kInvalidArgument;
  tolerance_radii_ = radii;
  return Status::kOk;
}

namespace {

bool project_disc(const BufferCamera& cam, const Eigen::Matrix3f& R_cam_world, const Eigen::Vector3f& position,
                  const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world, float radius,
                  ProjectedDisc* out) {
  if (!X_world.allFinite() || !normal_world.allFinite() || !std::isfinite(radius) || radius < 0.0f) return false;
  const Eigen::Vector3f Xc = R_cam_world * (X_world - position);
  if (!(Xc.z() > kNearDepth)) return false;
  const Eigen::Vector3f nc = R_cam_world * normal_world;
  const float k = nc.dot(Xc);
  const float inv_z = 1.0f / Xc.z();
  out->u = cam.fx_px * Xc.x() * inv_z + cam.cx_px;
  out->v = cam.fy_px * Xc.y() * inv_z + cam.cy_px;
  out->iz_centre = inv_z;
  splat_math::inverse_depth_gradient(nc.x(), nc.y(), k, Xc.squaredNorm(), cam.fx_px, cam.fy_px, &out->du, &out->dv);
  out->radius_px = radius * (cam.fx_px > cam.fy_px ? cam.fx_px : cam.fy_px) * inv_z;
  out->facing = -k;
  return std::isfinite(out->u) && std::isfinite(out->v);
}

}  // namespace

bool DepthBufferView::splat(const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world, float radius) {
  if (!configured_) return false;
  ProjectedDisc d;
  if (!project_disc(camera_, R_cam_world_, position_world_, X_world, normal_world, radius, &d)) return false;
  const float w = static_cast<float>(width_);
  const float h = static_cast<float>(height_);
  if (d.u + d.radius_px < -0.5f || d.v + d.radius_px < -0.5f || d.u - d.radius_px >= w - 0.5f ||
      d.v - d.radius_px >= h - 0.5f) {
    return false;
  }
  splat_projected(d.u, d.v, d.iz_centre, d.du, d.dv, d.radius_px);
  return true;
}

namespace {

// Four float lanes (GCC/Clang vector extensions: SSE2 on x86-64, NEON on aarch64) for splat_batch.
using Lanes = float __attribute__((vector_size(16)));
using LaneMask = std::int32_t __attribute__((vector_size(16)));

Lanes broadcast(float value) { return Lanes{value, value, value, value}; }

Lanes load_lanes(const std::array<float, kDiscBatchSize>& values) {
  static_assert(kDiscBatchSize * sizeof(float) == sizeof(Lanes), "one lane per disc");
  Lanes v;
  std::memcpy(&v, values.data(), sizeof v);
  return v;
}

// All ones where v is finite (v - v is 0 there, NaN for infinities and NaN).
LaneMask finite_lanes(Lanes v) { return (v - v) == broadcast(0.0f); }

Lanes select_lanes(LaneMask mask, Lanes if_true, Lanes if_false) {
  LaneMask t;
  LaneMask f;
  std::memcpy(&t, &if_true, sizeof t);
  std::memcpy(&f, &if_false, sizeof f);
  const LaneMask bits = (t & mask) | (f & ~mask);
  Lanes out;
  std::memcpy(&out, &bits, sizeof out);
  return out;
}

// a0 b0 + (a1 b1 + a2 b2): the order of Eigen's 3-term products and dots (project_disc).
Lanes dot3(Lanes a0, Lanes a1, Lanes a2, Lanes b0, Lanes b1, Lanes b2) { return a0 * b0 + (a1 * b1 + a2 * b2); }

// project_disc for the batch's lanes (lanes >= count are garbage, the caller ignores them).
struct ProjectedLanes {
  Lanes u;
  Lanes v;
  Lanes inv_z;
  Lanes du;
  Lanes dv;
  Lanes radius_px;
  Lanes facing;
  LaneMask valid;  // project_disc returned true
};

ProjectedLanes project_lanes(const BufferCamera& cam, const Eigen::Matrix3f& R, const Eigen::Vector3f& position,
                             const DiscBatch& batch) {
  const Lanes x = load_lanes(batch.x);
  const Lanes y = load_lanes(batch.y);
  const Lanes z = load_lanes(batch.z);
  const Lanes nx = load_lanes(batch.nx);
  const Lanes ny = load_lanes(batch.ny);
  const Lanes nz = load_lanes(batch.nz);
  const Lanes radius = load_lanes(batch.radius);
  ProjectedLanes d;
  d.valid = finite_lanes(x) & finite_lanes(y) & finite_lanes(z) & finite_lanes(nx) & finite_lanes(ny) &
            finite_lanes(nz) & finite_lanes(radius) & (radius >= broadcast(0.0f));
  const Lanes dx = x - broadcast(position.x());
  const Lanes dy = y - broadcast(position.y());
  const Lanes dz = z - broadcast(position.z());
  const Lanes r00 = broadcast(R(0, 0)), r01 = broadcast(R(0, 1)), r02 = broadcast(R(0, 2));
  const Lanes r10 = broadcast(R(1, 0)), r11 = broadcast(R(1, 1)), r12 = broadcast(R(1, 2));
  const Lanes r20 = broadcast(R(2, 0)), r21 = broadcast(R(2, 1)), r22 = broadcast(R(2, 2));
  const Lanes xc = dot3(r00, r01, r02, dx, dy, dz);
  const Lanes yc = dot3(r10, r11, r12, dx, dy, dz);
  const Lanes zc = dot3(r20, r21, r22, dx, dy, dz);
  d.valid &= zc > broadcast(kNearDepth);
  const Lanes ncx = dot3(r00, r01, r02, nx, ny, nz);
  const Lanes ncy = dot3(r10, r11, r12, nx, ny, nz);
  const Lanes ncz = dot3(r20, r21, r22, nx, ny, nz);
  const Lanes k = dot3(ncx, ncy, ncz, xc, yc, zc);
  d.inv_z = broadcast(1.0f) / zc;
  d.u = broadcast(cam.fx_px) * xc * d.inv_z + broadcast(cam.cx_px);
  d.v = broadcast(cam.fy_px) * yc * d.inv_z + broadcast(cam.cy_px);
  // splat_math::inverse_depth_gradient.
  const Lanes dist2 = dot3(xc, yc, zc, xc, yc, zc);
  const LaneMask grazing = k * k < broadcast(kGrazingCosine * kGrazingCosine) * dist2;
  const Lanes inv_k =
      select_lanes(grazing, broadcast(0.0f), broadcast(1.0f) / select_lanes(k != broadcast(0.0f), k, broadcast(1.0f)));
  d.du = ncx * inv_k / broadcast(cam.fx_px);
  d.dv = ncy * inv_k / broadcast(cam.fy_px);
  d.radius_px = radius * broadcast(cam.fx_px > cam.fy_px ? cam.fx_px : cam.fy_px) * d.inv_z;
  d.facing = -k;
  d.valid &= finite_lanes(d.u) & finite_lanes(d.v);
  return d;
}

// is_visible's test after project_disc, for one disc.
bool visible_at(const float* data, std::int32_t width, std::int32_t height, float tolerance_radii, float u, float v,
                float iz_centre, float du, float dv, float facing, float radius) {
  if (!(facing > 0.0f)) return false;
  if (!(u >= -0.5f && v >= -0.5f && u < width - 0.5f && v < height - 0.5f)) return false;
  const std::int32_t i = static_cast<std::int32_t>(u + 0.5f);
  const std::int32_t j = static_cast<std::int32_t>(v + 0.5f);
  const float iz_pixel = iz_centre + du * (static_cast<float>(i) - u) + dv * (static_cast<float>(j) - v);
  return data[j * width + i] <= splat_math::visibility_threshold(iz_pixel, radius, tolerance_radii);
}

}  // namespace

std::int32_t DepthBufferView::splat_batch(DiscBatch& batch) {
  const std::int32_t count = batch.count;
  batch.count = 0;
  if (!configured_ || count <= 0) return 0;
  const ProjectedLanes d = project_lanes(camera_, R_cam_world_, position_world_, batch);
  // splat(): the footprint must reach the image.
  const Lanes w = broadcast(static_cast<float>(width_) - 0.5f);
  const Lanes h = broadcast(static_cast<float>(height_) - 0.5f);
  const Lanes low = broadcast(-0.5f);
  const LaneMask valid = d.valid & ~((d.u + d.radius_px < low) | (d.v + d.radius_px < low) |
                                     (d.u - d.radius_px >= w) | (d.v - d.radius_px >= h));
  std::int32_t written = 0;
  for (std::int32_t lane = 0; lane < count; ++lane) {
    if (valid[lane] == 0) continue;
    splat_projected(d.u[lane], d.v[lane], d.inv_z[lane], d.du[lane], d.dv[lane], d.radius_px[lane]);
    ++written;
  }
  return written;
}

void DepthBufferView::is_visible_batch(const DiscBatch& batch, std::array<bool, kDiscBatchSize>* visible) const {
  visible->fill(false);
  if (!configured_ || batch.count <= 0) return;
  const ProjectedLanes d = project_lanes(camera_, R_cam_world_, position_world_, batch);
  for (std::int32_t lane = 0; lane < batch.count; ++lane) {
    (*visible)[lane] = d.valid[lane] != 0 && visible_at(data_, width_, height_, tolerance_radii_, d.u[lane], d.v[lane],
                                                       d.inv_z[lane], d.du[lane], d.dv[lane], d.facing[lane],
                                                       batch.radius[lane]);
  }
}

bool DepthBufferView::is_visible(const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world,
                                 float radius) const {
  if (!configured_) return false;
  ProjectedDisc d;
  if (!project_disc(camera_, R_cam_world_, position_world_, X_world, normal_world, radius, &d)) return false;
  return visible_at(data_, width_, height_, tolerance_radii_, d.u, d.v, d.iz_centre, d.du, d.dv, d.facing, radius);
}

void DepthBufferView::splat_projected_general(float u, float v, float iz_centre, float du, float dv,
                                              float radius_px) {
  splat_kernel::splat_general(data_, width_, height_, u, v, iz_centre, du, dv, radius_px);
}

}  // namespace vantage
