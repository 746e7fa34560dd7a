#include <cmath>

#include <catch2/catch.hpp>

#include "core/criterion/depth_buffer.hpp"
#include "tests/core/criterion_fixtures.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::view_from;

namespace {

DepthBuffer<160, 120> g_buffer;

// Splats a square wall of discs in the plane x = x_wall, facing +x, spacing 0.4 and radius 0.3.
void splat_wall(DepthBufferView& buffer, float x_wall, float half_size) {
  for (float y = -half_size; y <= half_size; y += 0.4f) {
    for (float z = -half_size; z <= half_size; z += 0.4f) {
      buffer.splat(Eigen::Vector3f(x_wall, y, z), Eigen::Vector3f::UnitX(), 0.3f);
    }
  }
}

}  // namespace

TEST_CASE("a disc behind a wall of discs is not visible, without the wall it is") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  const Eigen::Vector3f X = Eigen::Vector3f::Zero();
  const Eigen::Vector3f n = Eigen::Vector3f::UnitX();
  g_buffer.splat(X, n, 0.1f);
  CHECK(g_buffer.is_visible(X, n, 0.1f));
  splat_wall(g_buffer, 5.0f, 3.0f);
  CHECK_FALSE(g_buffer.is_visible(X, n, 0.1f));
  // A wall closer than the tolerance (2 radii) behind... in front: the disc still counts as the surface.
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  g_buffer.splat(Eigen::Vector3f(0.15f, 0.0f, 0.0f), n, 0.1f);
  CHECK(g_buffer.is_visible(X, n, 0.1f));
}

TEST_CASE("neighbouring discs of one tilted surface do not occlude each other") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  // A plane through the origin tilted 70 degrees away from the camera, densely sampled.
  const float tilt = 70.0f * 3.14159265f / 180.0f;
  const Eigen::Vector3f n(std::cos(tilt), std::sin(tilt), 0.0f);
  const Eigen::Vector3f along(-std::sin(tilt), std::cos(tilt), 0.0f);
  for (int i = -20; i <= 20; ++i) {
    for (int j = -20; j <= 20; ++j) {
      g_buffer.splat(along * (0.1f * i) + Eigen::Vector3f::UnitZ() * (0.1f * j), n, 0.07f);
    }
  }
  int visible = 0;
  int total = 0;
  for (int i = -18; i <= 18; ++i) {
    for (int j = -18; j <= 18; ++j) {
      ++total;
      visible += g_buffer.is_visible(along * (0.1f * i) + Eigen::Vector3f::UnitZ() * (0.1f * j), n, 0.07f) ? 1 : 0;
    }
  }
  CHECK(visible == total);
}

TEST_CASE("back-facing, behind-camera and out-of-image discs are not visible") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f::Zero(), -Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f(30.0f, 0.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f(0.0f, 40.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.splat(Eigen::Vector3f(30.0f, 0.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
}

TEST_CASE("a large disc covers its footprint, a small one only its centre pixel") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  const BufferCamera& cam = g_buffer.camera();
  CHECK(cam.width_px == 160);
  CHECK(cam.fx_px == Approx(k.fx_px / 4.0));
  g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 1.0f);  // ~7 buffer px radius at 20
  const float radius_px = static_cast<float>(1.0 * cam.fx_px / 20.0);
  const std::int32_t cu = static_cast<std::int32_t>(std::lround(cam.cx_px));
  const std::int32_t cv = static_cast<std::int32_t>(std::lround(cam.cy_px));
  CHECK(g_buffer.inverse_depth_at(cu, cv) == Approx(1.0f / 20.0f).epsilon(1e-3));
  CHECK(g_buffer.inverse_depth_at(cu + static_cast<int>(radius_px) - 1, cv) > 0.0f);
  CHECK(g_buffer.inverse_depth_at(cu + static_cast<int>(radius_px) + 2, cv) == 0.0f);
  g_buffer.clear();
  g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.01f);
  int written = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) written += g_buffer.inverse_depth_at(x, y) > 0.0f ? 1 : 0;
  }
  CHECK(written == 1);
}

TEST_CASE("bad pose or intrinsics leave the depth buffer unchanged") {
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint good = view_from({20.0, 0.0, 0.0});
  REQUIRE(ok(g_buffer.configure(good, k)));
  g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f);
  const BufferCamera before = g_buffer.camera();
  Viewpoint nan_pose = good;
  nan_pose.position_world.x() = std::nan("");
  CHECK(g_buffer.configure(nan_pose, k) == Status::kNonFiniteInput);
  Viewpoint not_rotation = good;
  not_rotation.R_world_cam *= 2.0;
  CHECK(g_buffer.configure(not_rotation, k) == Status::kInvalidArgument);
  PinholeIntrinsics inf_k = k;
  inf_k.fx_px = INFINITY;
  CHECK(g_buffer.configure(good, inf_k) == Status::kNonFiniteInput);
  PinholeIntrinsics empty = k;
  empty.width_px = 0;
  CHECK(g_buffer.configure(good, empty) == Status::kInvalidImage);
  CHECK(g_buffer.camera().fx_px == before.fx_px);
  CHECK(g_buffer.is_visible(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f));
  CHECK(g_buffer.set_tolerance_radii(-1.0f) == Status::kInvalidArgument);
  CHECK(g_buffer.set_tolerance_radii(std::nanf("")) == Status::kNonFiniteInput);
  CHECK(g_buffer.tolerance_radii() == kDefaultToleranceRadii);
}

TEST_CASE("depth buffer entry points do not allocate") {
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint view = view_from({20.0, 0.0, 0.0});
  bool visible = false;
  REQUIRE_NO_ALLOCATION(Status s = g_buffer.configure(view, k); (void)s; g_buffer.clear();
                        g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f);
                        visible = g_buffer.is_visible(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f));
  CHECK(visible);
}
