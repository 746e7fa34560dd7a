// A new primitive whose neighbours fit no plane (FrontEndConfig::spawn_requires_plane_fit).
#include <cmath>
#include <cstdint>
#include <vector>

#include <catch2/catch.hpp>

#include "core/frontend/image_front_end.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

ImageFrontEnd g_front_end;
PrimitivePool<8192> g_pool;

using Image = std::vector<std::uint8_t>;

Viewpoint first_view() { return vantage::test::looking_at_origin({40.0, 0.0, 0.0}); }
Viewpoint second_view() { return vantage::test::looking_at_origin({39.95, 2.0, 0.0}); }

// A depth step across the image: the textured plane x = 0 for world y < 0 in front of a textured plane
// x = -10, so the seeds along the step see two layers that slide apart between the views.
struct StepScene {
  vantage::test::PlaneScene near_plane;
  vantage::test::TexturedPlane far_plane;
  StepScene() {
    far_plane.offset = -10.0;
    far_plane.feature_size = 0.7;
  }
  Image render(const Viewpoint& view) const {
    const Image near_image = near_plane.render(view);
    Image far_image;
    vantage::test::render_plane(far_plane, view, near_plane.k, &far_image);
    Image out = far_image;
    for (std::int32_t y = 0; y < near_plane.k.height_px; ++y) {
      for (std::int32_t x = 0; x < near_plane.k.width_px; ++x) {
        Eigen::Vector3d X;
        if (near_plane.plane.intersect(Eigen::Vector2d(x, y), view, near_plane.k, &X) && X.y() < 0.0) {
          const std::size_t at = static_cast<std::size_t>(y) * near_plane.k.width_px + x;
          out[at] = near_image[at];
        }
      }
    }
    return out;
  }
  // Whether X lies within `sigmas` of its standard deviations along x of either layer.
  static bool on_a_layer(const Primitive& p, double sigmas) {
    const double sd = std::sqrt(p.Sigma_world(0, 0));
    return std::abs(p.X_world.x()) <= sigmas * sd || std::abs(p.X_world.x() + 10.0) <= sigmas * sd;
  }
};

struct Spawned {
  std::uint32_t spawned = 0;
  std::uint64_t erased = 0;  // FrontEndStats::seeds_rejected_no_plane_fit
  int facing_prior = 0;      // alive primitives whose normal is still the facing prior
  int off_layers = 0;        // alive primitives more than 6 sigma from both layers
};

Spawned initialize_from(const Image& a, const Image& b, const PinholeIntrinsics& k, bool requires_plane_fit) {
  FrontEndConfig config;
  config.depth_min = 15.0;
  config.depth_max = 65.0;
  config.spawn_requires_plane_fit = requires_plane_fit;
  g_pool.clear();
  REQUIRE(ok(g_front_end.configure(k, config)));
  UpdateReport report;
  REQUIRE(ok(g_front_end.initialize(vantage::test::view_of(a, k), first_view(), vantage::test::view_of(b, k),
                                    second_view(), g_pool, &report)));
  Spawned out;
  out.spawned = report.spawned;
  out.erased = g_front_end.stats().seeds_rejected_no_plane_fit;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (!g_pool.is_alive(i)) continue;
    if (g_front_end.normal_source(i) == NormalSource::kFacingPrior) ++out.facing_prior;
    if (!StepScene::on_a_layer(g_pool[i], 6.0)) ++out.off_layers;
  }
  return out;
}

}  // namespace

TEST_CASE("requiring a plane fit erases the new primitives along a depth step and only those") {
  const StepScene scene;
  const Image a = scene.render(first_view());
  const Image b = scene.render(second_view());
  const Spawned without = initialize_from(a, b, scene.near_plane.k, false);
  const Spawned with = initialize_from(a, b, scene.near_plane.k, true);
  REQUIRE(without.spawned > 300u);
  CHECK(without.erased == 0u);
  // The step leaves some seeds without a plane among their neighbours.
  CHECK(without.facing_prior >= 1);
  // The seeds spawned are the same; the rule erases after all of them are placed, and counts each.
  CHECK(with.spawned + with.erased == without.spawned);
  CHECK(with.erased >= static_cast<std::uint64_t>(without.facing_prior));
  CHECK(with.facing_prior == 0);
  // Most of the scene is kept: the step is one line across it.
  CHECK(with.spawned >= 0.8 * without.spawned);
  CHECK(with.off_layers <= without.off_layers);
}

TEST_CASE("requiring a plane fit keeps every new primitive of a textured plane") {
  const vantage::test::PlaneScene scene;
  const Image a = scene.render(first_view());
  const Image b = scene.render(second_view());
  const Spawned without = initialize_from(a, b, scene.k, false);
  const Spawned with = initialize_from(a, b, scene.k, true);
  REQUIRE(without.spawned > 300u);
  CHECK(without.facing_prior == 0);
  CHECK(with.spawned == without.spawned);
  CHECK(with.erased == 0u);
}

TEST_CASE("requiring a plane fit does not allocate") {
  const StepScene scene;
  const Image a = scene.render(first_view());
  const Image b = scene.render(second_view());
  FrontEndConfig config;
  config.depth_min = 15.0;
  config.depth_max = 65.0;
  config.spawn_requires_plane_fit = true;
  g_pool.clear();
  REQUIRE(ok(g_front_end.configure(scene.near_plane.k, config)));
  UpdateReport report;
  Status status = Status::kOk;
  REQUIRE_NO_ALLOCATION(status = g_front_end.initialize(vantage::test::view_of(a, scene.near_plane.k), first_view(),
                                                        vantage::test::view_of(b, scene.near_plane.k), second_view(),
                                                        g_pool, &report));
  CHECK(ok(status));
  CHECK(report.spawned > 300u);
}
