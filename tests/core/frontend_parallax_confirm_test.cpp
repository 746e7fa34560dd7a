// Confirmation by parallax (FrontEndConfig::confirm_min_depth_information, primitive_flags::kProvisional):
// a new primitive stays provisional until an accepted match has constrained its depth along the seed ray.
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <catch2/catch.hpp>

#include "core/frontend/image_front_end.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

ImageFrontEnd g_front_end;  // static storage, as in a target
PrimitivePool<8192> g_pool;

using Scene = vantage::test::PlaneScene;  // the plane x = 0, seen from +x

const Eigen::Vector3d kFirst{40.0, 0.0, 0.0};

FrontEndConfig config_with(double depth_information, std::uint32_t max_updates = 0) {
  FrontEndConfig config;
  config.depth_min = 25.0;
  config.depth_max = 55.0;
  config.confirm_min_depth_information = depth_information;
  config.provisional_max_updates = max_updates;
  return config;
}

bool provisional(const Primitive& p) { return (p.flags & primitive_flags::kProvisional) != 0; }

void initialize(const Scene& scene, const FrontEndConfig& config) {
  const Viewpoint first = vantage::test::looking_at_origin(kFirst);
  const Viewpoint second = vantage::test::looking_at_origin({39.95, 2.0, 0.0});
  UpdateReport report;
  REQUIRE(ok(vantage::test::initialize_on_plane(g_front_end, g_pool, scene, first, second, config, &report)));
  REQUIRE(report.spawned > 200);
}

UpdateReport update_from(const Scene& scene, const Viewpoint& view) {
  const auto image = scene.render(view);
  UpdateReport report;
  REQUIRE(ok(g_front_end.update(vantage::test::view_of(image, scene.k), view, g_pool, &report)));
  return report;
}

// The alive primitive nearest the plane's centre.
PrimitiveIndex central_primitive() {
  PrimitiveIndex best = kInvalidPrimitive;
  double best_distance = std::numeric_limits<double>::infinity();
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (!g_pool.is_alive(i)) continue;
    const double d = std::hypot(g_pool[i].X_world.y(), g_pool[i].X_world.z());
    if (d < best_distance) {
      best_distance = d;
      best = i;
    }
  }
  return best;
}

// A view farther back along primitive i's seed ray (from the first camera): a wrong depth along that ray
// does not move i's projection there.
Viewpoint collinear_view(PrimitiveIndex i) {
  const Eigen::Vector3d back = (kFirst - g_pool[i].X_world).normalized();
  Viewpoint view;
  (void)look_at(kFirst + 3.0 * back, g_pool[i].X_world, Eigen::Vector3d::UnitZ(), &view);
  return view;
}

double seed_ray_variance(const Primitive& p) {
  const Eigen::Vector3d ray = (p.X_world - kFirst).normalized();
  return ray.dot(p.Sigma_world * ray);
}

}  // namespace

TEST_CASE("parallax confirmation: spawns are provisional, a collinear view does not confirm, parallax does") {
  Scene scene;
  initialize(scene, config_with(1.0));
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (g_pool.is_alive(i)) CHECK(provisional(g_pool[i]));
  }
  const PrimitiveIndex c = central_primitive();
  REQUIRE(c != kInvalidPrimitive);
  const double variance_before = seed_ray_variance(g_pool[c]);
  (void)update_from(scene, collinear_view(c));
  // Matched and accepted (the image agrees), but its depth is as uncertain as before: still provisional.
  REQUIRE(g_pool.is_alive(c));
  CHECK(g_pool[c].observation_count == 1u);
  CHECK(provisional(g_pool[c]));
  CHECK(seed_ray_variance(g_pool[c]) > 0.5 * variance_before);

  // About 17 degrees away: the depth shows, and the updated primitives are confirmed.
  const std::uint64_t confirmed_before = g_front_end.stats().parallax_confirmed;
  const UpdateReport report = update_from(scene, vantage::test::looking_at_origin({38.0, -6.0, 10.0}));
  REQUIRE(report.updated > 100u);
  CHECK(g_front_end.stats().parallax_confirmed - confirmed_before >= 0.9 * report.updated);
  REQUIRE(g_pool.is_alive(c));
  CHECK(g_pool[c].observation_count == 2u);
  CHECK_FALSE(provisional(g_pool[c]));
  CHECK(seed_ray_variance(g_pool[c]) < 0.5 * variance_before);
  CHECK(g_front_end.stats().provisional_erased == 0u);
}

