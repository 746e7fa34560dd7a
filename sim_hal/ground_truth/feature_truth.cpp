#include "sim_hal/ground_truth/feature_truth.hpp"

#include <cmath>
#include <cstdint>

#include "core/frontend/ncc.hpp"
#include "core/frontend/patch_search.hpp"
#include "core/geometry/projection.hpp"

namespace vantage::sim {

bool feature_true_point(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics,
                        const GrayImageView& noise_free_creating_image, const Primitive& p,
                        const Eigen::Vector2d& seed_px, const Viewpoint& creating, FeatureTruth* out) {
  const auto x = static_cast<std::int32_t>(std::lround(seed_px.x()));
  const auto y = static_cast<std::int32_t>(std::lround(seed_px.y()));
  NccTemplate tmpl;
  make_template(p.patch, &tmpl);
  Eigen::Vector2d match_px(x, y);
  Eigen::Matrix2d covariance_px2;
  if (!refine_subpixel(noise_free_creating_image, tmpl, x, y, kFeatureTruthFitSteps, &match_px, &covariance_px2)) {
    return false;
  }
  const Eigen::Vector3d ray = back_project_ray_world(match_px, creating, intrinsics);
  const double t = scene.first_hit(creating.position_world, ray);
  if (!std::isfinite(t)) return false;
  out->X_world = creating.position_world + t * ray;
  out->shift_px = match_px - Eigen::Vector2d(x, y);
  out->fit_covariance_px2 = covariance_px2;
  return true;
}

}  // namespace vantage::sim
