// The fast forms of the warp's normal-uncertainty terms against the direct ones they replace: the
// analytic tilt derivatives of the plane-induced map against finite differences, and the moment form of
// the warp covariance against the per-pixel sum.
#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include <Eigen/Dense>
#include <catch2/catch.hpp>

#include "core/frontend/patch_warp.hpp"
#include "core/geometry/projection.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

// The direct form: per pixel, g from central differences (one-sided at the mask's edge), then
// d_k = (sum g g^T)^-1 sum g g^T A^-1 dA_k x.
Eigen::Matrix2d direct_warp_shift_covariance(const NccTemplate& tmpl, const Eigen::Matrix2d& A,
                                             const std::array<Eigen::Matrix2d, 2>& dA, double tilt_variance) {
  auto valid = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < kPatchSize && y < kPatchSize && tmpl.mask[y * kPatchSize + x] > 0.5f;
  };
  auto value = [&](int x, int y) { return static_cast<double>(tmpl.values[y * kPatchSize + x]); };
  auto derivative = [&](int x, int y, int dx, int dy, double* out) {
    const bool forward = valid(x + dx, y + dy);
    const bool backward = valid(x - dx, y - dy);
    if (forward && backward) {
      *out = 0.5 * (value(x + dx, y + dy) - value(x - dx, y - dy));
    } else if (forward) {
      *out = value(x + dx, y + dy) - value(x, y);
    } else if (backward) {
      *out = value(x, y) - value(x - dx, y - dy);
    } else {
      return false;
    }
    return true;
  };
  const Eigen::Matrix2d A_inv = A.inverse();
  Eigen::Matrix2d G = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b[2] = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kPatchSize; ++tx) {
      if (!valid(tx, ty)) continue;
      Eigen::Vector2d g;
      if (!derivative(tx, ty, 1, 0, &g.x()) || !derivative(tx, ty, 0, 1, &g.y())) continue;
      const Eigen::Vector2d offset(tx - kPatchRadius, ty - kPatchRadius);
      G += g * g.transpose();
      for (int k = 0; k < 2; ++k) b[k] += g * g.dot(A_inv * dA[static_cast<std::size_t>(k)] * offset);
    }
  }
  const Eigen::Vector2d m0 = G.inverse() * b[0];
  const Eigen::Vector2d m1 = G.inverse() * b[1];
  return tilt_variance * (m0 * m0.transpose() + m1 * m1.transpose());
}

// sum_k vec(dA_k) vec(dA_k)^T: what the covariance sees of the derivatives, free of the choice of the
// two orthonormal tilt axes.
Eigen::Matrix4d tilt_outer(const std::array<Eigen::Matrix2d, 2>& dA) {
  Eigen::Matrix4d out = Eigen::Matrix4d::Zero();
  for (const Eigen::Matrix2d& d : dA) {
    const Eigen::Map<const Eigen::Vector4d> v(d.data());
    out += v * v.transpose();
  }
  return out;
}

}  // namespace

