#include "sim_hal/ground_truth/normal_oracle.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>

#include "core/frontend/ncc.hpp"
#include "core/geometry/projection.hpp"
#include "sim_hal/ground_truth/gate_diagnostics.hpp"

namespace vantage::sim {

bool patch_plane_normal(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, const Eigen::Vector2d& seed_px,
                        const Viewpoint& view, Eigen::Vector3d* normal_world) {
  Eigen::Vector3d points[kPatchPixels];
  int hits = 0;
  for (int dy = -kPatchRadius; dy <= kPatchRadius; ++dy) {
    for (int dx = -kPatchRadius; dx <= kPatchRadius; ++dx) {
      const Eigen::Vector3d ray = back_project_ray_world(seed_px + Eigen::Vector2d(dx, dy), view, intrinsics);
      const double t = scene.first_hit(view.position_world, ray);
      if (std::isfinite(t)) points[hits++] = view.position_world + t * ray;
    }
  }
  if (hits < kPatchPixels / 2) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i = 0; i < hits; ++i) mean += points[i];
  mean /= hits;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int i = 0; i < hits; ++i) scatter += (points[i] - mean) * (points[i] - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  // The plane's normal is the scatter's smallest axis; a line of points (second axis ~ 0) has none.
  if (eigen.info() != Eigen::Success || !(eigen.eigenvalues()(1) > 1e-12)) return false;
  Eigen::Vector3d n = eigen.eigenvectors().col(0).normalized();
  if (n.dot(view.position_world - mean) < 0.0) n = -n;
  if (!n.allFinite()) return false;
  *normal_world = n;
  return true;
}

void NormalOracle::apply(ImageFrontEnd& front_end, PrimitivePoolView& pool) {
  if (truths_.size() < pool.index_bound()) truths_.resize(pool.index_bound());
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    const Primitive& p = pool[i];
    Viewpoint creating;
    Eigen::Vector2d seed;
    if (!ok(front_end.view_pose(p.creating_view, &creating)) ||
        !seed_px_of(intrinsics_, stride_px_, p, creating, &seed)) {
      ++without_truth_;
      continue;
    }
    Truth& truth = truths_[i];
    if (truth.creating_view != p.creating_view || truth.seed_px != seed) {
      truth.creating_view = p.creating_view;
      truth.seed_px = seed;
      truth.found = patch_plane_normal(scene_, intrinsics_, seed, creating, &truth.normal_world);
    }
    if (!truth.found || !ok(front_end.adopt_normal(i, truth.normal_world, kNormalOracleTiltVariance, pool))) {
      ++without_truth_;
      continue;
    }
    ++adopted_;
  }
}

void NormalOracle::print(std::FILE* out) const {
  std::fprintf(out, "normal oracle: %llu normals adopted over the mission, %llu asked without a truth\n",
               static_cast<unsigned long long>(adopted_), static_cast<unsigned long long>(without_truth_));
}

}  // namespace vantage::sim
