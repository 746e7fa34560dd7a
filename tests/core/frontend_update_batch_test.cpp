#include <cmath>
#include <cstring>
#include <random>

#include <Eigen/Dense>
#include <catch2/catch.hpp>

#include "core/frontend/iterated_update.hpp"
#include "core/geometry/projection.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

// The same bits (== would call -0.0 and 0.0 equal and NaN unequal).
template <typename Derived>
bool same_bits(const Eigen::MatrixBase<Derived>& a, const Eigen::MatrixBase<Derived>& b) {
  return std::memcmp(a.derived().data(), b.derived().data(), sizeof(double) * a.size()) == 0;
}

// One update's inputs. Kinds: 0 a tracked primitive with a small prior, 1 a new one long along the view's
// ray, 2 a prior wide across the ray that the observation pins (the short form cancels: the Joseph form),
// 3 an observation far off (gated), 4 a non-finite observation, 5 a prior that is not positive definite.
struct Case {
  Primitive primitive;
  CommonObservationError common;
  Eigen::Vector2d observation_px = Eigen::Vector2d::Zero();
  EkfConfig config;
  ProjectionAtPrior at_prior;
};

Case make_case(int kind, const Viewpoint& view, const PinholeIntrinsics& k, std::mt19937& rng) {
  std::normal_distribution<double> z(0.0, 1.0);
  Case c;
  c.primitive.X_world = Eigen::Vector3d{z(rng), z(rng), z(rng)};
  const Eigen::Matrix3d A = 0.02 * Eigen::Matrix3d::Random();
  c.primitive.Sigma_world = A * A.transpose() + 1e-4 * Eigen::Matrix3d::Identity();
  const Eigen::Vector3d ray = (c.primitive.X_world - view.position_world).normalized();
  if (kind == 1) c.primitive.Sigma_world += 4.0 * ray * ray.transpose();
  if (kind == 2) c.primitive.Sigma_world += 1e4 * Eigen::Vector3d(0.0, 1.0, 0.0) * Eigen::Vector3d(0.0, 1.0, 0.0).transpose();
  if (kind == 5) c.primitive.Sigma_world(0, 0) = -1.0;
  c.config.R_px2 << 0.012 + 0.01 * std::abs(z(rng)), 0.001, 0.001, 0.015;
  if (kind == 2) c.config.R_px2 = 1e-4 * Eigen::Matrix2d::Identity();
  c.common.B << 1.0 + 0.05 * z(rng), 0.02 * z(rng), 0.02 * z(rng), 1.0 + 0.05 * z(rng);
  c.common.covariance_px2 << 0.004, 0.0005, 0.0005, 0.005;
  REQUIRE(ok(project_with_jacobian(c.primitive.X_world, view, k, &c.at_prior.predicted_px, &c.at_prior.H)));
  c.common.cross_covariance = 0.3 * c.primitive.Sigma_world * c.at_prior.H.transpose() * c.config.R_px2.inverse() *
                              c.common.covariance_px2;
  if (kind == 2 || kind == 5) c.common.cross_covariance.setZero();  // a consistent C for these is not the point
  // A part kept apart (FrontEndConfig::view_correlated_error_scale: the patch noise within c + s).
  c.common.has_part = (kind % 2) == 0;  // lanes with and without a part in the same batch
  c.common.part_covariance_px2 = 0.4 * c.common.covariance_px2;
  c.common.part_cross_covariance = 0.6 * c.common.cross_covariance;
  const double off_px = kind == 1 ? 3.0 : kind == 3 ? 40.0 : 0.2;
  c.observation_px = c.at_prior.predicted_px + off_px * Eigen::Vector2d{z(rng), z(rng)};
  if (kind == 4) c.observation_px.x() = std::nan("");
  return c;
}

}  // namespace

