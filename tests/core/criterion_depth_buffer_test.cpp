#include <array>
#include <cmath>
#include <cstdint>

#include <catch2/catch.hpp>

#include "core/criterion/depth_buffer.hpp"
#include "tests/core/criterion_fixtures.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::view_from;

namespace {

DepthBuffer<160, 120> g_buffer;

// Splats a square wall of discs in the plane x = x_wall, facing +x, spacing 0.4 and radius 0.3.
void splat_wall(DepthBufferView& buffer, float x_wall, float half_size) {
  for (float y = -half_size; y <= half_size; y += 0.4f) {
    for (float z = -half_size; z <= half_size; z += 0.4f) {
      buffer.splat(Eigen::Vector3f(x_wall, y, z), Eigen::Vector3f::UnitX(), 0.3f);
    }
  }
}

}  // namespace

TEST_CASE("a disc behind a wall of discs is not visible, without the wall it is") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  const Eigen::Vector3f X = Eigen::Vector3f::Zero();
  const Eigen::Vector3f n = Eigen::Vector3f::UnitX();
  g_buffer.splat(X, n, 0.1f);
  CHECK(g_buffer.is_visible(X, n, 0.1f));
  splat_wall(g_buffer, 5.0f, 3.0f);
  CHECK_FALSE(g_buffer.is_visible(X, n, 0.1f));
  // A wall closer than the tolerance (2 radii) behind... in front: the disc still counts as the surface.
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  g_buffer.splat(Eigen::Vector3f(0.15f, 0.0f, 0.0f), n, 0.1f);
  CHECK(g_buffer.is_visible(X, n, 0.1f));
}

TEST_CASE("neighbouring discs of one tilted surface do not occlude each other") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  // A plane through the origin tilted 70 degrees away from the camera, densely sampled.
  const float tilt = 70.0f * 3.14159265f / 180.0f;
  const Eigen::Vector3f n(std::cos(tilt), std::sin(tilt), 0.0f);
  const Eigen::Vector3f along(-std::sin(tilt), std::cos(tilt), 0.0f);
  for (int i = -20; i <= 20; ++i) {
    for (int j = -20; j <= 20; ++j) {
      g_buffer.splat(along * (0.1f * i) + Eigen::Vector3f::UnitZ() * (0.1f * j), n, 0.07f);
    }
  }
  int visible = 0;
  int total = 0;
  for (int i = -18; i <= 18; ++i) {
    for (int j = -18; j <= 18; ++j) {
      ++total;
      visible += g_buffer.is_visible(along * (0.1f * i) + Eigen::Vector3f::UnitZ() * (0.1f * j), n, 0.07f) ? 1 : 0;
    }
  }
  CHECK(visible == total);
}

TEST_CASE("back-facing, behind-camera and out-of-image discs are not visible") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f::Zero(), -Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f(30.0f, 0.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f(0.0f, 40.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.splat(Eigen::Vector3f(30.0f, 0.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
  CHECK_FALSE(g_buffer.is_visible(Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.1f));
}

TEST_CASE("a large disc covers its footprint, a small one only its centre pixel") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_buffer.configure(view_from({20.0, 0.0, 0.0}), k)));
  const BufferCamera& cam = g_buffer.camera();
  CHECK(cam.width_px == 160);
  CHECK(cam.fx_px == Approx(k.fx_px / 4.0));
  g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 1.0f);  // ~7 buffer px radius at 20
  const float radius_px = static_cast<float>(1.0 * cam.fx_px / 20.0);
  const std::int32_t cu = static_cast<std::int32_t>(std::lround(cam.cx_px));
  const std::int32_t cv = static_cast<std::int32_t>(std::lround(cam.cy_px));
  CHECK(g_buffer.inverse_depth_at(cu, cv) == Approx(1.0f / 20.0f).epsilon(1e-3));
  CHECK(g_buffer.inverse_depth_at(cu + static_cast<int>(radius_px) - 1, cv) > 0.0f);
  CHECK(g_buffer.inverse_depth_at(cu + static_cast<int>(radius_px) + 2, cv) == 0.0f);
  g_buffer.clear();
  g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.01f);
  int written = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) written += g_buffer.inverse_depth_at(x, y) > 0.0f ? 1 : 0;
  }
  CHECK(written == 1);
}