TEST_CASE("the analytic tilt derivatives of the plane-induced map match finite differences") {
  const PinholeIntrinsics k = PinholeIntrinsics::default_vga();
  const Viewpoint reference = vantage::test::looking_at_origin({40.0, 0.0, 0.0});
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  int compared = 0;
  for (const Eigen::Vector3d target_position :
       {Eigen::Vector3d(40.0, 2.0, 0.5), Eigen::Vector3d(28.0, 26.0, 10.0), Eigen::Vector3d(30.0, -20.0, -15.0)}) {
    const Viewpoint target = vantage::test::looking_at_origin(target_position);
    for (int trial = 0; trial < 8; ++trial) {
      // Braced lists: their draws are evaluated left to right on every platform (a call's arguments are not).
      const Eigen::Vector3d X{gauss(rng), 3.0 * gauss(rng), 3.0 * gauss(rng)};
      const Eigen::Vector3d n = (Eigen::Vector3d(1.0, 0.0, 0.0) + 0.4 * Eigen::Vector3d{gauss(rng), gauss(rng),
                                                                                       gauss(rng)}).normalized();
      Eigen::Vector2d uv;
      Eigen::Matrix<double, 2, 3> H_ref;
      Eigen::Matrix<double, 2, 3> H_target;
      REQUIRE(ok(project_with_jacobian(X, reference, k, &uv, &H_ref)));
      REQUIRE(ok(project_with_jacobian(X, target, k, &uv, &H_target)));
      Eigen::Matrix2d A;
      std::array<Eigen::Matrix2d, 2> dA;
      Status status = Status::kOk;
      REQUIRE_NO_ALLOCATION(status = plane_affine_from_jacobians(H_ref, H_target, n.cast<float>(), &A, &dA));
      REQUIRE(ok(status));
      Eigen::Matrix2d A_direct;
      REQUIRE(ok(plane_affine(X, n.cast<float>(), reference, target, k, &A_direct)));
      CHECK((A - A_direct).norm() <= 1e-9 * A.norm());
      // Central differences along two orthonormal in-plane axes of the test's own choosing, in double
      // through the Jacobian form (plane_affine takes a float normal).
      const Eigen::Vector3d a1 = n.cross(Eigen::Vector3d(0.3, 0.8, -0.5)).normalized();
      const Eigen::Vector3d axes[2] = {a1, n.cross(a1)};
      std::array<Eigen::Matrix2d, 2> dA_fd;
      constexpr double kStep = 1e-4;
      for (int j = 0; j < 2; ++j) {
        Eigen::Matrix2d plus;
        Eigen::Matrix2d minus;
        REQUIRE(ok(plane_affine_from_jacobians(H_ref, H_target, (n + kStep * axes[j]).normalized().cast<float>(),
                                               &plus, nullptr)));
        REQUIRE(ok(plane_affine_from_jacobians(H_ref, H_target, (n - kStep * axes[j]).normalized().cast<float>(),
                                               &minus, nullptr)));
        dA_fd[static_cast<std::size_t>(j)] = (plus - minus) / (2.0 * kStep);
      }
      const Eigen::Matrix4d analytic = tilt_outer(dA);
      const Eigen::Matrix4d numeric = tilt_outer(dA_fd);
      INFO("analytic\n" << analytic << "\nnumeric\n" << numeric);
      CHECK((analytic - numeric).norm() <= 5e-3 * numeric.norm() + 1e-12);
      // The public wrapper gives the same derivatives.
      std::array<Eigen::Matrix2d, 2> dA_wrapper;
      REQUIRE(ok(plane_affine_tilt_derivatives(X, n.cast<float>(), reference, target, k, A, &dA_wrapper)));
      CHECK((tilt_outer(dA_wrapper) - analytic).norm() <= 1e-6 * analytic.norm() + 1e-12);
      ++compared;
    }
  }
  CHECK(compared == 24);
  // Edge-on and non-unit normals are refused.
  Eigen::Matrix<double, 2, 3> H = Eigen::Matrix<double, 2, 3>::Zero();
  H(0, 0) = 1.0;
  H(1, 1) = 1.0;
  Eigen::Matrix2d A;
  CHECK(plane_affine_from_jacobians(H, H, Eigen::Vector3f(1.0f, 0.0f, 0.0f), &A, nullptr) == Status::kInvalidArgument);
  CHECK(plane_affine_from_jacobians(H, H, Eigen::Vector3f(0.0f, 0.0f, 2.0f), &A, nullptr) == Status::kInvalidArgument);
  CHECK(plane_affine_from_jacobians(H, H, Eigen::Vector3f(0.0f, 0.0f, 1.0f), &A, nullptr) == Status::kOk);
}

TEST_CASE("the moment form of the warp covariance equals the per-pixel sum, masked templates too") {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> gray(0, 255);
  std::normal_distribution<double> gauss(0.0, 1.0);
  int compared = 0;
  for (int trial = 0; trial < 60; ++trial) {
    std::array<std::uint8_t, kPatchPixels> patch{};
    for (auto& value : patch) value = static_cast<std::uint8_t>(gray(rng));
    // Identity, mild and strong warps: the strong ones mask corners and edges of the template.
    const double scale = trial % 3 == 0 ? 0.0 : (trial % 3 == 1 ? 0.1 : 0.5);
    const Eigen::Matrix2d A =
        Eigen::Matrix2d::Identity() + scale * Eigen::Matrix2d(Eigen::Matrix2d::Random(2, 2).array());
    NccTemplate tmpl;
    if (scale == 0.0) {
      make_template(patch, &tmpl);
    } else {
      warp_patch_template(patch, A, &tmpl);
    }
    if (tmpl.valid_count < kPatchPixels / 2) continue;
    std::array<Eigen::Matrix2d, 2> dA;
    for (auto& d : dA) d << gauss(rng), gauss(rng), gauss(rng), gauss(rng);
    TemplateGradientMoments moments;
    REQUIRE_NO_ALLOCATION(template_gradient_moments(tmpl, &moments));
    Eigen::Matrix2d fast;
    REQUIRE_NO_ALLOCATION(fast = warp_shift_covariance(moments, A, dA, 0.25));
    const Eigen::Matrix2d direct = direct_warp_shift_covariance(tmpl, A, dA, 0.25);
    INFO("trial " << trial << " valid " << tmpl.valid_count << "\nfast\n" << fast << "\ndirect\n" << direct);
    CHECK((fast - direct).norm() <= 1e-5 * direct.norm());
    CHECK((warp_shift_covariance(tmpl, A, dA, 0.25) - fast).norm() <= 1e-12 * fast.norm());
    ++compared;
  }
  CHECK(compared >= 40);
}