TEST_CASE("parallax confirmation: a wrong depth passes a collinear view but is not confirmed") {
  Scene scene;
  initialize(scene, config_with(1.0));
  const PrimitiveIndex c = central_primitive();
  REQUIRE(c != kInvalidPrimitive);
  // A wrong spawn match: the point 20 seed-ray sigmas in front of the plane, on its seed ray (behind it,
  // the depth buffer would hide it and the first-view confirmation erase it).
  Primitive& p = g_pool[c];
  const Eigen::Vector3d ray = (p.X_world - kFirst).normalized();
  p.X_world -= 20.0 * std::sqrt(seed_ray_variance(p)) * ray;
  const double wrong_x = p.X_world.x();
  REQUIRE(wrong_x > 0.1);  // a gross error, not a rounding
  (void)update_from(scene, collinear_view(c));
  // The collinear view accepts it (the projection is right) and leaves the depth wrong: not confirmed.
  REQUIRE(g_pool.is_alive(c));
  CHECK(g_pool[c].observation_count == 1u);
  CHECK(g_pool[c].X_world.x() > 0.5 * wrong_x);
  CHECK(provisional(g_pool[c]));
}

TEST_CASE("parallax confirmation: provisional_max_updates erases what stays unconfirmed") {
  Scene scene;
  initialize(scene, config_with(1.0, 1));
  const PrimitiveIndex c = central_primitive();
  REQUIRE(c != kInvalidPrimitive);
  const UpdateReport report = update_from(scene, collinear_view(c));
  // Its one accepted update did not constrain the depth: erased at the first.
  CHECK_FALSE(g_pool.is_alive(c));
  CHECK(g_front_end.stats().provisional_erased > 0u);
  CHECK(report.gated_erased >= g_front_end.stats().provisional_erased);
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (g_pool.is_alive(i) && g_pool[i].observation_count > 0) CHECK_FALSE(provisional(g_pool[i]));
  }
}

TEST_CASE("parallax confirmation: off flags nothing and the fields are validated without allocating") {
  Scene scene;
  initialize(scene, config_with(0.0));
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (g_pool.is_alive(i)) CHECK_FALSE(provisional(g_pool[i]));
  }
  const Viewpoint third = vantage::test::looking_at_origin({38.0, -6.0, 10.0});
  const auto image = scene.render(third);
  UpdateReport report;
  Status status = Status::kOk;
  REQUIRE_NO_ALLOCATION(status = g_front_end.update(vantage::test::view_of(image, scene.k), third, g_pool, &report));
  REQUIRE(ok(status));
  CHECK(g_front_end.stats().parallax_confirmed == 0u);

  // With the rule on, the same update does not allocate either.
  initialize(scene, config_with(1.0, 2));
  REQUIRE_NO_ALLOCATION(status = g_front_end.update(vantage::test::view_of(image, scene.k), third, g_pool, &report));
  REQUIRE(ok(status));
  CHECK(g_front_end.stats().parallax_confirmed > 0u);

  FrontEndConfig bad = config_with(-1.0);
  CHECK(bad.validate() == Status::kInvalidArgument);
  bad.confirm_min_depth_information = std::numeric_limits<double>::quiet_NaN();
  CHECK(bad.validate() == Status::kNonFiniteInput);
}
