#include <cmath>

#include <Eigen/Dense>
#include <catch2/catch.hpp>

#include "core/frontend/patch_warp.hpp"
#include "core/frontend/surface_fit.hpp"
#include "core/frontend/triangulation.hpp"
#include "core/geometry/projection.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

TEST_CASE("two-view triangulation recovers the point and its information-form covariance") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  TwoViewObservation obs;
  obs.view_a = vantage::test::looking_at_origin({40.0, 0.0, 0.0});
  obs.view_b = vantage::test::looking_at_origin({39.0, 8.0, 3.0});
  obs.R_a_px2 = Eigen::Matrix2d::Identity() * 0.01;
  obs.R_b_px2 << 0.09, 0.02, 0.02, 0.16;
  const Eigen::Vector3d truth(1.5, -2.0, 3.0);
  REQUIRE(ok(project(truth, obs.view_a, k, &obs.uv_a_px)));
  REQUIRE(ok(project(truth, obs.view_b, k, &obs.uv_b_px)));
  Eigen::Vector3d X;
  Eigen::Matrix3d Sigma;
  Status status = Status::kOk;
  REQUIRE_NO_ALLOCATION(status = triangulate_two_views(obs, k, &X, &Sigma));
  REQUIRE(ok(status));
  CHECK((X - truth).norm() < 1e-9);
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> Ha;
  Eigen::Matrix<double, 2, 3> Hb;
  REQUIRE(ok(project_with_jacobian(truth, obs.view_a, k, &uv, &Ha)));
  REQUIRE(ok(project_with_jacobian(truth, obs.view_b, k, &uv, &Hb)));
  const Eigen::Matrix3d information =
      Ha.transpose() * obs.R_a_px2.inverse() * Ha + Hb.transpose() * obs.R_b_px2.inverse() * Hb;
  CHECK((Sigma - information.inverse()).norm() < 1e-9 * information.inverse().norm());
}

TEST_CASE("triangulation refuses parallel rays, non-finite input and points behind a camera") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  TwoViewObservation obs;
  obs.view_a = vantage::test::looking_at_origin({40.0, 0.0, 0.0});
  obs.view_b = obs.view_a;
  obs.view_b.position_world.x() = 30.0;  // same axis: every ray through the centre is shared
  obs.uv_a_px = Eigen::Vector2d(k.cx_px, k.cy_px);
  obs.uv_b_px = obs.uv_a_px;
  Eigen::Vector3d X = Eigen::Vector3d::Constant(7.0);
  Eigen::Matrix3d Sigma = Eigen::Matrix3d::Identity();
  CHECK(triangulate_two_views(obs, k, &X, &Sigma) == Status::kInvalidArgument);
  obs.uv_b_px.x() = std::nan("");
  CHECK(triangulate_two_views(obs, k, &X, &Sigma) == Status::kNonFiniteInput);
  CHECK(X == Eigen::Vector3d::Constant(7.0));
  // Two cameras side by side looking the same way, rays diverging: their lines meet behind both.
  obs.view_b = obs.view_a;
  obs.view_b.position_world = Eigen::Vector3d(40.0, 5.0, 0.0);
  obs.uv_a_px = Eigen::Vector2d(k.cx_px, k.cy_px);
  obs.uv_b_px = Eigen::Vector2d(k.cx_px + 200.0, k.cy_px);
  if (back_project_ray_world(obs.uv_b_px, obs.view_b, k).y() < 0.0) obs.uv_b_px.x() = k.cx_px - 200.0;
  CHECK(triangulate_two_views(obs, k, &X, &Sigma) == Status::kBehindCamera);
}

