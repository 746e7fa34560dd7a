#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "core/frontend/image_front_end.hpp"
#include "core/geometry/projection.hpp"
#include "sim_hal/ground_truth/normal_oracle.hpp"
#include "sim_hal/ground_truth/normals_by_source.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::fmin(1.0, a.normalized().dot(b.normalized()))) * 180.0 / test::kPi;
}

constexpr std::int32_t kStride = 4;

// Static storage, as in a target: the front end is megabytes.
ImageFrontEnd g_front_end;
PrimitivePool<4096> g_pool;

}  // namespace

TEST_CASE("a patch's plane normal is the face's on a box and the radial direction on a sphere, facing the view",
          "[sim_hal][normal_oracle]") {
  const PinholeIntrinsics k = test::small_intrinsics();
  const EmbreeScene box{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5))};
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  // The +x face seen head on and obliquely: its normal either way.
  REQUIRE(patch_plane_normal(box, k, Eigen::Vector2d(78, 58), test::looking_at({30, 0, 0}), &n));
  CHECK(angle_deg(n, Eigen::Vector3d::UnitX()) < 1e-3);
  REQUIRE(patch_plane_normal(box, k, Eigen::Vector2d(70, 62), test::looking_at({28, 8, 3}), &n));
  CHECK(angle_deg(n, Eigen::Vector3d::UnitX()) < 1e-3);
  // A sphere of radius 8: the patch plane is the tangent plane at its centre's hit, to within a degree.
  const EmbreeScene sphere{test::make_uv_sphere(Eigen::Vector3f::Zero(), 8.0f, 256)};
  const Viewpoint view = test::looking_at({30, 0, 0});
  const Eigen::Vector2d seed(100, 40);
  const Eigen::Vector3d ray = back_project_ray_world(seed, view, k);
  const double t = sphere.first_hit(view.position_world, ray);
  REQUIRE(std::isfinite(t));
  REQUIRE(patch_plane_normal(sphere, k, seed, view, &n));
  CHECK(angle_deg(n, view.position_world + t * ray) < 1.0);
  // Rays past the box: no plane, the output untouched.
  n = Eigen::Vector3d(0, 0, 7);
  CHECK_FALSE(patch_plane_normal(box, k, Eigen::Vector2d(2, 2), test::looking_at({30, 0, 0}), &n));
  CHECK(n == Eigen::Vector3d(0, 0, 7));
}

namespace {

// A textured plate facing +x and filling the image, seen from 30 units by a two-view start one unit apart:
// the front end initialized on it (g_front_end, g_pool).
const EmbreeScene& initialize_on_plate() {
  static const EmbreeScene plate{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(0.1f, 20.0f, 20.0f))};
  const PinholeIntrinsics k = test::small_intrinsics();
  RaycastCameraConfig camera_config;
  camera_config.intrinsics = k;
  const RaycastCamera camera(plate, camera_config, nullptr);
  const Viewpoint first = test::looking_at({30, 0, 0});
  const Viewpoint second = test::looking_at({30, 1, 0});
  std::vector<std::uint8_t> a(static_cast<std::size_t>(k.width_px) * k.height_px);
  std::vector<std::uint8_t> b(a.size());
  REQUIRE(ok(camera.render(first, MutableGrayImageView{a.data(), k.width_px, k.height_px, k.width_px}, nullptr, 0)));
  REQUIRE(ok(camera.render(second, MutableGrayImageView{b.data(), k.width_px, k.height_px, k.width_px}, nullptr, 1)));
  FrontEndConfig config;
  config.seed_stride_px = kStride;
  REQUIRE(ok(g_front_end.configure(k, config)));
  g_pool.clear();
  UpdateReport report;
  REQUIRE(ok(g_front_end.initialize(GrayImageView{a.data(), k.width_px, k.height_px, k.width_px}, first,
                                    GrayImageView{b.data(), k.width_px, k.height_px, k.width_px}, second, g_pool,
                                    &report)));
  REQUIRE(g_pool.size() > 20u);
  return plate;
}

}  // namespace

