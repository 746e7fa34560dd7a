#include <catch2/catch.hpp>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "core/model/primitive_pool.hpp"
#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/oracle/oracle_measurement_source.hpp"
#include "sim_hal/sim_error.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

PrimitivePool<8192> g_pool;
PrimitivePool<16> g_other_pool;

double mean_nees(const OracleMeasurementSource& oracle, const PrimitivePoolView& pool) {
  double sum = 0.0;
  std::size_t n = 0;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    const Eigen::Vector3d* truth = oracle.true_point(i);
    REQUIRE(truth != nullptr);
    const Eigen::Vector3d e = pool[i].X_world - *truth;
    sum += e.dot(pool[i].Sigma_world.ldlt().solve(e));
    ++n;
  }
  return sum / static_cast<double>(n);
}

// Fills g_pool from the pair 30 units out on +x, 4 units apart; returns the first view.
Viewpoint initialize_from_pair(OracleMeasurementSource& oracle) {
  const Viewpoint a = test::looking_at(Eigen::Vector3d(30.0, 0.0, 0.0));
  g_pool.clear();
  UpdateReport report;
  REQUIRE(ok(oracle.initialize(GrayImageView{}, a, GrayImageView{}, test::looking_at(Eigen::Vector3d(30.0, 4.0, 0.0)),
                               g_pool, &report)));
  return a;
}

}  // namespace

TEST_CASE("oracle initialization: depth-elongated covariance and honest errors", "[sim_hal][oracle]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 5.0f, 64)};
  OracleConfig config;
  config.site_count = 4000;
  OracleMeasurementSource oracle(scene, config);
  const Viewpoint a = test::looking_at(Eigen::Vector3d(30.0, 0.0, 0.0));
  const Viewpoint b = test::looking_at(Eigen::Vector3d(30.0, 1.0, 0.0));  // small baseline
  g_pool.clear();
  UpdateReport report;
  REQUIRE(ok(oracle.initialize(GrayImageView{}, a, GrayImageView{}, b, g_pool, &report)));
  REQUIRE(report.spawned > 500);
  CHECK(g_pool.size() == report.spawned);
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    const Primitive& p = g_pool[i];
    REQUIRE(is_spd(p.Sigma_world));
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(p.Sigma_world);
    const Eigen::Vector3d axis = eig.eigenvectors().col(2);
    const Eigen::Vector3d ray = (*oracle.true_point(i) - b.position_world).normalized();
    CHECK(std::abs(axis.dot(ray)) > 0.95);
    CHECK(std::sqrt(eig.eigenvalues()(2) / eig.eigenvalues()(0)) > 10.0);
    CHECK(p.normal_world.cast<double>().dot(oracle.true_point(i)->normalized()) > 0.99);
    CHECK(p.radius > 0.0f);
  }
  // NEES ~ chi-square with 3 dof: mean 3, standard error sqrt(6 / n).
  CHECK(mean_nees(oracle, g_pool) == Approx(3.0).margin(0.35));
}

TEST_CASE("oracle update: EKF updates shrink sigma and augmentation adds new surface and errors stay honest", "[sim_hal][oracle]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 5.0f, 64)};
  OracleConfig config;
  config.site_count = 4000;
  OracleMeasurementSource oracle(scene, config);
  g_pool.clear();
  UpdateReport report;
  REQUIRE(ok(oracle.initialize(GrayImageView{}, test::looking_at(Eigen::Vector3d(30.0, 0.0, 0.0)), GrayImageView{},
                               test::looking_at(Eigen::Vector3d(30.0, 4.0, 0.0)), g_pool, &report)));
  const std::size_t initial = g_pool.size();
  const double sigma_before = GroundTruth::average_sigma(g_pool);
  const std::uint64_t revision = g_pool.revision();

  REQUIRE(ok(oracle.update(GrayImageView{}, test::looking_at(Eigen::Vector3d(21.0, 21.0, 0.0)), g_pool, &report)));
  CHECK(report.predicted_in_view > 100);
  CHECK(report.matched == report.predicted_in_view);
  CHECK(report.updated + report.gated_outliers == report.matched);
  CHECK(report.updated > report.matched * 9 / 10);
  CHECK(report.spawned > 0);
  CHECK(g_pool.size() == initial + report.spawned);
  CHECK(g_pool.revision() > revision);
  CHECK(GroundTruth::average_sigma(g_pool) < sigma_before);
  CHECK(mean_nees(oracle, g_pool) == Approx(3.0).margin(0.5));

  // A pool the oracle did not build is refused, nothing changes.
  CHECK(oracle.update(GrayImageView{}, test::looking_at(Eigen::Vector3d(0.0, 30.0, 0.0)), g_other_pool, &report) ==
        Status::kInvalidArgument);
}

