#pragma once
// The surface point a primitive's reference patch shows: its stored patch, as noisy as the creating image
// was, matched by the photometric subpixel fit in a noise-free render of the creating view, started at the
// seed pixel; the ray through the match meets the mesh there. The consistency figures' truth is the seed
// ray's point (seed_true_point). The two differ by the shift the patch's own pixel noise gives every later
// match of the primitive alike, the common error FrontEndConfig::model_template_noise models as P_c
// (core/frontend/EXPERIMENTS.md, "Session 28"). A diagnostic of what the NEES says against a truth not
// pinned to the seed ray.
#include <Eigen/Core>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive.hpp"
#include "sim_hal/scene/embree_scene.hpp"

namespace vantage::sim {

struct FeatureTruth {
  Eigen::Vector3d X_world = Eigen::Vector3d::Zero();
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();            // the fit's match minus the seed pixel
  Eigen::Matrix2d fit_covariance_px2 = Eigen::Matrix2d::Zero();  // the fit's: the patch's noise over its gradients
};

// Gauss-Newton steps of the fit: run to convergence (the tracker stops after 3).
inline constexpr int kFeatureTruthFitSteps = 20;

// seed_px: the primitive's seed pixel (seed_px_of), the centre of its stored patch. False, out untouched,
// when the fit does not converge within a pixel of the seed or leaves the image, or the ray through the
// match misses the mesh.
bool feature_true_point(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics,
                        const GrayImageView& noise_free_creating_image, const Primitive& p,
                        const Eigen::Vector2d& seed_px, const Viewpoint& creating, FeatureTruth* out);

}  // namespace vantage::sim
