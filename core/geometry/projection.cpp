#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

Eigen::Vector3d to_camera(const Eigen::Vector3d& X_world, const Viewpoint& view) {
  return view.R_world_cam.transpose() * (X_world - view.position_world);
}

}  // namespace

Status project(const Eigen::Vector3d& X_world, const Viewpoint& view, const PinholeIntrinsics& k,
               Eigen::Vector2d* uv_px) {
  const Eigen::Vector3d Xc = to_camera(X_world, view);
  if (!(Xc.z() > kMinDepth)) return Status::kBehindCamera;
  const double xn = Xc.x() / Xc.z();
  const double yn = Xc.y() / Xc.z();
  const double r2 = xn * xn + yn * yn;
  const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  (*uv_px) << k.fx_px * xn * d + k.cx_px, k.fy_px * yn * d + k.cy_px;
  return Status::kOk;
}

Status project_with_jacobian(const Eigen::Vector3d& X_world, const Viewpoint& view, const PinholeIntrinsics& k,
                             Eigen::Vector2d* uv_px, Eigen::Matrix<double, 2, 3>* H) {
  const Eigen::Vector3d Xc = to_camera(X_world, view);
  if (!(Xc.z() > kMinDepth)) return Status::kBehindCamera;
  const double inv_z = 1.0 / Xc.z();
  const double xn = Xc.x() * inv_z;
  const double yn = Xc.y() * inv_z;
  const double r2 = xn * xn + yn * yn;
  const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  const double dd_dr2 = k.k1 + 2.0 * k.k2 * r2;
  (*uv_px) << k.fx_px * xn * d + k.cx_px, k.fy_px * yn * d + k.cy_px;

  // d(xd, yd)/d(xn, yn) where xd = xn * d(r2), r2 = xn^2 + yn^2.
  Eigen::Matrix2d J_dist;
  J_dist << d + 2.0 * xn * xn * dd_dr2, 2.0 * xn * yn * dd_dr2,
            2.0 * xn * yn * dd_dr2, d + 2.0 * yn * yn * dd_dr2;
  // d(xn, yn)/d(Xc).
  Eigen::Matrix<double, 2, 3> J_norm;
  J_norm << inv_z, 0.0, -xn * inv_z,
            0.0, inv_z, -yn * inv_z;
  Eigen::Matrix2d J_pix = Eigen::Matrix2d::Zero();
  J_pix(0, 0) = k.fx_px;
  J_pix(1, 1) = k.fy_px;
  *H = J_pix * J_dist * J_norm * view.R_world_cam.transpose();
  return Status::kOk;
}

bool in_image(const Eigen::Vector2d& uv, const PinholeIntrinsics& k, double margin_px) {
  return uv.x() >= -0.5 + margin_px && uv.y() >= -0.5 + margin_px && uv.x() <= k.width_px - 0.5 - margin_px &&
         uv.y() <= k.height_px - 0.5 - margin_px;
}

Eigen::Vector3d back_project_ray_world(const Eigen::Vector2d& uv, const Viewpoint& view, const PinholeIntrinsics& k) {
  const double xd = (uv.x() - k.cx_px) / k.fx_px;
  const double yd = (uv.y() - k.cy_px) / k.fy_px;
  double xn = xd;
  double yn = yd;
  // Invert the radial model by fixed-point iteration; converges for the mild distortion of real lenses.
  for (int i = 0; i < 20; ++i) {
    const double r2 = xn * xn + yn * yn;
    const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
    xn = xd / d;
    yn = yd / d;
  }
  return (view.R_world_cam * Eigen::Vector3d(xn, yn, 1.0)).normalized();
}

}  // namespace vantage
