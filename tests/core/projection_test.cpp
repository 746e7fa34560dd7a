#include <catch2/catch.hpp>

#include "core/geometry/projection.hpp"
#include "tests/support/no_allocation.hpp"

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
