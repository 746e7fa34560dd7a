#include <cmath>
#include <cstdint>
#include <vector>

#include <catch2/catch.hpp>

#include "core/frontend/ncc.hpp"
#include "core/frontend/patch_search.hpp"
#include "tests/core/frontend_test_scene.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::TexturedPlane;

namespace {

// An image of value noise, optionally shifted by (dx, dy) pixels (sampled analytically, so subpixel).
std::vector<std::uint8_t> noise_image(std::int32_t w, std::int32_t h, double dx, double dy, double feature_px = 3.0) {
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(w) * h);
  for (std::int32_t y = 0; y < h; ++y) {
    for (std::int32_t x = 0; x < w; ++x) {
      const double v = vantage::test::value_noise(x - dx, y - dy, feature_px);
      pixels[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint8_t>(std::lround(20.0 + 210.0 * v));
    }
  }
  return pixels;
}

}  // namespace

TEST_CASE("NCC is 1 for the same patch, -1 for its negative, and invariant to gain and offset") {
  std::array<std::uint8_t, kPatchPixels> patch{};
  for (int i = 0; i < kPatchPixels; ++i) patch[i] = static_cast<std::uint8_t>((i * 37) % 101 + 50);
  std::vector<std::uint8_t> pixels(kPatchPixels * 3);
  for (int y = 0; y < kPatchSize; ++y) {
    for (int x = 0; x < kPatchSize; ++x) {
      const int v = patch[y * kPatchSize + x];
      pixels[y * kPatchSize * 3 + x] = static_cast<std::uint8_t>(v);
      pixels[y * kPatchSize * 3 + kPatchSize + x] = static_cast<std::uint8_t>(255 - v);
      pixels[y * kPatchSize * 3 + 2 * kPatchSize + x] = static_cast<std::uint8_t>(v / 2 + 20);
    }
  }
  const GrayImageView image{pixels.data(), kPatchSize * 3, kPatchSize, kPatchSize * 3};
  NccTemplate tmpl;
  make_template(patch, &tmpl);
  CHECK(ncc_at(image, kPatchRadius, kPatchRadius, tmpl) == Approx(1.0f).margin(1e-5));
  CHECK(ncc_at(image, kPatchSize + kPatchRadius, kPatchRadius, tmpl) == Approx(-1.0f).margin(1e-5));
  // Integer halving loses a little: the correlation stays near 1.
  CHECK(ncc_at(image, 2 * kPatchSize + kPatchRadius, kPatchRadius, tmpl) > 0.99f);
}

TEST_CASE("NCC against a flat image patch or with a flat template is -1") {
  std::vector<std::uint8_t> flat(kPatchPixels, 128);
  const GrayImageView image{flat.data(), kPatchSize, kPatchSize, kPatchSize};
  std::array<std::uint8_t, kPatchPixels> textured{};
  for (int i = 0; i < kPatchPixels; ++i) textured[i] = static_cast<std::uint8_t>(i * 5);
  NccTemplate tmpl;
  make_template(textured, &tmpl);
  CHECK(ncc_at(image, kPatchRadius, kPatchRadius, tmpl) == -1.0f);
  std::array<std::uint8_t, kPatchPixels> constant{};
  constant.fill(77);
  make_template(constant, &tmpl);
  CHECK(tmpl.norm == 0.0f);
  std::vector<std::uint8_t> pixels(textured.begin(), textured.end());
  const GrayImageView textured_image{pixels.data(), kPatchSize, kPatchSize, kPatchSize};
  CHECK(ncc_at(textured_image, kPatchRadius, kPatchRadius, tmpl) == -1.0f);
}

TEST_CASE("the parabola fit recovers the vertex of a sampled parabola") {
  for (double vertex : {-0.4, -0.13, 0.0, 0.27, 0.45}) {
    auto f = [&](double x) { return 0.9 - 0.3 * (x - vertex) * (x - vertex); };
    CHECK(parabola_peak_offset(f(-1), f(0), f(1)) == Approx(vertex).margin(1e-12));
  }
  CHECK(parabola_peak_offset(0.9, 0.5, 0.1) == 0.0);  // not a maximum at the centre
}

TEST_CASE("a window search finds a subpixel shift of a textured image") {
  const std::int32_t w = 64;
  const std::int32_t h = 48;
  const auto reference = noise_image(w, h, 0.0, 0.0);
  const GrayImageView ref_view{reference.data(), w, h, w};
  std::array<float, window_scratch_size(8)> scratch{};
  double worst = 0.0;
  for (const auto& shift : {Eigen::Vector2d(0.3, -0.2), Eigen::Vector2d(-1.4, 0.7), Eigen::Vector2d(2.25, 1.6)}) {
    const auto moved = noise_image(w, h, shift.x(), shift.y());
    const GrayImageView moved_view{moved.data(), w, h, w};
    for (std::int32_t y = 12; y < 36; y += 6) {
      for (std::int32_t x = 12; x < 52; x += 6) {
        std::array<std::uint8_t, kPatchPixels> patch{};
        extract_patch(ref_view, x, y, &patch);
        NccTemplate tmpl;
        make_template(patch, &tmpl);
        WindowQuery query;
        query.predicted_px = Eigen::Vector2d(x, y);
        query.S_inv = Eigen::Matrix2d::Identity() / (1.5 * 1.5);
        query.half_width_px = 5;
        query.half_height_px = 5;
        Eigen::Vector2d found;
        float best = 0.0f;
        MatchOutcome outcome = MatchOutcome::kNoRoom;
        REQUIRE_NO_ALLOCATION(outcome = search_window(moved_view, tmpl, query, MatchConfig{},
                                                      Span<float>(scratch.data(), scratch.size()), &found, &best));
        REQUIRE(outcome == MatchOutcome::kMatched);
        worst = std::max(worst, (found - Eigen::Vector2d(x, y) - shift).norm());
      }
    }
  }
  // The parabola alone locks toward integers (0.37 px worst here); the photometric refinement does not.
  CHECK(worst < 0.1);
}