TEST_CASE("the batched consider update gives the scalar update's statuses, estimates and counts bit for bit") {
  const PinholeIntrinsics k = vantage::test::small_intrinsics();
  const Viewpoint view = vantage::test::looking_at_origin({30.0, 4.0, 2.0});
  std::mt19937 rng(29);
  std::uniform_int_distribution<int> kind_of(0, 9);
  int joseph = 0;  // accepted updates whose short form the kept-fraction check refuses
  int same = 0;
  int compared = 0;
  EkfStats scalar_stats;
  EkfStats batch_stats;
  for (int trial = 0; trial < 600; ++trial) {
    const int count = 1 + trial % kUpdateBatchSize;  // full batches and the tails of 1 to 3
    Case scalar[kUpdateBatchSize];
    Case batch[kUpdateBatchSize];
    double prior_lateral[kUpdateBatchSize] = {};
    for (int l = 0; l < count; ++l) {
      const int draw = kind_of(rng);  // mostly tracked primitives, as in a frame
      const int kind = draw < 5 ? 0 : draw - 4;
      scalar[l] = make_case(kind, view, k, rng);
      batch[l] = scalar[l];
      prior_lateral[l] = scalar[l].primitive.Sigma_world(1, 1);
    }
    Status expected[kUpdateBatchSize];
    for (int l = 0; l < count; ++l) {
      Case& c = scalar[l];
      expected[l] = iterated_consider_update(c.primitive, &c.common, c.observation_px, view, k, c.config, 5, c.at_prior,
                                             &scalar_stats);
    }
    ConsiderUpdateRequest requests[kUpdateBatchSize];
    for (int l = 0; l < count; ++l) {
      requests[l].primitive = &batch[l].primitive;
      requests[l].common = &batch[l].common;
      requests[l].observation_px = batch[l].observation_px;
      requests[l].config = batch[l].config;
      requests[l].at_prior = batch[l].at_prior;
    }
    Status got[kUpdateBatchSize];
    REQUIRE_NO_ALLOCATION(iterated_consider_update_batch(requests, count, view, k, 5, &batch_stats, got));
    for (int l = 0; l < count; ++l) {
      REQUIRE(got[l] == expected[l]);
      ++compared;
      if (ok(got[l]) && batch[l].primitive.Sigma_world(1, 1) < 1e-6 * prior_lateral[l]) ++joseph;
      const bool identical = same_bits(scalar[l].primitive.X_world, batch[l].primitive.X_world) &&
                             same_bits(scalar[l].primitive.Sigma_world, batch[l].primitive.Sigma_world) &&
                             same_bits(scalar[l].common.cross_covariance, batch[l].common.cross_covariance) &&
                             same_bits(scalar[l].common.part_cross_covariance, batch[l].common.part_cross_covariance) &&
                             scalar[l].primitive.observation_count == batch[l].primitive.observation_count;
      same += identical ? 1 : 0;
    }
  }
  CHECK(same == compared);
  CHECK(batch_stats.accepted == scalar_stats.accepted);
  CHECK(batch_stats.gated_outliers == scalar_stats.gated_outliers);
  CHECK(batch_stats.rejected_inputs == scalar_stats.rejected_inputs);
  // The innovations the gates tested, once each (the Joseph-form lanes' scalar redo does not add its own).
  CHECK(batch_stats.nis.counts == scalar_stats.nis.counts);
  CHECK(scalar_stats.nis.total() == scalar_stats.accepted + scalar_stats.gated_outliers);
  // Every path was taken: accepted, gated, refused inputs, the Joseph form.
  CHECK(joseph > 10);
  CHECK(scalar_stats.accepted > 500);
  CHECK(scalar_stats.gated_outliers > 50);
  CHECK(scalar_stats.rejected_inputs > 50);
}

TEST_CASE("a batch of no updates changes nothing, and one beyond four is not read") {
  const PinholeIntrinsics k = vantage::test::small_intrinsics();
  const Viewpoint view = vantage::test::looking_at_origin({30.0, 4.0, 2.0});
  std::mt19937 rng(3);
  Case cases[5];
  ConsiderUpdateRequest requests[5];
  for (int l = 0; l < 5; ++l) {
    cases[l] = make_case(0, view, k, rng);
    requests[l].primitive = &cases[l].primitive;
    requests[l].common = &cases[l].common;
    requests[l].observation_px = cases[l].observation_px;
    requests[l].config = cases[l].config;
    requests[l].at_prior = cases[l].at_prior;
  }
  const Case untouched = cases[4];
  Status statuses[5] = {Status::kNotFound, Status::kNotFound, Status::kNotFound, Status::kNotFound, Status::kNotFound};
  EkfStats stats;
  iterated_consider_update_batch(requests, 0, view, k, 5, &stats, statuses);
  CHECK(stats.accepted + stats.gated_outliers + stats.rejected_inputs == 0);
  CHECK(statuses[0] == Status::kNotFound);
  iterated_consider_update_batch(requests, 5, view, k, 5, &stats, statuses);
  CHECK(stats.accepted + stats.gated_outliers + stats.rejected_inputs == 4);
  CHECK(statuses[4] == Status::kNotFound);
  CHECK(cases[4].primitive.X_world == untouched.primitive.X_world);
  CHECK(cases[4].primitive.observation_count == untouched.primitive.observation_count);
}