TEST_CASE("bad pose or intrinsics leave the depth buffer unchanged") {
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint good = view_from({20.0, 0.0, 0.0});
  REQUIRE(ok(g_buffer.configure(good, k)));
  g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f);
  const BufferCamera before = g_buffer.camera();
  Viewpoint nan_pose = good;
  nan_pose.position_world.x() = std::nan("");
  CHECK(g_buffer.configure(nan_pose, k) == Status::kNonFiniteInput);
  Viewpoint not_rotation = good;
  not_rotation.R_world_cam *= 2.0;
  CHECK(g_buffer.configure(not_rotation, k) == Status::kInvalidArgument);
  PinholeIntrinsics inf_k = k;
  inf_k.fx_px = INFINITY;
  CHECK(g_buffer.configure(good, inf_k) == Status::kNonFiniteInput);
  PinholeIntrinsics empty = k;
  empty.width_px = 0;
  CHECK(g_buffer.configure(good, empty) == Status::kInvalidImage);
  CHECK(g_buffer.camera().fx_px == before.fx_px);
  CHECK(g_buffer.is_visible(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f));
  CHECK(g_buffer.set_tolerance_radii(-1.0f) == Status::kInvalidArgument);
  CHECK(g_buffer.set_tolerance_radii(std::nanf("")) == Status::kNonFiniteInput);
  CHECK(g_buffer.tolerance_radii() == kDefaultToleranceRadii);
}

TEST_CASE("depth buffer entry points do not allocate") {
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint view = view_from({20.0, 0.0, 0.0});
  bool visible = false;
  REQUIRE_NO_ALLOCATION(Status s = g_buffer.configure(view, k); (void)s; g_buffer.clear();
                        g_buffer.splat(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f);
                        visible = g_buffer.is_visible(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f));
  CHECK(visible);
}

namespace {

DepthBuffer<160, 120> g_batched;

// Random discs around the origin, some grazing, back-facing, behind the camera, outside the image, huge
// or non-finite, so every branch of project_disc and splat runs in the lanes.
struct RandomDisc {
  Eigen::Vector3f X;
  Eigen::Vector3f n;
  float radius;
};

RandomDisc random_disc(std::uint32_t* state) {
  auto next = [state]() {
    *state = *state * 1664525u + 1013904223u;
    return static_cast<float>(*state >> 8) / 16777216.0f;  // [0, 1)
  };
  // One draw per statement: the order in which a call's arguments are evaluated is unspecified (GCC
  // draws them right to left on x86-64, left to right on aarch64, which gave the two different scenes).
  float draws[6];
  for (float& draw : draws) draw = next();
  RandomDisc d;
  d.X = Eigen::Vector3f(30.0f * draws[0] - 15.0f, 12.0f * draws[1] - 6.0f, 12.0f * draws[2] - 6.0f);
  d.n = Eigen::Vector3f(2.0f * draws[3] - 1.0f, 2.0f * draws[4] - 1.0f, 2.0f * draws[5] - 1.0f).normalized();
  d.radius = next() < 0.1f ? 3.0f * next() : 0.2f * next();
  const float special = next();
  if (special < 0.02f) d.X.y() = std::nanf("");
  if (special > 0.98f) d.radius = -0.1f;
  if (special > 0.96f && special <= 0.98f) d.n.z() = INFINITY;
  return d;
}

}  // namespace

