#include <cmath>
#include <cstdint>
#include <vector>

#include <catch2/catch.hpp>

#include "core/frontend/match_covariance.hpp"
#include "core/frontend/patch_search.hpp"
#include "core/frontend/patch_warp.hpp"
#include "core/frontend/photometric_normal.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

// Deterministic Gaussian pixel noise (sigma gray levels) on a rendered image.
void add_noise(std::vector<std::uint8_t>* pixels, double sigma, std::uint64_t seed) {
  std::uint64_t state = seed * 0x9E3779B97F4A7C15ull + 1;
  auto uniform = [&state] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return (static_cast<double>(state >> 11) + 0.5) / 9007199254740992.0;
  };
  for (std::uint8_t& value : *pixels) {
    const double gauss = std::sqrt(-2.0 * std::log(uniform())) * std::cos(6.283185307179586 * uniform());
    const double noisy = std::round(value + sigma * gauss);
    value = static_cast<std::uint8_t>(noisy < 0.0 ? 0.0 : (noisy > 255.0 ? 255.0 : noisy));
  }
}

struct TwoViews {
  PinholeIntrinsics k = vantage::test::small_intrinsics();
  vantage::test::TexturedPlane plane;  // x = 0, normal +x
  Viewpoint reference;
  Viewpoint target;
  std::vector<std::uint8_t> pixels[2];

  TwoViews(double azimuth_rad, double noise_sigma, std::uint64_t seed) {
    plane.feature_size = 1.0;
    reference = vantage::test::looking_at_origin({30.0, 0.0, 0.0});
    target = vantage::test::looking_at_origin({30.0 * std::cos(azimuth_rad), 30.0 * std::sin(azimuth_rad), 2.0});
    for (int j = 0; j < 2; ++j) {
      vantage::test::render_plane(plane, j == 0 ? reference : target, k, &pixels[j]);
      if (noise_sigma > 0.0) add_noise(&pixels[j], noise_sigma, 2 * seed + static_cast<std::uint64_t>(j));
    }
  }
};

// The angle (rad) between the estimate and the plane's normal, and its normalized squared tilt error.
struct Error {
  double angle = 0.0;
  double nees = 0.0;
};

}  // namespace