TEST_CASE("a window search rejects a periodic texture as ambiguous and a flat image as no match") {
  const std::int32_t w = 48;
  const std::int32_t h = 32;
  std::vector<std::uint8_t> stripes(static_cast<std::size_t>(w) * h);
  for (std::int32_t y = 0; y < h; ++y) {
    for (std::int32_t x = 0; x < w; ++x) {
      stripes[static_cast<std::size_t>(y) * w + x] =
          static_cast<std::uint8_t>(128 + 100 * std::sin(2.0 * 3.14159265358979 * x / 4.0) + 20 * std::sin(y * 0.9));
    }
  }
  const GrayImageView image{stripes.data(), w, h, w};
  std::array<std::uint8_t, kPatchPixels> patch{};
  extract_patch(image, 24, 16, &patch);
  NccTemplate tmpl;
  make_template(patch, &tmpl);
  WindowQuery query;
  query.predicted_px = Eigen::Vector2d(24.3, 16.0);
  query.S_inv = Eigen::Matrix2d::Identity() / 9.0;
  query.half_width_px = 8;
  query.half_height_px = 3;
  std::array<float, window_scratch_size(8)> scratch{};
  Eigen::Vector2d found;
  float best = 0.0f;
  CHECK(search_window(image, tmpl, query, MatchConfig{}, Span<float>(scratch.data(), scratch.size()), &found, &best) ==
        MatchOutcome::kAmbiguous);
  std::vector<std::uint8_t> flat(static_cast<std::size_t>(w) * h, 90);
  const GrayImageView flat_image{flat.data(), w, h, w};
  CHECK(search_window(flat_image, tmpl, query, MatchConfig{}, Span<float>(scratch.data(), scratch.size()), &found,
                      &best) == MatchOutcome::kBelowThreshold);
}

TEST_CASE("an epipolar search within the depth range finds the true correspondence on a textured plane") {
  const PinholeIntrinsics k = vantage::test::small_intrinsics();
  TexturedPlane plane;
  const Viewpoint first = vantage::test::looking_at_origin({40.0, 0.0, 0.0});
  const Viewpoint second = vantage::test::looking_at_origin({39.9, 2.0, 0.3});
  std::vector<std::uint8_t> a;
  std::vector<std::uint8_t> b;
  vantage::test::render_plane(plane, first, k, &a);
  vantage::test::render_plane(plane, second, k, &b);
  const GrayImageView image_a = vantage::test::view_of(a, k);
  const GrayImageView image_b = vantage::test::view_of(b, k);
  std::array<float, 512> ncc{};
  std::array<std::int32_t, 1024> xy{};
  int matched = 0;
  int tried = 0;
  double sum_sq = 0.0;
  for (std::int32_t y = 20; y < 100; y += 10) {
    for (std::int32_t x = 20; x < 140; x += 10) {
      std::array<std::uint8_t, kPatchPixels> patch{};
      extract_patch(image_a, x, y, &patch);
      NccTemplate tmpl;
      make_template(patch, &tmpl);
      if (tmpl.stddev_gray < 6.0f) continue;
      ++tried;
      EpipolarQuery query;
      query.uv_first_px = Eigen::Vector2d(x, y);
      query.first = first;
      query.second = second;
      query.depth_min = 25.0;
      query.depth_max = 55.0;
      Eigen::Vector2d found;
      float best = 0.0f;
      MatchOutcome outcome = MatchOutcome::kNoRoom;
      REQUIRE_NO_ALLOCATION(outcome = search_epipolar(image_b, tmpl, query, k, MatchConfig{},
                                                      Span<float>(ncc.data(), ncc.size()),
                                                      Span<std::int32_t>(xy.data(), xy.size()), &found, &best));
      if (outcome != MatchOutcome::kMatched) continue;
      ++matched;
      Eigen::Vector3d X;
      REQUIRE(plane.intersect(query.uv_first_px, first, k, &X));
      Eigen::Vector2d truth;
      REQUIRE(ok(project(X, second, k, &truth)));
      sum_sq += (found - truth).squaredNorm();
    }
  }
  REQUIRE(tried > 50);
  CHECK(matched > 0.8 * tried);
  CHECK(std::sqrt(sum_sq / matched) < 0.15);
}