TEST_CASE("batched splats and visibility tests equal the disc-by-disc ones") {
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint view = view_from({20.0, 3.0, 2.0});
  REQUIRE(ok(g_buffer.configure(view, k)));
  REQUIRE(ok(g_batched.configure(view, k)));
  std::uint32_t state = 7u;
  std::int32_t written_single = 0;
  std::int32_t written_batched = 0;
  DiscBatch batch;
  for (int d = 0; d < 2000; ++d) {
    const RandomDisc disc = random_disc(&state);
    written_single += g_buffer.splat(disc.X, disc.n, disc.radius) ? 1 : 0;
    batch.push(disc.X, disc.n, disc.radius);
    // Partial batches too: flush after 1, 2, 3 or 4 discs.
    if (batch.full() || d % 7 == 0) written_batched += g_batched.splat_batch(batch);
    CHECK(batch.count < kDiscBatchSize);
  }
  written_batched += g_batched.splat_batch(batch);
  CHECK(batch.count == 0);
  CHECK(written_single > 1000);
  CHECK(written_batched == written_single);
  std::int32_t differing = 0;
  for (std::int32_t y = 0; y < g_buffer.height(); ++y) {
    for (std::int32_t x = 0; x < g_buffer.width(); ++x) {
      const float a = g_buffer.inverse_depth_at(x, y);
      const float b = g_batched.inverse_depth_at(x, y);
      // The same operations in the same order: equal bits where the compiler does not fuse a * b + c
      // differently in the two (x86-64's baseline has no FMA; aarch64 may fuse).
      if (std::abs(a - b) > 1e-5f * std::abs(a)) ++differing;
    }
  }
  CHECK(differing == 0);
  // Visibility of more random discs against the splatted scene, in batches of every size.
  std::int32_t agree = 0;
  std::int32_t visible_count = 0;
  std::int32_t tested = 0;
  for (int round = 0; round < 500; ++round) {
    DiscBatch query;
    std::array<bool, kDiscBatchSize> single{};
    const std::int32_t size = 1 + round % kDiscBatchSize;
    for (std::int32_t lane = 0; lane < size; ++lane) {
      RandomDisc disc = random_disc(&state);
      // Two in three face the camera (the rest are random, half of them back-facing).
      const Eigen::Vector3f camera(20.0f, 3.0f, 2.0f);
      if ((round + lane) % 3 != 0 && disc.n.allFinite()) disc.n = (camera - disc.X).normalized();
      // One in three of those moved a quarter of the way to the camera, in front of most of the splatted
      // scene, so that both outcomes are common.
      if ((round + lane) % 3 == 1) disc.X = camera + 0.25f * (disc.X - camera);
      single[lane] = g_buffer.is_visible(disc.X, disc.n, disc.radius);
      query.push(disc.X, disc.n, disc.radius);
    }
    std::array<bool, kDiscBatchSize> batched{};
    batched.fill(true);
    g_buffer.is_visible_batch(query, &batched);
    for (std::int32_t lane = 0; lane < kDiscBatchSize; ++lane) {
      if (lane >= size) {
        CHECK_FALSE(batched[lane]);
        continue;
      }
      ++tested;
      agree += batched[lane] == single[lane] ? 1 : 0;
      visible_count += single[lane] ? 1 : 0;
    }
  }
  CHECK(visible_count >= 100);  // both outcomes are common (201 visible of 1,250 on x86-64)
  CHECK(tested - visible_count >= 100);
#if defined(__x86_64__)
  CHECK(agree == tested);
#else
  CHECK(agree >= tested - 2);  // a fused multiply-add may move a disc across the tolerance
#endif
  // Not configured: nothing written, nothing visible.
  DepthBuffer<8, 8> unconfigured;
  DiscBatch one;
  one.push(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f);
  std::array<bool, kDiscBatchSize> flags{};
  flags.fill(true);
  unconfigured.is_visible_batch(one, &flags);
  CHECK_FALSE(flags[0]);
  CHECK(unconfigured.splat_batch(one) == 0);
  CHECK(one.count == 0);
}

TEST_CASE("batched depth buffer entry points do not allocate") {
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_batched.configure(view_from({20.0, 0.0, 0.0}), k)));
  DiscBatch batch;
  batch.push(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 0.5f);
  batch.push(Eigen::Vector3f(0.0f, 1.0f, 0.0f), Eigen::Vector3f::UnitX(), 0.5f);
  std::array<bool, kDiscBatchSize> visible{};
  std::int32_t written = 0;
  REQUIRE_NO_ALLOCATION(written = g_batched.splat_batch(batch); batch.push(Eigen::Vector3f::Zero(),
                                                                          Eigen::Vector3f::UnitX(), 0.5f);
                        g_batched.is_visible_batch(batch, &visible));
  CHECK(written == 2);
  CHECK(visible[0]);
}
