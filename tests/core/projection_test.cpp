#include <catch2/catch.hpp>

#include <array>
#include <limits>
#include <random>

#include "core/geometry/projection.hpp"
#include "tests/support/no_allocation.hpp"
#include "tests/support/same_bits.hpp"

using namespace vantage;

namespace {

Viewpoint camera_at(const Eigen::Vector3d& position) {
  Viewpoint view;
  REQUIRE(ok(look_at(position, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)));
  return view;
}

}  // namespace

TEST_CASE("look_at builds a rotation whose optical axis points at the target") {
  const Viewpoint view = camera_at({40.0, 10.0, 5.0});
  REQUIRE(ok(view.validate()));
  const Eigen::Vector3d axis = view.R_world_cam.col(2);
  CHECK((axis - (-view.position_world.normalized())).norm() < 1e-12);
  // image "down" (camera y) has a negative world z component: up is up in the image
  CHECK(view.R_world_cam.col(1).z() < 0.0);
}

TEST_CASE("the target projects to the principal point") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  Eigen::Vector2d uv;
  REQUIRE(ok(project(Eigen::Vector3d::Zero(), camera_at({40.0, 0.0, 3.0}), k, &uv)));
  CHECK(uv.x() == Approx(k.cx_px).margin(1e-9));
  CHECK(uv.y() == Approx(k.cy_px).margin(1e-9));
}

TEST_CASE("a point behind the camera is refused") {
  Eigen::Vector2d uv;
  CHECK(project({80.0, 0.0, 0.0}, camera_at({40.0, 0.0, 0.0}), PinholeIntrinsics::default_vga(), &uv) ==
        Status::kBehindCamera);
}

TEST_CASE("the analytic Jacobian matches central finite differences, with distortion") {
  PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  k.k1 = -0.21;
  k.k2 = 0.05;
  const Viewpoint view = camera_at({30.0, -20.0, 8.0});
  const Eigen::Vector3d points[] = {{0.0, 0.0, 0.0}, {3.0, -2.0, 4.0}, {-5.0, 6.0, -1.0}, {7.0, 7.0, 7.0}};
  for (const Eigen::Vector3d& X : points) {
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 3> H;
    REQUIRE(ok(project_with_jacobian(X, view, k, &uv, &H)));
    for (int axis = 0; axis < 3; ++axis) {
      const double step = 1e-5;
      Eigen::Vector2d plus, minus;
      REQUIRE(ok(project(X + step * Eigen::Vector3d::Unit(axis), view, k, &plus)));
      REQUIRE(ok(project(X - step * Eigen::Vector3d::Unit(axis), view, k, &minus)));
      const Eigen::Vector2d numeric = (plus - minus) / (2.0 * step);
      CHECK((numeric - H.col(axis)).norm() < 1e-5 * (1.0 + H.col(axis).norm()));
    }
  }
}

TEST_CASE("back-projection inverts projection") {
  PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  k.k1 = -0.1;
  const Viewpoint view = camera_at({0.0, 40.0, 2.0});
  const Eigen::Vector3d X(2.0, 1.0, 3.0);
  Eigen::Vector2d uv;
  REQUIRE(ok(project(X, view, k, &uv)));
  const Eigen::Vector3d ray = back_project_ray_world(uv, view, k);
  const Eigen::Vector3d expected = (X - view.position_world).normalized();
  CHECK((ray - expected).norm() < 1e-9);
}

TEST_CASE("intrinsics validation names impossible values") {
  PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  CHECK(ok(k.validate()));
  k.fx_px = -1.0;
  CHECK(k.validate() == Status::kInvalidArgument);
  k = PinholeIntrinsics::default_vga();
  k.cy_px = std::nan("");
  CHECK(k.validate() == Status::kNonFiniteInput);
  k = PinholeIntrinsics::default_vga();
  k.width_px = 0;
  CHECK(k.validate() == Status::kInvalidArgument);
}

