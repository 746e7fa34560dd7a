#include "core/frontend/triangulation.hpp"

#include <cmath>

#include <Eigen/Cholesky>

#include "core/estimation/ekf.hpp"
#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// Accumulates J^T R^-1 J and J^T R^-1 r of one observation at X; false when X is behind the camera.
bool accumulate(const Eigen::Vector3d& X, const Eigen::Vector2d& uv, const Viewpoint& view,
                const PinholeIntrinsics& intrinsics, const Eigen::Matrix2d& R_inv, Eigen::Matrix3d* information,
                Eigen::Vector3d* gradient) {
  Eigen::Vector2d predicted;
  Eigen::Matrix<double, 2, 3> H;
  if (!ok(project_with_jacobian(X, view, intrinsics, &predicted, &H))) return false;
  *information += H.transpose() * R_inv * H;
  *gradient += H.transpose() * R_inv * (uv - predicted);
  return true;
}

}  // namespace

Status triangulate_two_views(const TwoViewObservation& obs, const PinholeIntrinsics& intrinsics,
                             Eigen::Vector3d* X_world, Eigen::Matrix3d* Sigma_world) {
  if (!obs.uv_a_px.allFinite() || !obs.uv_b_px.allFinite() || !obs.view_a.position_world.allFinite() ||
      !obs.view_b.position_world.allFinite() || !obs.view_a.R_world_cam.allFinite() ||
      !obs.view_b.R_world_cam.allFinite() || !obs.R_a_px2.allFinite() || !obs.R_b_px2.allFinite()) {
    return Status::kNonFiniteInput;
  }
  const Eigen::Vector3d& Ca = obs.view_a.position_world;
  const Eigen::Vector3d& Cb = obs.view_b.position_world;
  const Eigen::Vector3d da = back_project_ray_world(obs.uv_a_px, obs.view_a, intrinsics);
  const Eigen::Vector3d db = back_project_ray_world(obs.uv_b_px, obs.view_b, intrinsics);
  // Closest approach of Ca + s da and Cb + t db (unit directions).
  const Eigen::Vector3d w0 = Ca - Cb;
  const double b = da.dot(db);
  const double d = da.dot(w0);
  const double e = db.dot(w0);
  const double denominator = 1.0 - b * b;
  if (!(denominator > 1e-14)) return Status::kInvalidArgument;
  const double s = (b * e - d) / denominator;
  const double t = (e - b * d) / denominator;
  if (!(s > 0.0) || !(t > 0.0)) return Status::kBehindCamera;
  Eigen::Vector3d X = 0.5 * (Ca + s * da + Cb + t * db);

  const Eigen::Matrix2d Ra_inv = obs.R_a_px2.inverse();
  const Eigen::Matrix2d Rb_inv = obs.R_b_px2.inverse();
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (int iteration = 0; iteration < 10; ++iteration) {
    information.setZero();
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    if (!accumulate(X, obs.uv_a_px, obs.view_a, intrinsics, Ra_inv, &information, &gradient) ||
        !accumulate(X, obs.uv_b_px, obs.view_b, intrinsics, Rb_inv, &information, &gradient)) {
      return Status::kBehindCamera;
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(information);
    if (ldlt.info() != Eigen::Success) return Status::kNotSpd;
    const Eigen::Vector3d step = ldlt.solve(gradient);
    if (!step.allFinite()) return Status::kNotSpd;
    X += step;
    if (step.norm() <= 1e-10 * (1.0 + X.norm())) break;
  }
  // The information at the solution (one more evaluation, so it matches the final X).
  information.setZero();
  Eigen::Vector3d unused = Eigen::Vector3d::Zero();
  if (!accumulate(X, obs.uv_a_px, obs.view_a, intrinsics, Ra_inv, &information, &unused) ||
      !accumulate(X, obs.uv_b_px, obs.view_b, intrinsics, Rb_inv, &information, &unused)) {
    return Status::kBehindCamera;
  }
  const Eigen::LLT<Eigen::Matrix3d> llt(information);
  if (llt.info() != Eigen::Success) return Status::kNotSpd;
  Eigen::Matrix3d Sigma = llt.solve(Eigen::Matrix3d::Identity());
  Sigma = 0.5 * (Sigma + Sigma.transpose());
  if (!X.allFinite() || !is_spd(Sigma)) return Status::kNotSpd;
  *X_world = X;
  *Sigma_world = Sigma;
  return Status::kOk;
}

}  // namespace vantage
