#include "core/frontend/patch_warp.hpp"

#include <cmath>

#include "core/geometry/projection.hpp"

namespace vantage {

Status plane_affine(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world, const Viewpoint& reference,
                    const Viewpoint& target, const PinholeIntrinsics& intrinsics, Eigen::Matrix2d* A_ref_per_target) {
  const Eigen::Vector3d n = normal_world.cast<double>();
  if (!n.allFinite() || std::abs(n.norm() - 1.0) > 1e-3) return Status::kInvalidArgument;
  // Any orthonormal basis of the plane.
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = n.cross(helper).normalized();
  const Eigen::Vector3d e2 = n.cross(e1);
  Eigen::Matrix<double, 3, 2> basis;
  basis.col(0) = e1;
  basis.col(1) = e2;
  Eigen::Vector2d unused;
  Eigen::Matrix<double, 2, 3> H_ref;
  Eigen::Matrix<double, 2, 3> H_target;
  Status status = project_with_jacobian(X_world, reference, intrinsics, &unused, &H_ref);
  if (!ok(status)) return status;
  status = project_with_jacobian(X_world, target, intrinsics, &unused, &H_target);
  if (!ok(status)) return status;
  const Eigen::Matrix2d J_ref = H_ref * basis;        // pixels in the reference per unit on the plane
  const Eigen::Matrix2d J_target = H_target * basis;  // pixels in the target per unit on the plane
  const double det = J_target.determinant();
  // Edge-on: the plane's image in the target has (almost) no area.
  if (!(std::abs(det) > 1e-9 * J_target.squaredNorm())) return Status::kInvalidArgument;
  *A_ref_per_target = J_ref * J_target.inverse();
  return A_ref_per_target->allFinite() ? Status::kOk : Status::kInvalidArgument;
}

void warp_patch_template(const std::array<std::uint8_t, kPatchPixels>& patch, const Eigen::Matrix2d& A,
                         NccTemplate* out) {
  std::array<float, kPatchPixels> gray{};
  std::array<float, kPatchPixels> mask{};
  constexpr double kLimit = kPatchRadius;  // the stored patch covers offsets [-r, r]
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kPatchSize; ++tx) {
      const Eigen::Vector2d offset = A * Eigen::Vector2d(tx - kPatchRadius, ty - kPatchRadius);
      const int i = ty * kPatchSize + tx;
      if (!(std::abs(offset.x()) <= kLimit) || !(std::abs(offset.y()) <= kLimit)) continue;
      const double sx = offset.x() + kPatchRadius;
      const double sy = offset.y() + kPatchRadius;
      int x0 = static_cast<int>(std::floor(sx));
      int y0 = static_cast<int>(std::floor(sy));
      if (x0 > kPatchSize - 2) x0 = kPatchSize - 2;
      if (y0 > kPatchSize - 2) y0 = kPatchSize - 2;
      const double fx = sx - x0;
      const double fy = sy - y0;
      const double top = (1.0 - fx) * patch[y0 * kPatchSize + x0] + fx * patch[y0 * kPatchSize + x0 + 1];
      const double bottom = (1.0 - fx) * patch[(y0 + 1) * kPatchSize + x0] + fx * patch[(y0 + 1) * kPatchSize + x0 + 1];
      gray[i] = static_cast<float>((1.0 - fy) * top + fy * bottom);
      mask[i] = 1.0f;
    }
  }
  make_template(gray, mask, out);
}

Status plane_affine_tilt_derivatives(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world,
                                     const Viewpoint& reference, const Viewpoint& target,
                                     const PinholeIntrinsics& intrinsics, const Eigen::Matrix2d& A_ref_per_target,
                                     std::array<Eigen::Matrix2d, 2>* dA) {
  const Eigen::Vector3d n = normal_world.cast<double>().normalized();
  if (!n.allFinite()) return Status::kInvalidArgument;
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d axes[2] = {n.cross(helper).normalized(), n.cross(n.cross(helper).normalized())};
  constexpr double kStep = 1e-3;  // rad; float normals resolve ~1e-7
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3f tilted = (n + kStep * axes[k]).normalized().cast<float>();
    Eigen::Matrix2d A_tilted;
    const Status status = plane_affine(X_world, tilted, reference, target, intrinsics, &A_tilted);
    if (!ok(status)) return status;
    (*dA)[static_cast<std::size_t>(k)] = (A_tilted - A_ref_per_target) / kStep;
  }
  return Status::kOk;
}

Eigen::Matrix2d warp_shift_covariance(const NccTemplate& tmpl, const Eigen::Matrix2d& A_ref_per_target,
                                      const std::array<Eigen::Matrix2d, 2>& dA, double tilt_variance) {
  const Eigen::Matrix2d A_inv = A_ref_per_target.inverse();
  if (!A_inv.allFinite() || !(tilt_variance > 0.0)) return Eigen::Matrix2d::Zero();
  const Eigen::Matrix2d U[2] = {A_inv * dA[0], A_inv * dA[1]};  // displacement per unit tilt: U_k x
  Eigen::Matrix2d G = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b[2] = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  auto valid = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < kPatchSize && y < kPatchSize && tmpl.mask[y * kPatchSize + x] > 0.5f;
  };
  auto value = [&](int x, int y) { return static_cast<double>(tmpl.values[y * kPatchSize + x]); };
  // One-sided differences at the mask's edge, none where both sides are missing.
  auto derivative = [&](int x, int y, int dx, int dy, double* out) {
    const bool forward = valid(x + dx, y + dy);
    const bool backward = valid(x - dx, y - dy);
    if (forward && backward) {
      *out = 0.5 * (value(x + dx, y + dy) - value(x - dx, y - dy));
    } else if (forward) {
      *out = value(x + dx, y + dy) - value(x, y);
    } else if (backward) {
      *out = value(x, y) - value(x - dx, y - dy);
    } else {
      return false;
    }
    return true;
  };
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kPatchSize; ++tx) {
      if (!valid(tx, ty)) continue;
      Eigen::Vector2d g;
      if (!derivative(tx, ty, 1, 0, &g.x()) || !derivative(tx, ty, 0, 1, &g.y())) continue;
      const Eigen::Vector2d offset(tx - kPatchRadius, ty - kPatchRadius);
      G += g * g.transpose();
      for (int k = 0; k < 2; ++k) b[k] += g * g.dot(U[k] * offset);
    }
  }
  if (!(G.determinant() > 1e-12 * G.squaredNorm())) return Eigen::Matrix2d::Zero();
  const Eigen::Matrix2d G_inv = G.inverse();
  const Eigen::Vector2d m0 = G_inv * b[0];
  const Eigen::Vector2d m1 = G_inv * b[1];
  return tilt_variance * (m0 * m0.transpose() + m1 * m1.transpose());
}

}  // namespace vantage

