#include "core/estimation/nis_histogram.hpp"

#include <Eigen/Cholesky>
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>

#include "core/estimation/ekf.hpp"
#include "core/geometry/projection.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

TEST_CASE("the NIS bins are chi-square(2) quantiles at steps of 5 %, the top one the default gate") {
  CHECK(kNisBinLowerEdges[0] == 0.0);
  for (int k = 1; k < kNisBins; ++k) {
    const double expected = -2.0 * std::log1p(-static_cast<double>(k) / kNisBins);
    CHECK(kNisBinLowerEdges[static_cast<std::size_t>(k)] == Approx(expected).epsilon(1e-14));
  }
  CHECK(kNisBinLowerEdges[kNisBins - 1] == Approx(kChiSquare2Dof95).epsilon(1e-14));
  CHECK(kChiSquare2DofMedian == Approx(2.0 * std::log(2.0)).epsilon(1e-15));
}

TEST_CASE("a NIS lands in the bin whose lower edge it reaches, and NaN or negative values are not recorded") {
  NisHistogram h;
  REQUIRE_NO_ALLOCATION(h.record(0.0));
  h.record(kNisBinLowerEdges[7]);
  h.record(std::nextafter(kNisBinLowerEdges[7], 0.0));
  h.record(1e300);
  h.record(std::numeric_limits<double>::infinity());
  h.record(std::nan(""));
  h.record(-1e-12);
  CHECK(h.total() == 5);
  CHECK(h.counts[0] == 1);
  CHECK(h.counts[6] == 1);
  CHECK(h.counts[7] == 1);
  CHECK(h.counts[kNisBins - 1] == 2);
  NisHistogram twice = h;
  twice.add(h);
  CHECK(twice.total() == 10);
  CHECK(twice.counts[kNisBins - 1] == 4);
  const NisSummary empty = summarize(NisHistogram{});
  CHECK(empty.count == 0);
  CHECK(empty.median_scale == 0.0);
}

TEST_CASE("the summary reads the scale of scaled chi-square(2) samples from their median") {
  std::mt19937 rng(37);
  std::exponential_distribution<double> chi2_2dof(0.5);  // chi-square(2) is exponential with mean 2
  for (const double scale : {0.4, 1.0, 2.5}) {
    NisHistogram h;
    for (int i = 0; i < 40000; ++i) h.record(scale * chi2_2dof(rng));
    const NisSummary s = summarize(h);
    CHECK(s.count == 40000);
    CHECK_FALSE(s.median_in_top_bin);
    CHECK(s.median_scale == Approx(scale).epsilon(0.03));
    // The share beyond chi-square(2)'s 95 % point: exp(-5.991 / (2 scale)).
    CHECK(s.fraction_beyond_95 == Approx(std::exp(-0.5 * kChiSquare2Dof95 / scale)).margin(0.005));
  }
  // A median beyond the 95 % point is reported as the top bin's edge, a lower bound.
  NisHistogram far;
  for (int i = 0; i < 1000; ++i) far.record(10.0 * chi2_2dof(rng));
  const NisSummary s = summarize(far);
  CHECK(s.median_in_top_bin);
  CHECK(s.median_scale == Approx(kChiSquare2Dof95 / kChiSquare2DofMedian).epsilon(1e-12));
}

namespace {

// ekf_update of `trials` primitives whose truth is drawn from their prior, observed with pixel noise of
// standard deviation noise_sd_px while the filter assumes R = r_sd_px^2 I: the innovations' histogram.
NisHistogram ekf_innovations(double noise_sd_px, double r_sd_px, int trials) {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  Viewpoint view;
  REQUIRE(ok(look_at({40.0, 0.0, 0.0}, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view)));
  std::mt19937 rng(5);
  std::normal_distribution<double> z(0.0, 1.0);
  EkfConfig config;
  config.R_px2 = r_sd_px * r_sd_px * Eigen::Matrix2d::Identity();
  EkfStats stats;
  for (int t = 0; t < trials; ++t) {
    Primitive p;
    p.X_world = Eigen::Vector3d(2.0 * z(rng), 2.0 * z(rng), 2.0 * z(rng));
    Eigen::Matrix3d A;
    for (int i = 0; i < 9; ++i) A(i / 3, i % 3) = 0.004 * z(rng);
    p.Sigma_world = A * A.transpose() + 1e-6 * Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d L = p.Sigma_world.llt().matrixL();
    const Eigen::Vector3d truth = p.X_world + L * Eigen::Vector3d(z(rng), z(rng), z(rng));
    Eigen::Vector2d uv;
    REQUIRE(ok(project(truth, view, k, &uv)));
    const Eigen::Vector2d observed = uv + noise_sd_px * Eigen::Vector2d(z(rng), z(rng));
    (void)ekf_update(p, observed, view, k, config, &stats);
  }
  CHECK(stats.nis.total() == static_cast<std::uint64_t>(trials));
  CHECK(stats.nis.total() == stats.accepted + stats.gated_outliers);
  return stats.nis;
}

}  // namespace

TEST_CASE(
    "an EKF whose R is the observations' noise has uniform NIS bins, one that understates or overstates it does not") {
  const int trials = 20000;
  const NisHistogram honest = ekf_innovations(0.5, 0.5, trials);
  const NisSummary h = summarize(honest);
  CHECK(h.median_scale == Approx(1.0).margin(0.05));
  CHECK(h.fraction_beyond_95 == Approx(0.05).margin(0.006));
  // Pearson's statistic against equal bins, 19 dof: below its 99.9 % point (43.82).
  double pearson = 0.0;
  const double expected = static_cast<double>(trials) / kNisBins;
  for (std::uint64_t c : honest.counts)
    pearson += (static_cast<double>(c) - expected) * (static_cast<double>(c) - expected) / expected;
  CHECK(pearson < 43.82);
  // The pixel noise twice what R says (the prior's share of S is small): innovations about 4 times S.
  const NisSummary over = summarize(ekf_innovations(1.0, 0.5, trials));
  CHECK(over.median_scale > 2.5);
  CHECK(over.fraction_beyond_95 > 0.3);
  // Half what R says: about a quarter.
  const NisSummary under = summarize(ekf_innovations(0.25, 0.5, trials));
  CHECK(under.median_scale < 0.5);
  CHECK(under.fraction_beyond_95 < 0.01);
}