TEST_CASE("the normal oracle gives every primitive its seed's face normal and counts those without a truth",
          "[sim_hal][normal_oracle]") {
  const EmbreeScene& plate = initialize_on_plate();
  const PinholeIntrinsics k = test::small_intrinsics();
  // Every primitive given a wrong, confident normal first, so the oracle's is the one seen afterwards.
  const Eigen::Vector3d wrong = Eigen::Vector3d(0.6, 0.8, 0.0);
  PrimitiveIndex moved = kInvalidPrimitive;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (!g_pool.is_alive(i)) continue;
    REQUIRE(ok(g_front_end.adopt_normal(i, wrong, 0.01, g_pool)));
    if (moved == kInvalidPrimitive) moved = i;
  }
  // One primitive said to come from a view the front end never saw: no creating pose, no truth.
  g_pool[moved].creating_view = 999;
  NormalOracle oracle(plate, k, kStride);
  oracle.apply(g_front_end, g_pool);
  CHECK(oracle.adopted() == g_pool.size() - 1);
  CHECK(oracle.without_truth() == 1u);
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (!g_pool.is_alive(i)) continue;
    INFO("slot " << i);
    if (i == moved) {
      CHECK(angle_deg(g_pool[i].normal_world.cast<double>(), wrong) < 1e-3);
      CHECK(g_front_end.normal_tilt_variance(i) == Approx(0.01));
    } else {
      CHECK(angle_deg(g_pool[i].normal_world.cast<double>(), Eigen::Vector3d::UnitX()) < 1e-3);
      CHECK(g_front_end.normal_tilt_variance(i) == Approx(kNormalOracleTiltVariance));
    }
  }
  // Asked again, the cached truths give the same, and the counts add up.
  oracle.apply(g_front_end, g_pool);
  CHECK(oracle.adopted() == 2 * (g_pool.size() - 1));
  CHECK(oracle.without_truth() == 2u);
}

TEST_CASE("normals by source: each source's angle to the seed patch's plane, its capped consistency, the skipped",
          "[sim_hal][normal_oracle]") {
  // By hand: a normal 10 degrees off claiming 5 degrees reads 4 (angle^2 / variance); one 60 degrees off
  // claiming 5 degrees is capped at 50, and counts as more than 30 degrees off.
  NormalsBySource by_hand;
  const double deg = M_PI / 180.0;
  const Eigen::Vector3d truth = Eigen::Vector3d::UnitZ();
  by_hand.add(NormalSource::kRefit, Eigen::Vector3d(std::sin(10 * deg), 0, std::cos(10 * deg)), std::pow(5 * deg, 2), truth,
              2.0, 4);
  by_hand.add(NormalSource::kRefit, Eigen::Vector3d(0, -std::sin(60 * deg), -std::cos(60 * deg)), std::pow(5 * deg, 2),
              truth, 4.0, 8);
  CHECK(by_hand.count(NormalSource::kRefit) == 2u);
  CHECK(by_hand.mean_angle_deg(NormalSource::kRefit) == Approx(35.0));
  CHECK(by_hand.count(NormalSource::kSpawnFit) == 0u);
  CHECK(by_hand.mean_angle_deg(NormalSource::kSpawnFit) == 0.0);
  char text[2048] = {};
  std::FILE* out = fmemopen(text, sizeof(text) - 1, "w");
  REQUIRE(out != nullptr);
  by_hand.print(out, "row: ");
  std::fclose(out);
  CHECK(std::string(text) ==
        "row: normals from refit: N=2 mean angle to the seed patch's plane 35.0 deg, more than 30 deg off 0.500, "
        "claimed sd 5.0 deg, mean angle^2 / tilt variance 27.00 (2 when consistent; each capped at 50), the "
        "primitives' mean NEES 3.000, mean updates 6.0\n");

  // From a front end's pool on the plate: every normal adopted as the plate's reads 0 degrees, a wrong one
  // its angle, and a primitive without its creating view is skipped.
  const EmbreeScene& plate = initialize_on_plate();
  PrimitiveIndex wrong_one = kInvalidPrimitive;
  PrimitiveIndex orphan = kInvalidPrimitive;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    if (!g_pool.is_alive(i)) continue;
    if (wrong_one == kInvalidPrimitive) {
      wrong_one = i;
      REQUIRE(ok(g_front_end.adopt_normal(i, Eigen::Vector3d(0.6, 0.8, 0.0), 0.01, g_pool)));
      continue;
    }
    if (orphan == kInvalidPrimitive) {
      orphan = i;
      continue;
    }
    REQUIRE(ok(g_front_end.adopt_normal(i, Eigen::Vector3d::UnitX(), 1e-4, g_pool)));
  }
  g_pool[orphan].creating_view = 999;
  NormalsBySource from_pool;
  from_pool.add_pool(plate, g_front_end, g_pool);
  CHECK(from_pool.skipped() == 1u);
  CHECK(from_pool.count(NormalSource::kAdopted) == g_pool.size() - 1);
  // The wrong one is 53.13 degrees off; the rest 0 (up to the mesh's float precision).
  const double expected = std::acos(0.6) * 180.0 / M_PI / static_cast<double>(g_pool.size() - 1);
  CHECK(from_pool.mean_angle_deg(NormalSource::kAdopted) == Approx(expected).margin(1e-3));
}