TEST_CASE("oracle track loss: K gated observations in a row erase a primitive and free its site", "[sim_hal][oracle]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 5.0f, 32)};
  OracleConfig config;
  config.site_count = 500;
  config.max_gated_in_a_row = 3;
  OracleMeasurementSource oracle(scene, config);
  const Viewpoint a = initialize_from_pair(oracle);
  UpdateReport report;
  REQUIRE(g_pool.size() > 10);
  const PrimitiveIndex lost = 0;
  const PrimitiveIndex kept = 1;
  REQUIRE(g_pool.is_alive(lost));
  REQUIRE(g_pool.is_alive(kept));
  const Eigen::Vector3d kept_truth = *oracle.true_point(kept);
  // A confident estimate a unit off its true point: every observation fails the gate.
  const Eigen::Vector3d lost_truth = *oracle.true_point(lost);
  const auto spoil = [&](PrimitiveIndex i) {
    g_pool[i].X_world = (i == lost ? lost_truth : kept_truth) + Eigen::Vector3d(0.0, 0.7, 0.7);
    g_pool[i].Sigma_world = Eigen::Matrix3d::Identity() * 1e-4;
  };
  std::uint64_t erased = 0;
  for (int n = 1; n < config.max_gated_in_a_row; ++n) {
    spoil(lost);
    spoil(kept);
    REQUIRE(ok(oracle.update(GrayImageView{}, a, g_pool, &report)));
    erased += report.gated_erased;
    REQUIRE(g_pool.is_alive(lost));
    REQUIRE(g_pool.is_alive(kept));
  }
  // The K-th gated observation erases `lost`; `kept`, back at its true point, is accepted (count restarts).
  spoil(lost);
  g_pool[kept].X_world = kept_truth;
  g_pool[kept].Sigma_world = Eigen::Matrix3d::Identity() * 1e-2;
  REQUIRE(ok(oracle.update(GrayImageView{}, a, g_pool, &report)));
  erased += report.gated_erased;
  CHECK(!g_pool.is_alive(lost));
  CHECK(oracle.true_point(lost) == nullptr);
  REQUIRE(g_pool.is_alive(kept));
  CHECK(g_pool[kept].Sigma_world.trace() < 3e-2);
  for (int n = 1; n < config.max_gated_in_a_row; ++n) {
    spoil(kept);
    REQUIRE(ok(oracle.update(GrayImageView{}, a, g_pool, &report)));
    erased += report.gated_erased;
  }
  CHECK(g_pool.is_alive(kept));
  CHECK(erased >= 1u);
  // The freed site is spawned again from the next pair that sees it with a baseline.
  const std::size_t before = g_pool.size();
  REQUIRE(ok(oracle.update(GrayImageView{}, test::looking_at(Eigen::Vector3d(30.0, -4.0, 0.0)), g_pool, &report)));
  CHECK(report.spawned > 0u);
  CHECK(g_pool.size() == before + report.spawned - report.gated_erased);
  bool respawned = false;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    respawned = respawned || (g_pool.is_alive(i) && oracle.true_point(i) != nullptr && *oracle.true_point(i) == lost_truth);
  }
  CHECK(respawned);

  // Off: never erased.
  config.max_gated_in_a_row = 0;
  OracleMeasurementSource never(scene, config);
  g_pool.clear();
  REQUIRE(ok(never.initialize(GrayImageView{}, a, GrayImageView{}, test::looking_at(Eigen::Vector3d(30.0, 4.0, 0.0)),
                              g_pool, &report)));
  for (int n = 0; n < 4; ++n) {
    spoil(lost);
    REQUIRE(ok(never.update(GrayImageView{}, a, g_pool, &report)));
    CHECK(report.gated_erased == 0u);
  }
  CHECK(g_pool.is_alive(lost));
  config.max_gated_in_a_row = 256;
  CHECK_THROWS_AS(OracleMeasurementSource(scene, config), SimError);
}

