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

namespace {

#if defined(__x86_64__)
// Four points in AVX lanes (no FMA: nothing is contracted). No lambdas or helpers taking the vectors:
// they would not inherit the target attribute.
__attribute__((target("avx2"))) void project_lanes4(const Eigen::Vector3d* const* X_world, std::int32_t count,
                                                    const Viewpoint& view, const PinholeIntrinsics& k,
                                                    Eigen::Vector2d* uv_px, Eigen::Matrix<double, 2, 3>* H,
                                                    Status* status) {
  using Double4 = double __attribute__((vector_size(32)));
  Double4 x, y, z;
  for (std::int32_t lane = 0; lane < kProjectionBatchSize; ++lane) {
    const Eigen::Vector3d& X = *X_world[lane < count ? lane : 0];  // unused lanes repeat the first point
    x[lane] = X.x();
    y[lane] = X.y();
    z[lane] = X.z();
  }
  const Eigen::Matrix3d& R = view.R_world_cam;
  const Double4 d0 = x - view.position_world.x();
  const Double4 d1 = y - view.position_world.y();
  const Double4 d2 = z - view.position_world.z();
  // to_camera: R^T (X - position).
  const Double4 xc = (R(0, 0) * d0 + R(1, 0) * d1) + R(2, 0) * d2;
  const Double4 yc = (R(0, 1) * d0 + R(1, 1) * d1) + R(2, 1) * d2;
  const Double4 zc = (R(0, 2) * d0 + R(1, 2) * d1) + R(2, 2) * d2;
  const Double4 inv_z = 1.0 / zc;
  const Double4 xn = xc * inv_z;
  const Double4 yn = yc * inv_z;
  const Double4 r2 = xn * xn + yn * yn;
  const Double4 d = (1.0 + k.k1 * r2) + (k.k2 * r2) * r2;
  const Double4 dd_dr2 = k.k1 + (2.0 * k.k2) * r2;
  const Double4 u = (k.fx_px * xn) * d + k.cx_px;
  const Double4 v = (k.fy_px * yn) * d + k.cy_px;
  const Double4 dist00 = d + ((2.0 * xn) * xn) * dd_dr2;
  const Double4 dist01 = ((2.0 * xn) * yn) * dd_dr2;  // = dist10
  const Double4 dist11 = d + ((2.0 * yn) * yn) * dd_dr2;
  // J_pix J_dist, J_pix's zeros multiplied as Eigen does.
  const double fx = k.fx_px;
  const double fy = k.fy_px;
  const double zero = 0.0;
  const Double4 t00 = fx * dist00 + zero * dist01;
  const Double4 t01 = fx * dist01 + zero * dist11;
  const Double4 t10 = zero * dist00 + fy * dist01;
  const Double4 t11 = zero * dist01 + fy * dist11;
  // (J_pix J_dist) J_norm, J_norm = [inv_z 0 -xn inv_z; 0 inv_z -yn inv_z].
  const Double4 zero4 = Double4{} + zero;
  const Double4 norm02 = (-xn) * inv_z;
  const Double4 norm12 = (-yn) * inv_z;
  const Double4 s00 = t00 * inv_z + t01 * zero4;
  const Double4 s01 = t00 * zero4 + t01 * inv_z;
  const Double4 s02 = t00 * norm02 + t01 * norm12;
  const Double4 s10 = t10 * inv_z + t11 * zero4;
  const Double4 s11 = t10 * zero4 + t11 * inv_z;
  const Double4 s12 = t10 * norm02 + t11 * norm12;
  // ... R^T: H(i, j) = s_i0 R(j, 0) + (s_i1 R(j, 1) + s_i2 R(j, 2)).
  const Double4 h00 = s00 * R(0, 0) + (s01 * R(0, 1) + s02 * R(0, 2));
  const Double4 h01 = s00 * R(1, 0) + (s01 * R(1, 1) + s02 * R(1, 2));
  const Double4 h02 = s00 * R(2, 0) + (s01 * R(2, 1) + s02 * R(2, 2));
  const Double4 h10 = s10 * R(0, 0) + (s11 * R(0, 1) + s12 * R(0, 2));
  const Double4 h11 = s10 * R(1, 0) + (s11 * R(1, 1) + s12 * R(1, 2));
  const Double4 h12 = s10 * R(2, 0) + (s11 * R(2, 1) + s12 * R(2, 2));
  for (std::int32_t lane = 0; lane < count; ++lane) {
    if (!(zc[lane] > kMinDepth)) {
      status[lane] = Status::kBehindCamera;
      continue;
    }
    status[lane] = Status::kOk;
    uv_px[lane] << u[lane], v[lane];
    H[lane] << h00[lane], h01[lane], h02[lane], h10[lane], h11[lane], h12[lane];
  }
}
#endif

}  // namespace

void project_with_jacobian_batch(const Eigen::Vector3d* const* X_world, std::int32_t count, const Viewpoint& view,
                                 const PinholeIntrinsics& intrinsics, Eigen::Vector2d* uv_px,
                                 Eigen::Matrix<double, 2, 3>* H_px_per_unit, Status* status) {
  if (count <= 0) return;
  if (count > kProjectionBatchSize) count = kProjectionBatchSize;
#if defined(__x86_64__)
  if (__builtin_cpu_supports("avx2")) {
    project_lanes4(X_world, count, view, intrinsics, uv_px, H_px_per_unit, status);
    return;
  }
#endif
  for (std::int32_t i = 0; i < count; ++i) {
    status[i] = project_with_jacobian(*X_world[i], view, intrinsics, &uv_px[i], &H_px_per_unit[i]);
  }
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
