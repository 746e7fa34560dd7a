// The plane-induced map in lanes (plane_affine_from_jacobians_batch) against the scalar
// plane_affine_from_jacobians it stands for in the tracker's prediction batch.
#include <array>
#include <limits>
#include <random>

#include <Eigen/Core>
#include <catch2/catch.hpp>

#include "core/frontend/patch_warp.hpp"
#include "core/geometry/projection.hpp"
#include "tests/support/no_allocation.hpp"
#include "tests/support/same_bits.hpp"

using namespace vantage;
using vantage::test::same_bits;

namespace {

template <typename Derived>
bool close(const Eigen::MatrixBase<Derived>& a, const Eigen::MatrixBase<Derived>& b) {
  return (a - b).norm() <= 1e-12 * (1.0 + b.norm());
}

}  // namespace

TEST_CASE("the batch plane map equals plane_affine_from_jacobians primitive by primitive") {
  // Random views and points (projections as the tracker makes them), random unit normals, normals near the
  // x axis (the basis helper's switch at |n_x| = 0.9), with a zero component, non-unit, NaN, and edge-on
  // planes (a target Jacobian with no area along the plane); batches of 0-4. Bit for bit on x86-64 (the
  // AVX lanes do the scalar operations in Eigen's order); elsewhere the batch runs the scalar function
  // one by one, which the compiler may fuse differently where it inlines it, so within 1e-12 there.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  int compared = 0;
  int refused = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    Viewpoint ref_view;
    Viewpoint target_view;
    const double rx = unit(rng);
    const double ry = unit(rng);
    const double rz = unit(rng);
    const double tx = unit(rng);
    const double ty = unit(rng);
    const double tz = unit(rng);
    REQUIRE(ok(look_at(Eigen::Vector3d(40.0 * rx, 40.0 * ry, 10.0 * rz + 40.0), Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::UnitY(), &ref_view)));
    REQUIRE(ok(look_at(Eigen::Vector3d(40.0 * tx, 40.0 * ty, 10.0 * tz + 40.0), Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::UnitY(), &target_view)));
    const std::int32_t count = trial % (kPlaneAffineBatchSize + 1);
    std::array<Eigen::Matrix<double, 2, 3>, kPlaneAffineBatchSize> H_ref;
    std::array<Eigen::Matrix<double, 2, 3>, kPlaneAffineBatchSize> H_target;
    std::array<Eigen::Vector3f, kPlaneAffineBatchSize> normals;
    std::array<const Eigen::Vector3f*, kPlaneAffineBatchSize> normal_pointers{};
    for (std::int32_t i = 0; i < kPlaneAffineBatchSize; ++i) {
      const double x = 5.0 * unit(rng);
      const double y = 5.0 * unit(rng);
      const double z = 5.0 * unit(rng);
      const Eigen::Vector3d X(x, y, z);
      Eigen::Vector2d uv;
      REQUIRE(ok(project_with_jacobian(X, ref_view, k, &uv, &H_ref[i])));
      REQUIRE(ok(project_with_jacobian(X, target_view, k, &uv, &H_target[i])));
      const double n0 = unit(rng);
      const double n1 = unit(rng);
      const double n2 = unit(rng);
      Eigen::Vector3d n(n0, n1, n2);
      const int kind = (trial + 3 * i) % 23;
      if (kind == 1) n = Eigen::Vector3d(0.9 + 0.01 * n0, 0.3 * n1, 0.3 * n2);  // about the helper's switch
      if (kind == 2) n.x() = 0.0;
      if (kind == 3) n = Eigen::Vector3d::UnitX();
      normals[i] = n.normalized().cast<float>();
      if (kind == 4) normals[i] *= 1.01f;  // not unit length
      if (kind == 5) normals[i].y() = std::numeric_limits<float>::quiet_NaN();
      if (kind == 6) H_target[i].row(1) = H_target[i].row(0);  // edge-on: the plane's image has no area
      normal_pointers[i] = &normals[i];
    }
    std::array<Eigen::Matrix2d, kPlaneAffineBatchSize> A;
    std::array<std::array<Eigen::Matrix2d, 2>, kPlaneAffineBatchSize> dA;
    std::array<Status, kPlaneAffineBatchSize> status;
    status.fill(Status::kNotFound);  // untouched past count
    REQUIRE_NO_ALLOCATION(plane_affine_from_jacobians_batch(H_ref.data(), H_target.data(), normal_pointers.data(),
                                                            count, A.data(), dA.data(), status.data()));
    for (std::int32_t i = 0; i < kPlaneAffineBatchSize; ++i) {
      if (i >= count) {
        CHECK(status[i] == Status::kNotFound);
        continue;
      }
      Eigen::Matrix2d A_one;
      std::array<Eigen::Matrix2d, 2> dA_one;
      const Status one = plane_affine_from_jacobians(H_ref[i], H_target[i], normals[i], &A_one, &dA_one);
      REQUIRE(status[i] == one);
      if (!ok(one)) {
        ++refused;
        continue;
      }
      ++compared;
#if defined(__x86_64__)
      CHECK(same_bits(A[i], A_one));
      CHECK(same_bits(dA[i][0], dA_one[0]));
      CHECK(same_bits(dA[i][1], dA_one[1]));
#else
      CHECK(close(A[i], A_one));
      CHECK(close(dA[i][0], dA_one[0]));
      CHECK(close(dA[i][1], dA_one[1]));
#endif
    }
  }
  CHECK(compared > 5000);
  CHECK(refused > 500);
  // Without dA, A alone.
  const Eigen::Matrix<double, 2, 3> H = (Eigen::Matrix<double, 2, 3>() << 500.0, 0.0, 3.0, 0.0, 500.0, -2.0).finished();
  const Eigen::Matrix<double, 2, 3> H_other = (Eigen::Matrix<double, 2, 3>() << 450.0, 80.0, 3.0, -20.0, 480.0, 9.0).finished();
  const Eigen::Vector3f n = Eigen::Vector3f(0.1f, -0.2f, 1.0f).normalized();
  const Eigen::Vector3f* n_pointer = &n;
  Eigen::Matrix2d A_batch;
  Status status = Status::kNotFound;
  plane_affine_from_jacobians_batch(&H_other, &H, &n_pointer, 1, &A_batch, nullptr, &status);
  Eigen::Matrix2d A_one;
  REQUIRE(ok(plane_affine_from_jacobians(H_other, H, n, &A_one, nullptr)));
  REQUIRE(ok(status));
  CHECK(close(A_batch, A_one));
}
