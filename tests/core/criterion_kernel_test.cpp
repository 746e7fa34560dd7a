// The criterion's view loops (core/criterion/block_kernel*): the run-time kernel choice, agreement of the
// baseline and AVX2+FMA builds, and the splats of every footprint class (single pixel, 2 x 2 quad, general,
// centre outside the image) against the public DepthBuffer API.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <catch2/catch.hpp>

#include "core/criterion/criterion_model.hpp"
#include "tests/core/criterion_fixtures.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::make_primitive;
using vantage::test::view_from;

namespace {

constexpr std::size_t kCap = 4096;
PrimitivePool<kCap> g_pool;
CriterionModel<kCap> g_model;
CriterionScratch<kCap> g_scratch_a;
CriterionScratch<kCap> g_scratch_b;
DepthBuffer<160, 120> g_buffer;

// A sphere of primitives with footprints of random radius (0.03 to 0.4 units: 0.2 to 3 buffer pixels at
// 20 units), and a small sphere in front of it as an occluder.
void fill_mixed_model() {
  g_pool.clear();
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> radius(0.03f, 0.4f);
  const int count = 3000;
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    const double r = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d n(r * std::cos(golden * i), r * std::sin(golden * i), z);
    PrimitiveIndex index;
    REQUIRE(ok(g_pool.insert(make_primitive(6.0 * n, n.cast<float>(), radius(rng),
                                            test::random_covariance(rng, 0.01, 0.2), 0.1f + 0.8f * (i % 7) / 6.0f),
                             &index)));
  }
  test::fill_sphere(g_pool, 300, 1.5, Eigen::Vector3d(9.0, 1.0, 0.0), 4);
  REQUIRE(ok(g_model.refresh(g_pool)));
}

// Far (mostly single pixels), middle (quads), near (general splats, the sphere larger than the image).
const Eigen::Vector3d kViewPositions[] = {{60.0, 10.0, 5.0}, {24.0, 3.0, 2.0}, {20.0, -8.0, 4.0},
                                          {12.0, 2.0, 1.0},  {-15.0, 9.0, -3.0}};

std::vector<PrimitiveIndex> visible_list(const Viewpoint& view, CriterionScratchView& scratch) {
  static PrimitiveIndex listed[kCap];
  std::size_t count = 0;
  REQUIRE(ok(g_model.visible_primitives(view, test::test_intrinsics(), scratch, Span<PrimitiveIndex>(listed, kCap),
                                        &count)));
  std::vector<PrimitiveIndex> v(listed, listed + count);
  std::sort(v.begin(), v.end());
  return v;
}

}  // namespace

TEST_CASE("the kernel choice: kAuto runs the best supported build, unsupported builds are refused") {
  static CriterionScratch<64> scratch;
  const CriterionKernel best = best_criterion_kernel();
  CHECK(scratch.kernel() == best);
  CHECK(criterion_kernel_supported(CriterionKernel::kAuto));
  CHECK(criterion_kernel_supported(CriterionKernel::kBaseline));
  CHECK(criterion_kernel_supported(best));
  REQUIRE(ok(scratch.select_kernel(CriterionKernel::kBaseline)));
  CHECK(scratch.kernel() == CriterionKernel::kBaseline);
  if (criterion_kernel_supported(CriterionKernel::kAvx2Fma)) {
    CHECK(best == CriterionKernel::kAvx2Fma);
    REQUIRE(ok(scratch.select_kernel(CriterionKernel::kAvx2Fma)));
    CHECK(scratch.kernel() == CriterionKernel::kAvx2Fma);
  } else {
    CHECK(best == CriterionKernel::kBaseline);
    CHECK(scratch.select_kernel(CriterionKernel::kAvx2Fma) == Status::kInvalidArgument);
    CHECK(scratch.kernel() == CriterionKernel::kBaseline);
  }
#if !defined(__x86_64__)
  CHECK_FALSE(criterion_kernel_supported(CriterionKernel::kAvx2Fma));
#endif
  REQUIRE(ok(scratch.select_kernel(CriterionKernel::kAuto)));
  CHECK(scratch.kernel() == best);
  CHECK(std::strcmp(to_string(CriterionKernel::kBaseline), to_string(CriterionKernel::kAvx2Fma)) != 0);
  CHECK(std::strcmp(to_string(CriterionKernel::kAuto), to_string(CriterionKernel::kBaseline)) != 0);
}