TEST_CASE("the plane-induced affine map matches the homography over a patch") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  const Viewpoint reference = vantage::test::looking_at_origin({40.0, 0.0, 0.0});
  const Viewpoint target = vantage::test::looking_at_origin({28.0, 26.0, 10.0});
  const Eigen::Vector3d X(0.0, 1.0, -2.0);
  const Eigen::Vector3f n(1.0f, 0.0f, 0.0f);  // the plane x = 0
  Eigen::Matrix2d A;
  REQUIRE(ok(plane_affine(X, n, reference, target, k, &A)));
  Eigen::Vector2d uv_ref0;
  Eigen::Vector2d uv_target0;
  REQUIRE(ok(project(X, reference, k, &uv_ref0)));
  REQUIRE(ok(project(X, target, k, &uv_target0)));
  vantage::test::TexturedPlane plane;
  for (const Eigen::Vector2d offset : {Eigen::Vector2d(3, 0), Eigen::Vector2d(0, -3), Eigen::Vector2d(-3, 3)}) {
    Eigen::Vector3d on_plane;
    REQUIRE(plane.intersect(uv_target0 + offset, target, k, &on_plane));
    Eigen::Vector2d uv_ref;
    REQUIRE(ok(project(on_plane, reference, k, &uv_ref)));
    // First order: the second-order terms stay a few hundredths of a pixel at 3 px for a 45 degree change.
    CHECK((uv_ref - uv_ref0 - A * offset).norm() < 0.05);
  }
  Eigen::Matrix2d identity;
  REQUIRE(ok(plane_affine(X, n, reference, reference, k, &identity)));
  CHECK((identity - Eigen::Matrix2d::Identity()).norm() < 1e-9);
  CHECK(plane_affine(X, Eigen::Vector3f(0.0f, 0.0f, 0.0f), reference, target, k, &A) == Status::kInvalidArgument);
}

TEST_CASE("a warped template equals the patch for the identity and masks what falls outside") {
  std::array<std::uint8_t, kPatchPixels> patch{};
  for (int i = 0; i < kPatchPixels; ++i) patch[i] = static_cast<std::uint8_t>((i * 53) % 200 + 20);
  NccTemplate plain;
  make_template(patch, &plain);
  NccTemplate warped;
  warp_patch_template(patch, Eigen::Matrix2d::Identity(), &warped);
  REQUIRE(warped.valid_count == kPatchPixels);
  for (int i = 0; i < kPatchPixels; ++i) CHECK(warped.values[i] == Approx(plain.values[i]).margin(1e-4));
  // Twice the scale: only offsets within half the patch radius stay inside the stored patch.
  warp_patch_template(patch, Eigen::Matrix2d::Identity() * 2.0, &warped);
  const int inside = 2 * (kPatchRadius / 2) + 1;
  CHECK(warped.valid_count == inside * inside);
}

TEST_CASE("a plane fit gives the plane's normal toward the camera, and refuses a scatter") {
  const Eigen::Vector3d centre(0.0, 0.0, 0.0);
  Eigen::Vector3d neighbours[8];
  int i = 0;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      if (dx == 0 && dy == 0) continue;
      neighbours[i++] = Eigen::Vector3d(0.02 * ((dx + dy) % 2), 0.3 * dx, 0.3 * dy);  // almost x = 0
    }
  }
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  REQUIRE(fit_plane_normal(centre, Span<const Eigen::Vector3d>(neighbours, 8), Eigen::Vector3d(-40, 0, 0),
                           PlaneFitConfig{}, &normal));
  CHECK(normal.x() < -0.99f);  // toward the camera at -x
  for (int j = 0; j < 8; ++j) neighbours[j].x() = (j % 3 - 1) * 0.3;  // depth scatter as large as the spacing
  CHECK_FALSE(fit_plane_normal(centre, Span<const Eigen::Vector3d>(neighbours, 8), Eigen::Vector3d(-40, 0, 0),
                               PlaneFitConfig{}, &normal));
  CHECK(footprint_radius(4.0, 40.0, 579.0, 1.0) == Approx(0.5 * std::sqrt(2.0) * 4.0 * 40.0 / 579.0));
  CHECK(footprint_radius(4.0, 40.0, 579.0, 0.0) == Approx(footprint_radius(4.0, 40.0, 579.0, 1.0) / std::cos(75.0 * M_PI / 180.0)));
}
