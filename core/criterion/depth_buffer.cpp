#include "core/criterion/depth_buffer.hpp"

#include <cmath>

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

bool DepthBufferView::is_visible(const Eigen::Vector3f& X_world, const Eigen::Vector3f& normal_world,
                                 float radius) const {
  if (!configured_) return false;
  ProjectedDisc d;
  if (!project_disc(camera_, R_cam_world_, position_world_, X_world, normal_world, radius, &d)) return false;
  if (!(d.facing > 0.0f)) return false;
  if (!(d.u >= -0.5f && d.v >= -0.5f && d.u < width_ - 0.5f && d.v < height_ - 0.5f)) return false;
  const std::int32_t i = static_cast<std::int32_t>(d.u + 0.5f);
  const std::int32_t j = static_cast<std::int32_t>(d.v + 0.5f);
  const float iz_pixel = d.iz_centre + d.du * (static_cast<float>(i) - d.u) + d.dv * (static_cast<float>(j) - d.v);
  return data_[j * width_ + i] <= splat_math::visibility_threshold(iz_pixel, radius, tolerance_radii_);
}

void DepthBufferView::splat_projected_general(float u, float v, float iz_centre, float du, float dv,
                                              float radius_px) {
  splat_kernel::splat_general(data_, width_, height_, u, v, iz_centre, du, dv, radius_px);
}

}  // namespace vantage
