#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <catch2/catch.hpp>

#include "core/frontend/correlated_residuals.hpp"
#include "core/frontend/match_covariance.hpp"
#include "core/frontend/match_kernel.hpp"
#include "core/frontend/patch_search.hpp"
#include "core/frontend/patch_warp.hpp"
#include "core/frontend/photometric_normal.hpp"
#include "core/geometry/projection.hpp"
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
    // One draw per statement (the operands' evaluation order is unspecified: GCC takes the left one first
    // on x86-64, the order kept here).
    const double radius_draw = uniform();
    const double angle_draw = uniform();
    const double gauss = std::sqrt(-2.0 * std::log(radius_draw)) * std::cos(6.283185307179586 * angle_draw);
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

// The query for the plane point seen at reference pixel (sx, sy) and its patch, with the front end's
// fallback prior: facing the creating camera (off the true normal by the ray's angle), variance 1/4.
PhotometricNormalQuery facing_query(const TwoViews& scene, const GrayImageView& reference_image, int sx, int sy,
                                    std::array<std::uint8_t, kPatchPixels>* patch) {
  Eigen::Vector3d X;
  REQUIRE(scene.plane.intersect(Eigen::Vector2d(sx, sy), scene.reference, scene.k, &X));
  PhotometricNormalQuery query;
  query.X_world = X;
  query.normal_world = (scene.reference.position_world - X).normalized().cast<float>();
  query.prior_tilt_variance = 0.25;
  query.reference = scene.reference;
  query.target = scene.target;
  REQUIRE(ok(project(X, scene.target, scene.k, &query.uv_target_px)));
  extract_patch(reference_image, sx, sy, patch);
  return query;
}

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
        std::array<std::uint8_t, kPatchPixels> patch;
        const PhotometricNormalQuery query = facing_query(scene, reference_image, sx, sy, &patch);
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

namespace {

// Bilinear interpolation of the image at (x, y), one sample at a time (x, y inside [0, w - 1) x [0, h - 1)).
double sample_bilinear(const GrayImageView& image, double x, double y) {
  const BilinearCell c = bilinear_cell(x, y);
  const double top = (1.0 - c.fx) * image.at(c.x0, c.y0) + c.fx * image.at(c.x0 + 1, c.y0);
  const double bottom = (1.0 - c.fx) * image.at(c.x0, c.y0 + 1) + c.fx * image.at(c.x0 + 1, c.y0 + 1);
  return (1.0 - c.fy) * top + c.fy * bottom;
}

// The photometric pass in plain double precision, pixel by pixel (sample_bilinear and its central
// differences): the reference for the vectorized builds. False when a pixel leaves [1, w - 2) x [1, h - 2).
bool reference_pass(const GrayImageView& image, const std::array<std::uint8_t, kPatchPixels>& patch,
                    match_kernel::PhotometricPass* pass) {
  const Eigen::Matrix2d M = Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(pass->M);
  const Eigen::Matrix2d dM0 = Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(pass->dM0);
  const Eigen::Matrix2d dM1 = Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(pass->dM1);
  Eigen::Matrix<double, 6, 6> JtJ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> Jtr = Eigen::Matrix<double, 6, 1>::Zero();
  pass->sum_r2 = 0.0;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kPatchSize; ++tx) {
      const Eigen::Vector2d y(tx - kPatchRadius, ty - kPatchRadius);
      const Eigen::Vector2d p = Eigen::Vector2d(pass->u_x, pass->u_y) + M * y;
      if (!(p.x() >= 1.0 && p.y() >= 1.0 && p.x() < image.width_px - 2.0 && p.y() < image.height_px - 2.0)) return false;
      const double value = sample_bilinear(image, p.x(), p.y());
      const Eigen::Vector2d g(0.5 * (sample_bilinear(image, p.x() + 1.0, p.y()) - sample_bilinear(image, p.x() - 1.0, p.y())),
                              0.5 * (sample_bilinear(image, p.x(), p.y() + 1.0) - sample_bilinear(image, p.x(), p.y() - 1.0)));
      const double T = patch[static_cast<std::size_t>(ty * kPatchSize + tx)];
      const double r = value - pass->gain * T - pass->offset;
      Eigen::Matrix<double, 6, 1> J;
      J << g.x(), g.y(), g.dot(dM0 * y), g.dot(dM1 * y), -T, -1.0;
      JtJ += J * J.transpose();
      Jtr += J * r;
      pass->sum_r2 += r * r;
      for (int k = 0; k < 4; ++k) pass->rows[k][ty][tx] = static_cast<float>(J(k));
      pass->rows[4][ty][tx] = static_cast<float>(r);
    }
  }
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) pass->JtJ[i][j] = JtJ(i, j);
    pass->Jtr[i] = Jtr(i);
  }
  return true;
}

}  // namespace

