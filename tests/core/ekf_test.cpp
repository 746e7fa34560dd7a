#include <random>

#include <Eigen/Eigenvalues>
#include <catch2/catch.hpp>

#include "core/estimation/ekf.hpp"
#include "core/geometry/projection.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

Eigen::Matrix3d random_spd(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix3d A;
  for (int i = 0; i < 9; ++i) A(i / 3, i % 3) = n(rng);
  return A * A.transpose() + 1e-3 * Eigen::Matrix3d::Identity();
}

}  // namespace

TEST_CASE("Lemma 1: a Joseph-form update never increases an eigenvalue of Sigma") {
  std::mt19937 rng(1234);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 5000; ++trial) {
    const Eigen::Matrix3d Sigma = random_spd(rng);
    Eigen::Matrix<double, 2, 3> H;
    for (int i = 0; i < 6; ++i) H(i / 3, i % 3) = 50.0 * n(rng);
    Eigen::Matrix2d B;
    for (int i = 0; i < 4; ++i) B(i / 2, i % 2) = n(rng);
    const Eigen::Matrix2d R = B * B.transpose() + 1e-2 * Eigen::Matrix2d::Identity();
    const Eigen::Matrix2d S = H * Sigma * H.transpose() + R;
    const Eigen::Matrix<double, 3, 2> K = Sigma * H.transpose() * S.inverse();
    const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
    Eigen::Matrix3d updated = I_KH * Sigma * I_KH.transpose() + K * R * K.transpose();
    updated = 0.5 * (updated + updated.transpose());
    // Loewner order: Sigma - updated is PSD, so every eigenvalue (sorted) is non-increasing.
    const Eigen::Vector3d before = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(Sigma).eigenvalues();
    const Eigen::Vector3d after = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(updated).eigenvalues();
    const double tol = 1e-9 * before.maxCoeff();
    for (int i = 0; i < 3; ++i) REQUIRE(after(i) <= before(i) + tol);
    const double min_difference =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(Sigma - updated).eigenvalues().minCoeff();
    REQUIRE(min_difference >= -tol);
  }
}

TEST_CASE("an update from a real view pulls the estimate toward the truth and shrinks Sigma") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  Viewpoint view;
  REQUIRE(ok(look_at({40.0, 0.0, 0.0}, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)));
  const Eigen::Vector3d truth(0.0, 0.3, -0.2);
  Primitive p;
  p.X_world = truth + Eigen::Vector3d(0.5, 0.1, 0.05);
  p.Sigma_world = Eigen::Matrix3d::Identity() * 0.1;
  Eigen::Vector2d observed;
  REQUIRE(ok(project(truth, view, k, &observed)));
  EkfConfig config;
  config.gate_chi2 = 1e9;
  EkfStats stats;
  const double lateral_error_before = (p.X_world - truth).tail<2>().norm();
  REQUIRE(ok(ekf_update(p, observed, view, k, config, &stats)));
  CHECK((p.X_world - truth).tail<2>().norm() < lateral_error_before);
  CHECK(p.Sigma_world.determinant() < 0.1 * 0.1 * 0.1);
  CHECK(stats.accepted == 1);
  CHECK(p.observation_count == 1);
}

TEST_CASE("the Mahalanobis gate rejects and counts an outlier, leaving the primitive unchanged") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  Viewpoint view;
  REQUIRE(ok(look_at({40.0, 0.0, 0.0}, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)));
  Primitive p;
  p.Sigma_world = Eigen::Matrix3d::Identity() * 1e-4;
  const Primitive before = p;
  EkfStats stats;
  Eigen::Vector2d uv;
  REQUIRE(ok(project(p.X_world, view, k, &uv)));
  CHECK(ekf_update(p, uv + Eigen::Vector2d(40.0, 0.0), view, k, EkfConfig{}, &stats) == Status::kGatedOutlier);
  CHECK(stats.gated_outliers == 1);
  CHECK(p.X_world == before.X_world);
  CHECK(p.Sigma_world == before.Sigma_world);
}

TEST_CASE("bad EKF inputs are refused by name and change nothing") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  Viewpoint view;
  REQUIRE(ok(look_at({40.0, 0.0, 0.0}, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)));
  Primitive p;
  const Primitive before = p;
  EkfStats stats;
  CHECK(ekf_update(p, Eigen::Vector2d(std::nan(""), 1.0), view, k, EkfConfig{}, &stats) == Status::kNonFiniteInput);
  Viewpoint bad_view = view;
  bad_view.position_world.x() = INFINITY;
  CHECK(ekf_update(p, Eigen::Vector2d(1.0, 1.0), bad_view, k, EkfConfig{}, &stats) == Status::kNonFiniteInput);
  Primitive not_spd = p;
  not_spd.Sigma_world(0, 0) = -1.0;
  CHECK(ekf_update(not_spd, Eigen::Vector2d(1.0, 1.0), view, k, EkfConfig{}, &stats) == Status::kNotSpd);
  CHECK(stats.rejected_inputs == 3);
  CHECK(p.X_world == before.X_world);
  CHECK(p.Sigma_world == before.Sigma_world);
}

TEST_CASE("predict_covariance equals the covariance of a real update and leaves P untouched") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  Viewpoint view;
  REQUIRE(ok(look_at({0.0, 40.0, 2.0}, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)));
  Primitive p;
  p.Sigma_world << 0.2, 0.05, 0.0, 0.05, 0.1, 0.01, 0.0, 0.01, 0.3;
  const Primitive before = p;
  Eigen::Matrix3d predicted;
  REQUIRE_NO_ALLOCATION(REQUIRE(ok(predict_covariance(p, view, k, EkfConfig{}.R_px2, &predicted))));
  CHECK(p.Sigma_world == before.Sigma_world);
  Eigen::Vector2d uv;
  REQUIRE(ok(project(p.X_world, view, k, &uv)));
  REQUIRE(ok(ekf_update(p, uv, view, k, EkfConfig{}, nullptr)));
  CHECK((p.Sigma_world - predicted).norm() < 1e-12);
}
