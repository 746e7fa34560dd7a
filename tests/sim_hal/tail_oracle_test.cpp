#include <catch2/catch.hpp>
#include <cmath>
#include <limits>

#include "core/geometry/projection.hpp"
#include "sim_hal/ground_truth/tail_oracle.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

constexpr std::int32_t kStride = 4;

// A tracked observation of the box's +x face seen from `creating`: the primitive stands on the ray of seed
// pixel `seed` (on the stride-4 lattice), matched in `view` at `offset_px` from the true point's projection
// with covariance sigma_px^2 I. false when the seed ray misses the box (then X is put 30 units out on it).
bool observation(const EmbreeScene& scene, const Viewpoint& creating, const Viewpoint& view, const Eigen::Vector2d& seed,
                 const Eigen::Vector2d& offset_px, double sigma_px, TrackedObservation* o) {
  const PinholeIntrinsics k = test::small_intrinsics();
  const Eigen::Vector3d ray = back_project_ray_world(seed, creating, k);
  const double t = scene.first_hit(creating.position_world, ray);
  const bool hit = std::isfinite(t);
  o->prior.X_world = creating.position_world + (hit ? t : 30.0) * ray;
  o->prior.Sigma_world = 0.01 * Eigen::Matrix3d::Identity();
  o->creating_view = creating;
  o->view = view;
  Eigen::Vector2d uv;
  if (!ok(project(o->prior.X_world, view, k, &uv))) uv = Eigen::Vector2d(k.cx_px, k.cy_px);
  o->predicted_px = uv;
  o->observed_px = uv + offset_px;
  o->R_px2 = sigma_px * sigma_px * Eigen::Matrix2d::Identity();
  o->common_covariance_px2 = Eigen::Matrix2d::Zero();
  o->B = Eigen::Matrix2d::Identity();
  return hit;
}

}  // namespace

TEST_CASE("the tail oracle refuses matches beyond the 99% quantile against the truth, and hidden true points",
          "[sim_hal][tail_oracle]") {
  const EmbreeScene scene{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5))};
  const Viewpoint creating = test::looking_at(Eigen::Vector3d(30, 0, 0));
  const Viewpoint view = test::looking_at(Eigen::Vector3d(28, 8, 3));
  const Viewpoint behind = test::looking_at(Eigen::Vector3d(-30, 0, 0));
  TailOracle oracle(scene, test::small_intrinsics(), kStride);
  TrackedObservation o;
  const Eigen::Vector2d seed(78, 58);
  // At the truth, and 2 sigma off (NEES/2 2 < 4.605): kept.
  REQUIRE(observation(scene, creating, view, seed, Eigen::Vector2d::Zero(), 0.1, &o));
  CHECK_FALSE(oracle.refuse(o));
  REQUIRE(observation(scene, creating, view, seed, Eigen::Vector2d(0.2, 0.0), 0.1, &o));
  CHECK_FALSE(oracle.refuse(o));
  // 3.3 sigma (NEES/2 5.4) and 2 px at 0.1 px: refused; 2 px at 1 px: kept.
  REQUIRE(observation(scene, creating, view, seed, Eigen::Vector2d(0.0, 0.33), 0.1, &o));
  CHECK(oracle.refuse(o));
  REQUIRE(observation(scene, creating, view, seed, Eigen::Vector2d(2.0, 0.0), 0.1, &o));
  CHECK(oracle.refuse(o));
  REQUIRE(observation(scene, creating, view, seed, Eigen::Vector2d(2.0, 0.0), 1.0, &o));
  CHECK_FALSE(oracle.refuse(o));
  // The same primitive seen from behind the box: its true point is hidden there, so the match is refused.
  REQUIRE(observation(scene, creating, behind, seed, Eigen::Vector2d::Zero(), 1.0, &o));
  CHECK(oracle.refuse(o));
  // A non-finite covariance is refused as well (it states no precision to check).
  REQUIRE(observation(scene, creating, view, seed, Eigen::Vector2d::Zero(), 0.1, &o));
  o.R_px2(0, 0) = std::numeric_limits<double>::quiet_NaN();
  CHECK(oracle.refuse(o));
  CHECK(oracle.refused() == 4u);
  CHECK(oracle.without_truth() == 0u);
  // A seed ray past the box: no truth, never refused, counted.
  REQUIRE_FALSE(observation(scene, creating, view, Eigen::Vector2d(2, 2), Eigen::Vector2d(5.0, 5.0), 0.01, &o));
  CHECK_FALSE(oracle.refuse(o));
  CHECK(oracle.without_truth() == 1u);
  CHECK(oracle.asked() == 8u);
}