TEST_CASE("the warped template equals plain per-pixel bilinear sampling of the patch under random maps") {
  // The warp's lanes gather each sample's neighbours as pairs; the reference samples one pixel at a time
  // with the same float arithmetic (offset A x, cell, fractions, then the two horizontal and one vertical
  // interpolation), so the templates agree to the last bit on x86-64; aarch64's compiler fuses a * b + c
  // into one FMA in one of the two and not the other, which moves the last bits (a few 1e-5 gray levels),
  // so the values and the norm are compared to within float rounding of that size.
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> gray(0.0f, 255.0f);
  std::uniform_real_distribution<double> entry(-0.4, 0.4);
  std::uniform_real_distribution<double> angle(-3.2, 3.2);
  const float limit = static_cast<float>(kPatchRadius);
  int masked_seen = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::array<std::uint8_t, kPatchPixels> patch;
    for (auto& v : patch) v = static_cast<std::uint8_t>(gray(rng));
    const double a = angle(rng);
    Eigen::Matrix2d A;
    A << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
    A += Eigen::Matrix2d{{entry(rng), entry(rng)}, {entry(rng), entry(rng)}};
    NccTemplate warped;
    REQUIRE_NO_ALLOCATION(warp_patch_template(patch, A, &warped));
    std::array<float, kPatchPixels> values{};
    std::array<float, kPatchPixels> mask{};
    const float a00 = static_cast<float>(A(0, 0));
    const float a01 = static_cast<float>(A(0, 1));
    const float a10 = static_cast<float>(A(1, 0));
    const float a11 = static_cast<float>(A(1, 1));
    for (int ty = 0; ty < kPatchSize; ++ty) {
      for (int tx = 0; tx < kPatchSize; ++tx) {
        const float dx = static_cast<float>(tx - kPatchRadius);
        const float dy = static_cast<float>(ty - kPatchRadius);
        const float ox = a00 * dx + a01 * dy;
        const float oy = a10 * dx + a11 * dy;
        if (!(ox <= limit && ox >= -limit && oy <= limit && oy >= -limit)) continue;
        const float sx = ox + limit;
        const float sy = oy + limit;
        const int x0 = std::min(static_cast<int>(sx), kPatchSize - 2);
        const int y0 = std::min(static_cast<int>(sy), kPatchSize - 2);
        const float fx = sx - static_cast<float>(x0);
        const float fy = sy - static_cast<float>(y0);
        auto at = [&](int x, int y) { return static_cast<float>(patch[static_cast<std::size_t>(y * kPatchSize + x)]); };
        const float top = at(x0, y0) + fx * (at(x0 + 1, y0) - at(x0, y0));
        const float bottom = at(x0, y0 + 1) + fx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
        values[static_cast<std::size_t>(ty * kPatchSize + tx)] = top + fy * (bottom - top);
        mask[static_cast<std::size_t>(ty * kPatchSize + tx)] = 1.0f;
      }
    }
    NccTemplate expected;
    make_template(values, mask, &expected);
    if (expected.valid_count < kPatchPixels) ++masked_seen;
    CHECK(warped.valid_count == expected.valid_count);
    CHECK(warped.mask == expected.mask);
    float worst = 0.0f;
    for (std::size_t j = 0; j < kPatchPixels; ++j) {
      worst = std::max(worst, std::abs(warped.values[j] - expected.values[j]));
    }
    CHECK(worst <= 1e-3f);
    CHECK(std::abs(warped.norm - expected.norm) <= 1e-5f * expected.norm);
  }
  CHECK(masked_seen > 50);  // rotations push corners out of the stored patch
}

TEST_CASE("the template moments give the same bits in both builds, masked templates too") {
  std::mt19937 rng(29);
  std::uniform_int_distribution<int> gray(0, 255);
  int masked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::array<std::uint8_t, kPatchPixels> patch{};
    // Full range, dark and flat-ish patches (small differences of centred values).
    const int span = trial % 3 == 0 ? 256 : (trial % 3 == 1 ? 8 : 64);
    for (auto& value : patch) value = static_cast<std::uint8_t>(gray(rng) % span);
    NccTemplate tmpl;
    if (trial % 2 == 0) {
      make_template(patch, &tmpl);
    } else {
      // Warps that mask corners and edges.
      const Eigen::Matrix2d A =
          Eigen::Matrix2d::Identity() + 0.4 * Eigen::Matrix2d(Eigen::Matrix2d::Random(2, 2).array());
      warp_patch_template(patch, A, &tmpl);
      if (tmpl.valid_count < kPatchPixels) ++masked;
    }
    TemplateGradientMoments baseline;
    TemplateGradientMoments chosen;
    REQUIRE_NO_ALLOCATION(template_gradient_moments(tmpl, &baseline, MatchKernel::kBaseline));
    REQUIRE_NO_ALLOCATION(template_gradient_moments(tmpl, &chosen, MatchKernel::kAuto));
    INFO("trial " << trial);
    CHECK((baseline.G.array() == chosen.G.array()).all());
    CHECK((baseline.Mx.array() == chosen.Mx.array()).all());
    CHECK((baseline.My.array() == chosen.My.array()).all());
  }
  CHECK(masked > 30);
}