TEST_CASE("the photometric normal's pixel loop equals a plain double-precision one in every build") {
  const TwoViews scene(0.5, 1.0, 3);
  const GrayImageView image = vantage::test::view_of(scene.pixels[1], scene.k);
  const GrayImageView reference_image = vantage::test::view_of(scene.pixels[0], scene.k);
  std::uint64_t state = 12345;
  auto uniform = [&state] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return (static_cast<double>(state >> 11) + 0.5) / 9007199254740992.0;
  };
  int compared = 0;
  int outside = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::array<std::uint8_t, kPatchPixels> patch;
    extract_patch(reference_image, 10 + static_cast<std::int32_t>(uniform() * (image.width_px - 20)),
                  10 + static_cast<std::int32_t>(uniform() * (image.height_px - 20)), &patch);
    match_kernel::PhotometricPass in{};
    // Centres over the whole image, the borders included (some patches leave it), maps with shear and
    // scale, negative positions relative to u's integer part.
    in.u_x = 2.0 + uniform() * (image.width_px - 4.0);
    in.u_y = 2.0 + uniform() * (image.height_px - 4.0);
    const double angle = 0.6 * (uniform() - 0.5);
    const double scale = 0.8 + 0.4 * uniform();
    in.M[0] = scale * std::cos(angle) + 0.1 * (uniform() - 0.5);
    in.M[1] = -scale * std::sin(angle);
    in.M[2] = scale * std::sin(angle);
    in.M[3] = scale * std::cos(angle) + 0.2 * (uniform() - 0.5);
    for (int k = 0; k < 4; ++k) {
      in.dM0[k] = uniform() - 0.5;
      in.dM1[k] = uniform() - 0.5;
    }
    in.gain = 0.8 + 0.4 * uniform();
    in.offset = 20.0 * (uniform() - 0.5);
    match_kernel::PhotometricPass expected = in;
    const bool expected_ok = reference_pass(image, patch, &expected);
    outside += expected_ok ? 0 : 1;
    for (const MatchKernel kernel : {MatchKernel::kBaseline, MatchKernel::kAvx2Fma}) {
      if (!match_kernel_supported(kernel)) continue;
      INFO("kernel " << to_string(kernel) << ", trial " << trial);
      match_kernel::PhotometricPass got = in;
      const match_kernel::Image view{image.pixels, image.width_px, image.height_px, image.stride_bytes};
      bool got_ok = false;
      REQUIRE_NO_ALLOCATION(got_ok = match_kernel::functions(kernel).photometric(view, patch.data(), &got));
      REQUIRE(got_ok == expected_ok);
      if (!got_ok) continue;
      ++compared;
      // Float lanes against double: within a few float roundings of each sum's scale.
      for (int i = 0; i < 6; ++i) {
        for (int j = 0; j < 6; ++j) {
          const double scale_ij = std::sqrt(expected.JtJ[i][i] * expected.JtJ[j][j]);
          CHECK(std::abs(got.JtJ[i][j] - expected.JtJ[i][j]) <= 1e-5 * scale_ij);
        }
        CHECK(std::abs(got.Jtr[i] - expected.Jtr[i]) <= 1e-5 * std::sqrt(expected.JtJ[i][i] * expected.sum_r2) + 1e-3);
      }
      CHECK(std::abs(got.sum_r2 - expected.sum_r2) <= 1e-5 * expected.sum_r2 + 1e-3);
      for (int k = 0; k < 5; ++k) {
        for (int ty = 0; ty < kPatchSize; ++ty) {
          for (int tx = 0; tx < kPatchSize; ++tx) CHECK(std::abs(got.rows[k][ty][tx] - expected.rows[k][ty][tx]) < 2e-3);
        }
      }
    }
  }
  CHECK(compared > 150);
  CHECK(outside > 0);
  // A non-finite input is refused.
  std::array<std::uint8_t, kPatchPixels> patch{};
  match_kernel::PhotometricPass bad{};
  bad.u_x = std::nan("");
  bad.u_y = 40.0;
  bad.M[0] = bad.M[3] = 1.0;
  const match_kernel::Image view{image.pixels, image.width_px, image.height_px, image.stride_bytes};
  CHECK_FALSE(match_kernel::functions(MatchKernel::kBaseline).photometric(view, patch.data(), &bad));
}