TEST_CASE("the photometric normal recovers a plane's normal from a facing-camera prior") {
  // Monte Carlo over seeds and patches: 35 degrees between the views, 1 gray level of noise.
  double sum_angle2_prior = 0.0;
  double sum_angle2 = 0.0;
  double sum_nees = 0.0;
  double sum_predicted = 0.0;
  int used = 0;
  int tried = 0;
  for (std::uint64_t seed = 0; seed < 4; ++seed) {
    const TwoViews scene(0.6, 1.0, seed);
    const GrayImageView reference_image = vantage::test::view_of(scene.pixels[0], scene.k);
    const GrayImageView target_image = vantage::test::view_of(scene.pixels[1], scene.k);
    for (int sy = 30; sy <= 90; sy += 10) {
      for (int sx = 40; sx <= 120; sx += 10) {
        Eigen::Vector3d X;
        REQUIRE(scene.plane.intersect(Eigen::Vector2d(sx, sy), scene.reference, scene.k, &X));
        PhotometricNormalQuery query;
        query.X_world = X;
        // The front end's fallback: facing the creating camera (off the true normal by the ray's angle).
        query.normal_world = (scene.reference.position_world - X).normalized().cast<float>();
        query.prior_tilt_variance = 0.25;
        query.reference = scene.reference;
        query.target = scene.target;
        REQUIRE(ok(project(X, scene.target, scene.k, &query.uv_target_px)));
        std::array<std::uint8_t, kPatchPixels> patch;
        extract_patch(reference_image, sx, sy, &patch);
        ++tried;
        PhotometricNormalEstimate estimate;
        if (!ok(estimate_photometric_normal(target_image, patch, query, scene.k, &estimate))) continue;
        const Eigen::Vector3d n = estimate.normal_world.cast<double>();
        const double angle = std::acos(std::fmin(1.0, n.x()));
        const double prior_angle = std::acos(std::fmin(1.0, static_cast<double>(query.normal_world.x())));
        // The tilt error in the estimate's tangent plane, against its tilt covariance (2 dof).
        const Eigen::Vector3d helper = std::abs(query.normal_world.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
        const Eigen::Vector3d n0 = query.normal_world.cast<double>();
        const Eigen::Vector3d e1 = n0.cross(helper).normalized();
        const Eigen::Vector3d e2 = n0.cross(e1);
        const Eigen::Vector3d truth = Eigen::Vector3d::UnitX();
        // Tilt coordinates (about n0's axes) of the truth and of the estimate.
        const Eigen::Vector2d t_true(truth.dot(e1) / truth.dot(n0), truth.dot(e2) / truth.dot(n0));
        const Eigen::Vector2d t_est(n.dot(e1) / n.dot(n0), n.dot(e2) / n.dot(n0));
        const Eigen::Vector2d d = t_est - t_true;
        sum_nees += d.dot(estimate.tilt_covariance.inverse() * d);
        sum_angle2 += angle * angle;
        sum_angle2_prior += prior_angle * prior_angle;
        sum_predicted += estimate.tilt_covariance.trace();
        ++used;
      }
    }
  }
  REQUIRE(used > 0.9 * tried);
  const double rms = std::sqrt(sum_angle2 / used);
  INFO("used " << used << "/" << tried << ", RMS angle prior " << std::sqrt(sum_angle2_prior / used) * 57.3
               << " deg, estimate " << rms * 57.3 << " deg, predicted " << std::sqrt(sum_predicted / used) * 57.3
               << " deg, mean NEES (2 dof) " << sum_nees / used);
  // Measured: 12.6 -> 3.9 degrees RMS, predicted 4.2; mean NEES 2.2 for 2 dof (3.1 when the residuals
  // are taken as white: the resampled patch's residuals are correlated between neighbours).
  CHECK(rms < 0.4 * std::sqrt(sum_angle2_prior / used));
  CHECK(sum_nees / used < 2.8);
  CHECK(sum_nees / used > 1.4);
}

TEST_CASE("the photometric normal keeps the prior where the view did not change, and refuses bad input") {
  const TwoViews scene(0.0, 1.0, 7);  // the target differs by 2 units of height only
  const GrayImageView reference_image = vantage::test::view_of(scene.pixels[0], scene.k);
  const GrayImageView target_image = vantage::test::view_of(scene.pixels[1], scene.k);
  Eigen::Vector3d X;
  REQUIRE(scene.plane.intersect(Eigen::Vector2d(80, 60), scene.reference, scene.k, &X));
  PhotometricNormalQuery query;
  query.X_world = X;
  query.normal_world = Eigen::Vector3f(1.0f, 0.0f, 0.0f);
  query.prior_tilt_variance = 0.01;
  query.reference = scene.reference;
  query.target = scene.target;
  REQUIRE(ok(project(X, scene.target, scene.k, &query.uv_target_px)));
  std::array<std::uint8_t, kPatchPixels> patch;
  extract_patch(reference_image, 80, 60, &patch);
  PhotometricNormalEstimate estimate;
  REQUIRE_NO_ALLOCATION(REQUIRE(ok(estimate_photometric_normal(target_image, patch, query, scene.k, &estimate))));
  // Little change of view: the data says little, the posterior stays near the prior.
  CHECK(estimate.tilt_variance <= query.prior_tilt_variance);
  CHECK(estimate.tilt_variance > 0.2 * query.prior_tilt_variance);
  CHECK(std::acos(std::fmin(1.0, static_cast<double>(estimate.normal_world.x()))) < 0.2);
  CHECK((estimate.uv_target_px - query.uv_target_px).norm() < 0.5);

  PhotometricNormalQuery bad = query;
  bad.normal_world = Eigen::Vector3f(2.0f, 0.0f, 0.0f);
  CHECK(estimate_photometric_normal(target_image, patch, bad, scene.k, &estimate) == Status::kInvalidArgument);
  bad = query;
  bad.prior_tilt_variance = 0.0;
  CHECK(estimate_photometric_normal(target_image, patch, bad, scene.k, &estimate) == Status::kInvalidArgument);
  bad = query;
  bad.normal_world = -query.normal_world;  // faces away from both views
  CHECK(estimate_photometric_normal(target_image, patch, bad, scene.k, &estimate) == Status::kBehindCamera);
  bad = query;
  bad.uv_target_px = Eigen::Vector2d(1.0, 1.0);  // the patch would leave the image
  CHECK(estimate_photometric_normal(target_image, patch, bad, scene.k, &estimate) == Status::kOutsideImage);
  CHECK(estimate_photometric_normal(GrayImageView{}, patch, query, scene.k, &estimate) == Status::kInvalidImage);
}

TEST_CASE("a match's covariance with correlated residuals follows the empirical error spread") {
  // Fronto-parallel views 0.4 units apart (a few pixels of shift), 1 gray level of noise in both: the
  // subpixel fit's white-residual covariance against the correlated one, over seeds and noise draws.
  double nees_white = 0.0;
  double nees_correlated = 0.0;
  int used = 0;
  int tried = 0;
  for (std::uint64_t seed = 0; seed < 4; ++seed) {
    vantage::test::TexturedPlane plane;
    plane.feature_size = 0.6;
    const PinholeIntrinsics k = vantage::test::small_intrinsics();
    const Viewpoint reference = vantage::test::looking_at_origin({30.0, 0.0, 0.0});
    const Viewpoint target = vantage::test::looking_at_origin({30.0, 0.3 + 0.05 * seed, 0.2});
    std::vector<std::uint8_t> pixels[2];
    for (int j = 0; j < 2; ++j) {
      vantage::test::render_plane(plane, j == 0 ? reference : target, k, &pixels[j]);
      add_noise(&pixels[j], 1.0, 100 + 2 * seed + static_cast<std::uint64_t>(j));
    }
    const GrayImageView reference_image = vantage::test::view_of(pixels[0], k);
    const GrayImageView target_image = vantage::test::view_of(pixels[1], k);
    for (int sy = 20; sy <= 100; sy += 8) {
      for (int sx = 20; sx <= 140; sx += 8) {
        Eigen::Vector3d X;
        REQUIRE(plane.intersect(Eigen::Vector2d(sx, sy), reference, k, &X));
        Eigen::Vector2d truth;
        REQUIRE(ok(project(X, target, k, &truth)));
        std::array<std::uint8_t, kPatchPixels> patch;
        extract_patch(reference_image, sx, sy, &patch);
        NccTemplate tmpl;
        make_template(patch, &tmpl);
        if (tmpl.stddev_gray < 6.0f) continue;
        ++tried;
        Eigen::Vector2d found = truth;
        Eigen::Matrix2d white;
        Eigen::Matrix2d correlated;
        if (!refine_subpixel(target_image, tmpl, static_cast<std::int32_t>(std::lround(truth.x())),
                             static_cast<std::int32_t>(std::lround(truth.y())), 5, &found, &white)) {
          continue;
        }
        bool computed = false;
        REQUIRE_NO_ALLOCATION(computed = correlated_match_covariance(target_image, tmpl, found, &correlated));
        REQUIRE(computed);
        const Eigen::Vector2d error = found - truth;
        nees_white += error.dot(white.inverse() * error);
        nees_correlated += error.dot(correlated.inverse() * error);
        ++used;
      }
    }
  }
  REQUIRE(used > 0.9 * tried);
  INFO(used << " matches: mean NEES / 2 white " << nees_white / used / 2.0 << ", correlated "
            << nees_correlated / used / 2.0);
  // Measured: white 1.32, correlated 1.10 (the rest: the bilinear model error, smooth, partly taken for
  // signal by the fit).
  CHECK(nees_correlated / used < nees_white / used);
  CHECK(nees_correlated / used / 2.0 > 0.7);
  CHECK(nees_correlated / used / 2.0 < 1.25);
}