TEST_CASE("projection allocates nothing") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  const Viewpoint view = camera_at({40.0, 0.0, 3.0});
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> H;
  REQUIRE_NO_ALLOCATION(REQUIRE(ok(project_with_jacobian({1.0, 2.0, 3.0}, view, k, &uv, &H))));
}

namespace {

// (sx u1, sy u2, sz u3) from three draws in this order (one per statement: a call's arguments are
// evaluated in an unspecified order, which differs between x86-64 and aarch64 builds).
template <typename Draw>
Eigen::Vector3d drawn_vector(Draw&& draw, double sx, double sy, double sz) {
  const double x = sx * draw();
  const double y = sy * draw();
  const double z = sz * draw();
  return Eigen::Vector3d(x, y, z);
}

}  // namespace

TEST_CASE("the batch projection equals project_with_jacobian point by point") {
  // Random views, points in front of, beside and behind the camera, NaN; with and without distortion;
  // batches of 0-4. Bit for bit on x86-64 (the AVX lanes do the scalar operations in Eigen's order); on
  // other targets the compiler may fuse a * b + c differently in the two, so within 1e-12 relative there.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  int compared = 0;
  int behind = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    k.k1 = trial % 2 == 0 ? 0.0 : 0.05 * unit(rng);
    k.k2 = trial % 2 == 0 ? 0.0 : 0.01 * unit(rng);
    Viewpoint view;
    auto draw = [&] { return unit(rng); };
    const Eigen::Vector3d position = drawn_vector(draw, 40.0, 40.0, 10.0);
    const Eigen::Vector3d target = drawn_vector(draw, 1.0, 1.0, 1.0);
    REQUIRE(ok(look_at(position, target, Eigen::Vector3d::UnitZ(), &view)));
    const std::int32_t count = trial % (kProjectionBatchSize + 1);
    std::array<Eigen::Vector3d, kProjectionBatchSize> points;
    std::array<const Eigen::Vector3d*, kProjectionBatchSize> pointers{};
    for (std::int32_t i = 0; i < kProjectionBatchSize; ++i) {
      const double depth = (trial + i) % 7 == 0 ? -5.0 * (1.0 + unit(rng)) : 20.0 + 30.0 * (1.0 + unit(rng));
      const double lateral_x = 15.0 * unit(rng);
      const double lateral_y = 15.0 * unit(rng);
      points[i] = position + view.R_world_cam * Eigen::Vector3d(lateral_x, lateral_y, depth);
      if ((trial + i) % 97 == 0) points[i].y() = std::numeric_limits<double>::quiet_NaN();
      pointers[i] = &points[i];
    }
    std::array<Eigen::Vector2d, kProjectionBatchSize> uv;
    std::array<Eigen::Matrix<double, 2, 3>, kProjectionBatchSize> H;
    std::array<Status, kProjectionBatchSize> status;
    status.fill(Status::kInvalidArgument);  // untouched past count
    REQUIRE_NO_ALLOCATION(project_with_jacobian_batch(pointers.data(), count, view, k, uv.data(), H.data(), status.data()));
    for (std::int32_t i = 0; i < kProjectionBatchSize; ++i) {
      if (i >= count) {
        CHECK(status[i] == Status::kInvalidArgument);
        continue;
      }
      Eigen::Vector2d uv_one;
      Eigen::Matrix<double, 2, 3> H_one;
      const Status one = project_with_jacobian(points[i], view, k, &uv_one, &H_one);
      REQUIRE(status[i] == one);
      if (!ok(one)) {
        ++behind;
        continue;
      }
      ++compared;
#if defined(__x86_64__)
      CHECK(test::same_bits(uv[i], uv_one));
      CHECK(test::same_bits(H[i], H_one));
#else
      CHECK((uv[i] - uv_one).norm() <= 1e-12 * uv_one.norm());
      CHECK((H[i] - H_one).norm() <= 1e-12 * H_one.norm());
#endif
    }
  }
  CHECK(compared > 4000);
  CHECK(behind > 500);
}