TEST_CASE("oracle unconsumed: K gated observations in a row flag a primitive and an accepted update clears it",
          "[sim_hal][oracle]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 5.0f, 32)};
  OracleConfig config;
  config.site_count = 500;
  config.max_gated_in_a_row = 0;  // no track loss: the flag alone
  config.unconsumed_after_gated = 3;
  OracleMeasurementSource oracle(scene, config);
  const Viewpoint a = initialize_from_pair(oracle);
  UpdateReport report;
  const PrimitiveIndex ghost = 0;
  REQUIRE(g_pool.is_alive(ghost));
  const Eigen::Vector3d truth = *oracle.true_point(ghost);
  // A confident estimate off its true point: every observation fails the gate.
  const auto spoil = [&]() {
    g_pool[ghost].X_world = truth + Eigen::Vector3d(0.0, 0.7, 0.7);
    g_pool[ghost].Sigma_world = Eigen::Matrix3d::Identity() * 1e-4;
  };
  const auto flagged = [&]() { return (g_pool[ghost].flags & primitive_flags::kUnconsumed) != 0; };
  spoil();
  for (int n = 1; n < config.unconsumed_after_gated; ++n) {
    REQUIRE(ok(oracle.update(GrayImageView{}, a, g_pool, &report)));
    CHECK_FALSE(flagged());
  }
  REQUIRE(ok(oracle.update(GrayImageView{}, a, g_pool, &report)));
  REQUIRE(g_pool.is_alive(ghost));
  CHECK(flagged());
  // Back at its true point with an honest covariance: accepted, the flag goes.
  g_pool[ghost].X_world = truth;
  g_pool[ghost].Sigma_world = Eigen::Matrix3d::Identity() * 1e-2;
  REQUIRE(ok(oracle.update(GrayImageView{}, a, g_pool, &report)));
  CHECK_FALSE(flagged());

  config.unconsumed_after_gated = 256;
  CHECK_THROWS_AS(OracleMeasurementSource(scene, config), SimError);
}

TEST_CASE("the oracle is deterministic for a seed", "[sim_hal][oracle]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 5.0f, 32)};
  OracleConfig config;
  config.site_count = 500;
  const Viewpoint a = test::looking_at(Eigen::Vector3d(30.0, 0.0, 0.0));
  const Viewpoint b = test::looking_at(Eigen::Vector3d(30.0, 2.0, 0.0));
  std::vector<Eigen::Vector3d> first;
  for (int run = 0; run < 2; ++run) {
    OracleMeasurementSource oracle(scene, config);
    g_pool.clear();
    UpdateReport report;
    REQUIRE(ok(oracle.initialize(GrayImageView{}, a, GrayImageView{}, b, g_pool, &report)));
    REQUIRE(ok(oracle.update(GrayImageView{}, test::looking_at(Eigen::Vector3d(25.0, 10.0, 3.0)), g_pool, &report)));
    for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
      if (run == 0) {
        first.push_back(g_pool[i].X_world);
      } else {
        CHECK(g_pool[i].X_world == first[i]);
      }
    }
  }
}
