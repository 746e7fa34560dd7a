// The left-right check of a new primitive's match (FrontEndConfig::spawn_back_match_max_px).
#include <cmath>
#include <cstdint>
#include <vector>

#include <catch2/catch.hpp>

#include "core/frontend/image_front_end.hpp"
#include "core/geometry/projection.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

ImageFrontEnd g_front_end;
PrimitivePool<8192> g_pool;

using Image = std::vector<std::uint8_t>;

Viewpoint first_view() { return vantage::test::looking_at_origin({40.0, 0.0, 0.0}); }
Viewpoint second_view() { return vantage::test::looking_at_origin({39.95, 2.0, 0.0}); }

FrontEndConfig config_with(double back_match_px) {
  FrontEndConfig config;
  config.depth_min = 15.0;
  config.depth_max = 55.0;
  config.spawn_back_match_max_px = back_match_px;
  return config;
}

struct Spawned {
  std::uint32_t spawned = 0;
  std::uint64_t rejected = 0;  // FrontEndStats::seeds_rejected_back_match
  int off_plane = 0;           // primitives more than 6 of their sigmas from the plane x = 0
};

Spawned initialize_from(const vantage::test::PlaneScene& scene, const Image& a, const Image& b,
                        const FrontEndConfig& config) {
  g_pool.clear();
  REQUIRE(ok(g_front_end.configure(scene.k, config)));
  UpdateReport report;
  REQUIRE(ok(g_front_end.initialize(vantage::test::view_of(a, scene.k), first_view(),
                                    vantage::test::view_of(b, scene.k), second_view(), g_pool, &report)));
  Spawned out;
  out.spawned = report.spawned;
  out.rejected = g_front_end.stats().seeds_rejected_back_match;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (g_pool.is_alive(i) && std::abs(g_pool[i].X_world.x()) > 6.0 * std::sqrt(g_pool[i].Sigma_world(0, 0))) {
      ++out.off_plane;
    }
  }
  return out;
}

// Copies the 7x7 block of `from` centred at (fx, fy) into `to` centred at (tx, ty).
void copy_patch(const Image& from, std::int32_t fx, std::int32_t fy, Image* to, std::int32_t tx, std::int32_t ty,
                std::int32_t width) {
  for (std::int32_t dy = -kPatchSize / 2; dy <= kPatchSize / 2; ++dy) {
    for (std::int32_t dx = -kPatchSize / 2; dx <= kPatchSize / 2; ++dx) {
      const std::size_t source = static_cast<std::size_t>(fy + dy) * width + fx + dx;
      (*to)[static_cast<std::size_t>(ty + dy) * width + tx + dx] = from[source];
    }
  }
}

}  // namespace

TEST_CASE("the left-right check keeps the matches of a static textured plane, and only removes seeds") {
  const vantage::test::PlaneScene scene;
  const Image a = scene.render(first_view());
  const Image b = scene.render(second_view());
  const Spawned without = initialize_from(scene, a, b, config_with(0.0));
  const Spawned with = initialize_from(scene, a, b, config_with(0.5));
  REQUIRE(without.spawned > 300u);
  CHECK(without.rejected == 0u);
  // Each refused seed is one primitive less, nothing else changes at initialization.
  CHECK(with.spawned + with.rejected == without.spawned);
  // The back match lands within half a pixel of the seed for nearly every right match: the expected
  // position follows the match's subpixel offset (a sign error there would cost up to 1.4 px).
  CHECK(with.spawned >= 0.97 * without.spawned);
  CHECK(with.off_plane == 0);
}

TEST_CASE("the left-right check refuses a match that a repeated patch in the seed's image explains as well") {
  // A decoy: the patch the second image shows at seed s's true match m is pasted into the first image at
  // the seed s2 two cells along the epipolar line (clear of s's own patch), where the pair (s2, m) means a
  // depth of about 19 units instead of 40. Forward, s2 finds m uniquely (the exact copy) and spawns a
  // primitive 21 units off the plane; back, m's patch is explained by both s and s2.
  const vantage::test::PlaneScene scene;
  const Viewpoint first = first_view();
  const Viewpoint second = second_view();
  Image a = scene.render(first);
  const Image b = scene.render(second);
  // The seed near the centre whose true match lies closest to a whole pixel (then m's integer patch is s's
  // patch almost exactly, so the back search's two peaks tie).
  std::int32_t best_x = -1;
  std::int32_t best_y = -1;
  Eigen::Vector2d best_m;
  double best_fraction = 1.0;
  for (std::int32_t y = 50; y <= 70; y += 4) {
    for (std::int32_t x = 66; x <= 94; x += 4) {
      Eigen::Vector3d X;
      REQUIRE(scene.plane.intersect(Eigen::Vector2d(x, y), first, scene.k, &X));
      Eigen::Vector2d m;
      REQUIRE(ok(project(X, second, scene.k, &m)));
      const double fraction = (m - m.array().round().matrix()).norm();
      if (fraction < best_fraction) {
        best_fraction = fraction;
        best_x = x;
        best_y = y;
        best_m = m;
      }
    }
  }
  REQUIRE(best_x > 0);
  const std::int32_t mx = static_cast<std::int32_t>(std::lround(best_m.x()));
  const std::int32_t my = static_cast<std::int32_t>(std::lround(best_m.y()));
  // The side of s along the row where the pair (s2, m) triangulates nearer than the plane: a point nearer
  // on s's ray moves m by delta in the second image, so a seed moved by -delta pairs with m at that depth.
  Eigen::Vector3d X;
  REQUIRE(scene.plane.intersect(Eigen::Vector2d(best_x, best_y), first, scene.k, &X));
  Eigen::Vector2d m_near;
  REQUIRE(ok(project(first.position_world + 0.5 * (X - first.position_world), second, scene.k, &m_near)));
  const std::int32_t s2_x = best_x + (m_near.x() > best_m.x() ? -8 : 8);
  copy_patch(b, mx, my, &a, s2_x, best_y, scene.k.width_px);
  const Spawned without = initialize_from(scene, a, b, config_with(0.0));
  const Spawned with = initialize_from(scene, a, b, config_with(1.0));
  CHECK(without.off_plane >= 1);
  CHECK(with.off_plane == 0);
  CHECK(with.rejected >= 1u);
}

TEST_CASE("the left-right check does not allocate") {
  const vantage::test::PlaneScene scene;
  const Image a = scene.render(first_view());
  const Image b = scene.render(second_view());
  g_pool.clear();
  REQUIRE(ok(g_front_end.configure(scene.k, config_with(1.0))));
  UpdateReport report;
  Status status = Status::kOk;
  REQUIRE_NO_ALLOCATION(status = g_front_end.initialize(vantage::test::view_of(a, scene.k), first_view(),
                                                        vantage::test::view_of(b, scene.k), second_view(), g_pool,
                                                        &report));
  CHECK(ok(status));
  CHECK(report.spawned > 300u);
}

TEST_CASE("configure refuses a negative or non-finite back-match bound") {
  FrontEndConfig bad = config_with(-0.5);
  CHECK(g_front_end.configure(vantage::test::small_intrinsics(), bad) == Status::kInvalidArgument);
  bad.spawn_back_match_max_px = std::nan("");
  CHECK(g_front_end.configure(vantage::test::small_intrinsics(), bad) == Status::kNonFiniteInput);
  bad.spawn_back_match_max_px = 0.0;
  CHECK(ok(g_front_end.configure(vantage::test::small_intrinsics(), bad)));
}