namespace {

// Calls visit(scene, target image, patch, query) for a 5 x 5 grid of the 35-degree scene's patches.
template <typename Visit>
void for_each_grid_query(std::uint64_t seed, Visit visit) {
  const TwoViews scene(0.6, 1.0, seed);
  const GrayImageView reference_image = vantage::test::view_of(scene.pixels[0], scene.k);
  const GrayImageView target_image = vantage::test::view_of(scene.pixels[1], scene.k);
  for (int sy = 30; sy <= 90; sy += 15) {
    for (int sx = 40; sx <= 120; sx += 20) {
      std::array<std::uint8_t, kPatchPixels> patch;
      const PhotometricNormalQuery query = facing_query(scene, reference_image, sx, sy, &patch);
      visit(scene, target_image, patch, query);
    }
  }
}

}  // namespace

TEST_CASE("the photometric normal's builds give the same estimate") {
  if (!match_kernel_supported(MatchKernel::kAvx2Fma)) return;  // one build only on this machine
  int compared = 0;
  for_each_grid_query(1, [&](const TwoViews& scene, const GrayImageView& target_image,
                             const std::array<std::uint8_t, kPatchPixels>& patch, PhotometricNormalQuery query) {
    PhotometricNormalEstimate estimates[2];
    Status status[2];
    for (int b = 0; b < 2; ++b) {
      query.kernel = b == 0 ? MatchKernel::kBaseline : MatchKernel::kAvx2Fma;
      status[b] = estimate_photometric_normal(target_image, patch, query, scene.k, &estimates[b]);
    }
    REQUIRE(status[0] == status[1]);
    if (!ok(status[0])) return;
    ++compared;
    CHECK((estimates[0].normal_world - estimates[1].normal_world).norm() < 1e-4f);
    CHECK((estimates[0].tilt_covariance - estimates[1].tilt_covariance).norm() < 1e-3 * estimates[0].tilt_covariance.norm());
    CHECK((estimates[0].uv_target_px - estimates[1].uv_target_px).norm() < 1e-4);
  });
  CHECK(compared > 10);
}

namespace {

// The tilt block of the sandwich covariance (information J^T J meat^-1 J^T J / sigma2 plus the prior on
// the tilt), as the estimate forms it, in plain Eigen.
Eigen::Matrix2d sandwich_tilt_covariance(const Eigen::Matrix<double, 6, 6>& JtJ, const Eigen::Matrix<double, 6, 6>& meat,
                                         double sigma2, double prior_information) {
  Eigen::Matrix<double, 6, 6> information = JtJ * meat.ldlt().solve(JtJ) / sigma2;
  information(2, 2) += prior_information;
  information(3, 3) += prior_information;
  return information.inverse().block<2, 2>(2, 2);
}

}  // namespace