TEST_CASE("every footprint class splats as the public DepthBuffer API does, in each kernel") {
  fill_mixed_model();
  const PinholeIntrinsics k = test::test_intrinsics();
  std::size_t single = 0, quad = 0, general = 0, outside = 0;  // splats of each class over the views
  for (const CriterionKernel kernel : {CriterionKernel::kBaseline, CriterionKernel::kAvx2Fma}) {
    if (!criterion_kernel_supported(kernel)) continue;
    REQUIRE(ok(g_scratch_a.select_kernel(kernel)));
    for (const Eigen::Vector3d& position : kViewPositions) {
      CAPTURE(to_string(kernel), position.transpose());
      const Viewpoint view = view_from(position);
      const std::vector<PrimitiveIndex> got = visible_list(view, g_scratch_a);
      // Reference: the public API, every front-facing primitive splatted, then tested one by one.
      REQUIRE(ok(g_buffer.configure(view, k)));
      const float f_max = static_cast<float>(std::max(k.fx_px, k.fy_px)) * 160.0f / 640.0f;
      for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
        const Primitive& p = g_pool[i];
        const Eigen::Vector3d to_camera = view.position_world - p.X_world;
        if (p.normal_world.cast<double>().dot(to_camera) <= 0.0) continue;
        if (!g_buffer.splat(p.X_world.cast<float>(), p.normal_world, p.radius)) continue;
        const Eigen::Vector3d Xc = view.R_world_cam.transpose() * -to_camera;
        const double u = k.fx_px * Xc.x() / Xc.z() + k.cx_px;
        const double v = k.fy_px * Xc.y() / Xc.z() + k.cy_px;
        const double r_px = p.radius * f_max / Xc.z();
        if (u < -0.5 || v < -0.5 || u >= k.width_px - 0.5 || v >= k.height_px - 0.5) {
          ++outside;
        } else {
          ++(r_px < 0.5 ? single : r_px < 1.0 ? quad : general);
        }
      }
      std::vector<PrimitiveIndex> expected;
      for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
        const Primitive& p = g_pool[i];
        if (g_buffer.is_visible(p.X_world.cast<float>(), p.normal_world, p.radius)) expected.push_back(i);
      }
      CHECK(got == expected);
      // The buffers: same pixels written, same inverse depths to float rounding.
      std::size_t written = 0, mismatched = 0;
      for (std::int32_t y = 0; y < 120; ++y) {
        for (std::int32_t x = 0; x < 160; ++x) {
          const float a = g_scratch_a.depth().inverse_depth_at(x, y);
          const float b = g_buffer.inverse_depth_at(x, y);
          written += b > 0.0f ? 1 : 0;
          mismatched += std::abs(a - b) <= 1e-5f * b ? 0 : 1;
        }
      }
      CHECK(mismatched == 0);
      CHECK(written > 100);
    }
  }
  // The views exercise every class (counted once per kernel).
  CHECK(single > 100);
  CHECK(quad > 100);
  CHECK(general > 100);
  CHECK(outside > 10);
  REQUIRE(ok(g_scratch_a.select_kernel(CriterionKernel::kAuto)));
}

TEST_CASE("the baseline and AVX2+FMA kernels give the same F, visible set and culling") {
  if (!criterion_kernel_supported(CriterionKernel::kAvx2Fma)) {
    WARN("no AVX2+FMA on this CPU or architecture: only the baseline kernel runs here");
    CHECK(best_criterion_kernel() == CriterionKernel::kBaseline);
    return;
  }
  fill_mixed_model();
  REQUIRE(ok(g_scratch_a.select_kernel(CriterionKernel::kBaseline)));
  REQUIRE(ok(g_scratch_b.select_kernel(CriterionKernel::kAvx2Fma)));
  const PinholeIntrinsics k = test::test_intrinsics();
  for (const Eigen::Vector3d& position : kViewPositions) {
    CAPTURE(position.transpose());
    const Viewpoint view = view_from(position);
    double F_baseline = 0.0, F_avx2 = 0.0;
    REQUIRE(ok(g_model.evaluate(view, k, g_scratch_a, &F_baseline)));
    REQUIRE(ok(g_model.evaluate(view, k, g_scratch_b, &F_avx2)));
    CHECK(F_baseline > 0.0);
    CHECK(F_avx2 == Approx(F_baseline).epsilon(1e-5));
    CHECK(g_scratch_a.clusters_kept() == g_scratch_b.clusters_kept());
    CHECK(g_scratch_a.candidates() == g_scratch_b.candidates());
    CHECK(visible_list(view, g_scratch_a) == visible_list(view, g_scratch_b));
  }
  REQUIRE(ok(g_scratch_a.select_kernel(CriterionKernel::kAuto)));
  REQUIRE(ok(g_scratch_b.select_kernel(CriterionKernel::kAuto)));
}

TEST_CASE("kernel selection and evaluation with either kernel do not allocate") {
  fill_mixed_model();
  const Viewpoint view = view_from(kViewPositions[1]);
  double F = 0.0;
  Status s1 = Status::kNotFound, s2 = Status::kNotFound;
  REQUIRE_NO_ALLOCATION(s1 = g_scratch_a.select_kernel(CriterionKernel::kBaseline);
                        s2 = g_model.evaluate(view, test::test_intrinsics(), g_scratch_a, &F));
  CHECK(ok(s1));
  CHECK(ok(s2));
  CHECK(F > 0.0);
  REQUIRE(ok(g_scratch_a.select_kernel(CriterionKernel::kAuto)));
}