TEST_CASE("the photometric pass's float meat equals the double one of the correlated model") {
  // Passes of the kernel at the true plane's map with small errors in u and the tilt (the estimate's
  // last passes), the meat from the pass's rows in float lanes against correlated_information_meat in
  // double from the same rows, and the tilt covariance each gives.
  const TwoViews scene(0.6, 1.0, 5);
  const GrayImageView reference_image = vantage::test::view_of(scene.pixels[0], scene.k);
  const GrayImageView target_image = vantage::test::view_of(scene.pixels[1], scene.k);
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  int compared = 0;
  double largest_relative_variance_change = 0.0;
  for (int sy = 30; sy <= 90; sy += 10) {
    for (int sx = 40; sx <= 120; sx += 10) {
      std::array<std::uint8_t, kPatchPixels> patch;
      const PhotometricNormalQuery query = facing_query(scene, reference_image, sx, sy, &patch);
      Eigen::Matrix2d A;
      std::array<Eigen::Matrix2d, 2> dA;
      Eigen::Matrix<double, 2, 3> H_reference;
      Eigen::Matrix<double, 2, 3> H_target;
      Eigen::Vector2d unused;
      REQUIRE(ok(project_with_jacobian(query.X_world, scene.reference, scene.k, &unused, &H_reference)));
      REQUIRE(ok(project_with_jacobian(query.X_world, scene.target, scene.k, &unused, &H_target)));
      if (!ok(plane_affine_from_jacobians(H_reference, H_target, Eigen::Vector3f::UnitX(), &A, &dA))) continue;
      const Eigen::Matrix2d M = A.inverse();
      match_kernel::PhotometricPass pass{};
      const double du_x = jitter(rng);
      const double du_y = jitter(rng);
      pass.u_x = query.uv_target_px.x() + du_x;
      pass.u_y = query.uv_target_px.y() + du_y;
      for (int k = 0; k < 4; ++k) {
        pass.M[k] = M(k / 2, k % 2);
        pass.dM0[k] = -(M * dA[0] * M)(k / 2, k % 2);
        pass.dM1[k] = -(M * dA[1] * M)(k / 2, k % 2);
      }
      pass.gain = 1.0;
      pass.offset = 0.0;
      const match_kernel::Image view{target_image.pixels, target_image.width_px, target_image.height_px,
                                     target_image.stride_bytes};
      if (!match_kernel::functions(MatchKernel::kAuto).photometric(view, patch.data(), &pass)) continue;
      PatchResiduals<6> rows;
      Eigen::Matrix<double, 6, 6> JtJ;
      for (int i = 0; i < kPatchPixels; ++i) {
        const int ty = i / kPatchSize;
        const int tx = i % kPatchSize;
        rows.J[static_cast<std::size_t>(i)] << pass.rows[0][ty][tx], pass.rows[1][ty][tx], pass.rows[2][ty][tx],
            pass.rows[3][ty][tx], -static_cast<double>(patch[static_cast<std::size_t>(i)]), -1.0;
        rows.r[static_cast<std::size_t>(i)] = pass.rows[4][ty][tx];
        rows.valid[static_cast<std::size_t>(i)] = true;
      }
      for (int i = 0; i < 6; ++i) {
        for (int j = 0; j < 6; ++j) JtJ(i, j) = pass.JtJ[i][j];
      }
      double rho_x = 0.0;
      double rho_y = 0.0;
      lag_one_correlations(rows, &rho_x, &rho_y);
      const Eigen::Matrix<double, 6, 6> general = correlated_information_meat(rows, rho_x, rho_y);
      double got_rho_x = -1.0;
      double got_rho_y = -1.0;
      Eigen::Matrix<double, 6, 6> got;
      REQUIRE_NO_ALLOCATION(got = photometric_correlated_meat(pass, patch, &got_rho_x, &got_rho_y));
      INFO("patch " << sx << ", " << sy << "\ngeneral\n" << general << "\nfloat\n" << got);
      // Both builds: the same operations per lane, the same bits.
      double baseline_rho_x = -1.0;
      double baseline_rho_y = -1.0;
      const Eigen::Matrix<double, 6, 6> baseline =
          photometric_correlated_meat(pass, patch, &baseline_rho_x, &baseline_rho_y, MatchKernel::kBaseline);
      CHECK((baseline.array() == got.array()).all());
      CHECK(baseline_rho_x == got_rho_x);
      CHECK(baseline_rho_y == got_rho_y);
      CHECK(std::abs(got_rho_x - rho_x) < 1e-5);
      CHECK(std::abs(got_rho_y - rho_y) < 1e-5);
      CHECK((got - got.transpose()).norm() == 0.0);
      for (int i = 0; i < 6; ++i) {
        for (int j = 0; j < 6; ++j) CHECK(std::abs(got(i, j) - general(i, j)) <= 1e-5 * std::sqrt(general(i, i) * general(j, j)));
      }
      // The tilt covariance: the same to well within its own size (the estimate's posterior).
      const double sigma2 = std::max(pass.sum_r2 / (kPatchPixels - 6), 2.0 / 12.0);
      const Eigen::Matrix2d expected = sandwich_tilt_covariance(JtJ, general, sigma2, 4.0);
      const Eigen::Matrix2d from_float = sandwich_tilt_covariance(JtJ, got, sigma2, 4.0);
      const double change = (from_float - expected).norm() / expected.norm();
      largest_relative_variance_change = std::max(largest_relative_variance_change, change);
      CHECK(change < 1e-3);
      ++compared;
    }
  }
  INFO("largest relative change of the tilt covariance " << largest_relative_variance_change);
  CHECK(compared > 30);
}

TEST_CASE("the photometric normal's decrement stop stays within the estimate's own uncertainty") {
  int compared = 0;
  for_each_grid_query(7, [&](const TwoViews& scene, const GrayImageView& target_image,
                             const std::array<std::uint8_t, kPatchPixels>& patch, PhotometricNormalQuery query) {
    query.stop_decrement = 0.0;  // the full run: the step-length rule only
    PhotometricNormalEstimate full;
    if (!ok(estimate_photometric_normal(target_image, patch, query, scene.k, &full))) return;
    query.stop_decrement = 1e-2;
    PhotometricNormalEstimate stopped;
    Status status = Status::kOk;
    REQUIRE_NO_ALLOCATION(status = estimate_photometric_normal(target_image, patch, query, scene.k, &stopped));
    REQUIRE(ok(status));
    // The normals' angle against the tilt's posterior standard deviation, u against a hundredth of a pixel.
    const double angle = std::acos(std::fmin(1.0, static_cast<double>(full.normal_world.dot(stopped.normal_world))));
    INFO("angle " << angle << " rad, tilt variance " << full.tilt_variance);
    CHECK(angle < 0.2 * std::sqrt(full.tilt_variance));
    CHECK((full.uv_target_px - stopped.uv_target_px).norm() < 0.01);
    CHECK(std::abs(stopped.tilt_variance - full.tilt_variance) < 0.1 * full.tilt_variance);
    ++compared;
  });
  CHECK(compared > 10);
}
