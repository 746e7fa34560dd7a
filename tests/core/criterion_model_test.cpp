#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>
#include <catch2/catch.hpp>

#include "core/criterion/criterion_model.hpp"
#include "tests/core/criterion_fixtures.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::make_primitive;
using vantage::test::view_from;

namespace {

constexpr std::size_t kCap = 2048;
PrimitivePool<kCap> g_pool;
PrimitivePool<kCap> g_pool_b;
CriterionModel<kCap> g_model;
CriterionModel<kCap> g_model_b;
CriterionScratch<kCap> g_scratch;
CriterionModel<64> g_small_model;

double evaluate_F(const CriterionModelView& model, const Viewpoint& view) {
  double F = -1.0;
  REQUIRE(ok(model.evaluate(view, test::test_intrinsics(), g_scratch, &F)));
  return F;
}

}  // namespace

TEST_CASE("f = ||v^T Psi|| from the eigen-decomposition equals ||Sigma v||") {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Matrix3d Sigma = test::random_covariance(rng, 0.001, 1.0);
    const Eigen::Matrix3d psi = compute_psi(Sigma);
    const Eigen::Vector3d v = Eigen::Vector3d::Random().normalized();
    CHECK((v.transpose() * psi).norm() == Approx((Sigma * v).norm()).epsilon(1e-9));
    CHECK(psi.col(0).norm() >= psi.col(1).norm());
    CHECK(psi.col(1).norm() >= psi.col(2).norm());
  }
}

TEST_CASE("terms of a visible primitive match the paper's formulas") {
  g_pool.clear();
  const Eigen::Matrix3d Sigma = Eigen::Vector3d(0.04, 0.01, 0.0025).asDiagonal();
  PrimitiveIndex index;
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 0.0, 0.0}, Eigen::Vector3f::UnitX(), 0.2f, Sigma, 0.7f), &index)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint view = view_from({20.0, 0.0, 0.0});
  CriterionTerms t;
  REQUIRE(ok(g_model.primitive_terms(view, k, g_scratch, index, &t)));
  CHECK(t.visible);
  // Fronto-parallel disc on the optical axis: g = pi r^2 fx fy / z^2.
  const double r = 0.2f;
  const double g = 3.14159265358979323846 * r * r * k.fx_px * k.fy_px / 400.0;
  CHECK(t.g_px2 == Approx(g).epsilon(1e-4));
  CHECK(t.w == Approx(Sigma.determinant()).epsilon(1e-5));
  CHECK(t.f == Approx(0.04).epsilon(1e-5));  // v = -x, Sigma v = -0.04 x
  CHECK(t.h == Approx(0.7).epsilon(1e-6));
  CHECK(t.contribution == Approx(t.w * std::pow(g, 0.7) / 0.04).epsilon(1e-4));
  CHECK(evaluate_F(g_model, view) == Approx(t.contribution).epsilon(1e-3));
}

TEST_CASE("an elongated-uncertainty primitive's best view is orthogonal to its e1") {
  g_pool.clear();
  // e1 = (1, 1, 0)/sqrt2 carries almost all the uncertainty; h = 0 so g does not enter (g^0 = 1).
  const Eigen::Vector3d e1 = Eigen::Vector3d(1.0, 1.0, 0.0).normalized();
  const Eigen::Matrix3d Sigma = 0.0001 * Eigen::Matrix3d::Identity() + 0.09 * e1 * e1.transpose();
  PrimitiveIndex index;
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 0.0, 0.0}, Eigen::Vector3f::UnitZ(), 0.1f, Sigma, 0.0f), &index)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  // Views on a circle of radius 20 at height 10, all seeing the up-facing disc.
  double best_F = -1.0;
  Eigen::Vector3d best_direction = Eigen::Vector3d::Zero();
  for (int a = 0; a < 72; ++a) {
    const double angle = a * 2.0 * 3.14159265358979323846 / 72.0;
    const Eigen::Vector3d position(20.0 * std::cos(angle), 20.0 * std::sin(angle), 10.0);
    const double F = evaluate_F(g_model, view_from(position));
    REQUIRE(F > 0.0);
    if (F > best_F) {
      best_F = F;
      best_direction = -position.normalized();
    }
  }
  CHECK(std::abs(best_direction.dot(e1)) < 0.05);
  // And the view along e1 is far worse.
  const double along = evaluate_F(g_model, view_from(Eigen::Vector3d(20.0 * e1.x(), 20.0 * e1.y(), 10.0)));
  CHECK(along < 0.2 * best_F);
}

TEST_CASE("a primitive behind a wall of primitives gets g = 0 and adds nothing") {
  g_pool.clear();
  const Eigen::Matrix3d Sigma = 0.01 * Eigen::Matrix3d::Identity();
  PrimitiveIndex hidden;
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 0.0, 0.0}, Eigen::Vector3f::UnitX(), 0.1f, Sigma, 1.0f), &hidden)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  const Viewpoint view = view_from({20.0, 0.0, 0.0});
  CriterionTerms alone;
  REQUIRE(ok(g_model.primitive_terms(view, test::test_intrinsics(), g_scratch, hidden, &alone)));
  CHECK(alone.visible);
  CHECK(alone.g_px2 > 0.0);
  const double F_alone = evaluate_F(g_model, view);
  for (double y = -3.0; y <= 3.0; y += 0.4) {
    for (double z = -3.0; z <= 3.0; z += 0.4) {
      REQUIRE(ok(g_pool.insert(make_primitive({5.0, y, z}, Eigen::Vector3f::UnitX(), 0.3f, Sigma, 1.0f), nullptr)));
    }
  }
  REQUIRE(ok(g_model.refresh(g_pool)));
  CriterionTerms walled;
  REQUIRE(ok(g_model.primitive_terms(view, test::test_intrinsics(), g_scratch, hidden, &walled)));
  CHECK_FALSE(walled.visible);
  CHECK(walled.g_px2 == 0.0);
  CHECK(walled.contribution == 0.0);
  // F now sums the wall only: removing the hidden primitive does not change it.
  const double F_with_hidden = evaluate_F(g_model, view);
  REQUIRE(ok(g_pool.erase(hidden)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  CHECK(evaluate_F(g_model, view) == Approx(F_with_hidden).epsilon(1e-5));
  CHECK(F_alone > 0.0);
}

TEST_CASE("a primitive flagged kUnconsumed adds exactly 0 to F but still occludes") {
  g_pool.clear();
  const Eigen::Matrix3d Sigma = 0.01 * Eigen::Matrix3d::Identity();
  // A few precise primitives on the plane x = 0, a ghost (sigma 3 units) off to the side that owns F,
  // and a ghost in front of one plane primitive, hiding it.
  for (double y = -2.0; y <= 2.0; y += 1.0) {
    REQUIRE(ok(g_pool.insert(make_primitive({0.0, y, 1.0}, Eigen::Vector3f::UnitX(), 0.1f, Sigma, 1.0f), nullptr)));
  }
  PrimitiveIndex hidden, ghost, occluding_ghost;
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 0.0, -2.0}, Eigen::Vector3f::UnitX(), 0.1f, Sigma, 1.0f), &hidden)));
  const Eigen::Matrix3d Sigma_ghost = 9.0 * Eigen::Matrix3d::Identity();
  REQUIRE(ok(g_pool.insert(make_primitive({2.0, 3.0, 0.0}, Eigen::Vector3f::UnitX(), 0.2f, Sigma_ghost, 1.0f), &ghost)));
  REQUIRE(ok(g_pool.insert(make_primitive({4.0, 0.0, -2.0}, Eigen::Vector3f::UnitX(), 0.5f, Sigma_ghost, 1.0f),
                           &occluding_ghost)));
  const Viewpoint view = view_from({20.0, 0.0, 0.0});
  REQUIRE(ok(g_model.refresh(g_pool)));
  const double F_with_ghosts = evaluate_F(g_model, view);
  CriterionTerms terms;
  REQUIRE(ok(g_model.primitive_terms(view, test::test_intrinsics(), g_scratch, ghost, &terms)));
  REQUIRE(terms.visible);
  CHECK(terms.contribution > 0.1 * F_with_ghosts);  // the ghosts own F (w = det Sigma)

  g_pool[ghost].flags |= primitive_flags::kUnconsumed;
  g_pool[occluding_ghost].flags |= primitive_flags::kUnconsumed | primitive_flags::kLostTrack;
  REQUIRE(ok(g_model.refresh(g_pool)));
  REQUIRE(ok(g_model.primitive_terms(view, test::test_intrinsics(), g_scratch, ghost, &terms)));
  CHECK(terms.visible);
  CHECK(terms.w == 0.0);
  CHECK(terms.contribution == 0.0);
  REQUIRE(ok(g_model.primitive_terms(view, test::test_intrinsics(), g_scratch, hidden, &terms)));
  CHECK_FALSE(terms.visible);  // the flagged ghost still occludes
  // F is the plane's alone, in both kernels: the same as with the ghosts erased and the hidden one too.
  double F_flagged[2] = {-1.0, -1.0};
  const CriterionKernel kernels[2] = {CriterionKernel::kBaseline, CriterionKernel::kAvx2Fma};
  for (int k = 0; k < 2; ++k) {
    if (!criterion_kernel_supported(kernels[k])) continue;
    REQUIRE(ok(g_scratch.select_kernel(kernels[k])));
    F_flagged[k] = evaluate_F(g_model, view);
  }
  REQUIRE(ok(g_scratch.select_kernel(CriterionKernel::kAuto)));
  CHECK(F_flagged[0] < 1e-6 * F_with_ghosts);
  REQUIRE(ok(g_pool.erase(ghost)));
  REQUIRE(ok(g_pool.erase(occluding_ghost)));
  REQUIRE(ok(g_pool.erase(hidden)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  const double F_plane = evaluate_F(g_model, view);
  CHECK(F_plane > 0.0);
  for (double F : F_flagged) {
    if (F >= 0.0) CHECK(F == Approx(F_plane).epsilon(1e-4));  // float sums relative to another scale
  }
}

TEST_CASE("invisible primitives add exactly 0 even with h = 0 (no 0^0 = 1)") {
  g_pool.clear();
  const Eigen::Matrix3d Sigma = 0.01 * Eigen::Matrix3d::Identity();
  // Back-facing, behind the camera, outside the image, zero radius: all h = 0.
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 0.0, 0.0}, -Eigen::Vector3f::UnitX(), 0.1f, Sigma, 0.0f), nullptr)));
  REQUIRE(ok(g_pool.insert(make_primitive({30.0, 0.0, 0.0}, Eigen::Vector3f::UnitX(), 0.1f, Sigma, 0.0f), nullptr)));
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 50.0, 0.0}, Eigen::Vector3f::UnitX(), 0.1f, Sigma, 0.0f), nullptr)));
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 1.0, 0.0}, Eigen::Vector3f::UnitX(), 0.0f, Sigma, 0.0f), nullptr)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  CHECK(evaluate_F(g_model, view_from({20.0, 0.0, 0.0})) == 0.0);
  std::size_t count = 99;
  PrimitiveIndex out[8];
  REQUIRE(ok(g_model.visible_primitives(view_from({20.0, 0.0, 0.0}), test::test_intrinsics(), g_scratch,
                                        Span<PrimitiveIndex>(out, 8), &count)));
  CHECK(count == 1);  // the zero-radius one is visible (a point), but has no area to add
  CHECK(out[0] == 3u);
}

TEST_CASE("F does not depend on the order of the primitives in the pool") {
  g_pool.clear();
  g_pool_b.clear();
  test::fill_sphere(g_pool, 1500, 8.0, Eigen::Vector3d::Zero(), 42);
  std::vector<PrimitiveIndex> order(g_pool.index_bound());
  for (PrimitiveIndex i = 0; i < order.size(); ++i) order[i] = i;
  std::mt19937 rng(9);
  std::shuffle(order.begin(), order.end(), rng);
  for (PrimitiveIndex i : order) REQUIRE(ok(g_pool_b.insert(g_pool[i], nullptr)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  REQUIRE(ok(g_model_b.refresh(g_pool_b)));
  for (const Eigen::Vector3d& position : {Eigen::Vector3d(40.0, 0.0, 5.0), Eigen::Vector3d(-10.0, 30.0, 0.0),
                                          Eigen::Vector3d(3.0, -25.0, 12.0)}) {
    const double a = evaluate_F(g_model, view_from(position));
    const double b = evaluate_F(g_model_b, view_from(position));
    CHECK(a > 0.0);
    CHECK(a == Approx(b).epsilon(1e-5));
  }
}

TEST_CASE("F equals the sum of the per-primitive double-precision terms") {
  g_pool.clear();
  test::fill_sphere(g_pool, 300, 5.0, Eigen::Vector3d(1.0, -1.0, 0.5), 17);
  REQUIRE(ok(g_model.refresh(g_pool)));
  const Viewpoint view = view_from({25.0, 10.0, 6.0}, {1.0, -1.0, 0.5});
  double sum = 0.0;
  int visible = 0;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    CriterionTerms t;
    REQUIRE(ok(g_model.primitive_terms(view, test::test_intrinsics(), g_scratch, i, &t)));
    sum += t.contribution;
    visible += t.visible ? 1 : 0;
  }
  CHECK(visible > 60);    // about half the sphere faces the camera, minus grazing self-occlusion
  CHECK(visible < 200);
  CHECK(evaluate_F(g_model, view) == Approx(sum).epsilon(1e-3));
}

TEST_CASE("visible_primitives agrees with the public depth-buffer API") {
  g_pool.clear();
  test::fill_sphere(g_pool, 800, 6.0, Eigen::Vector3d::Zero(), 5);
  // A small sphere in front of the big one occludes part of it.
  test::fill_sphere(g_pool, 200, 1.5, Eigen::Vector3d(10.0, 0.0, 0.0), 6);
  REQUIRE(ok(g_model.refresh(g_pool)));
  const Viewpoint view = view_from({30.0, 2.0, 1.0});
  const PinholeIntrinsics k = test::test_intrinsics();
  static PrimitiveIndex listed[kCap];
  std::size_t count = 0;
  REQUIRE(ok(g_model.visible_primitives(view, k, g_scratch, Span<PrimitiveIndex>(listed, kCap), &count)));
  static DepthBuffer<160, 120> buffer;
  REQUIRE(ok(buffer.configure(view, k)));
  auto front = [&](const Primitive& p) { return p.normal_world.cast<double>().dot(view.position_world - p.X_world) > 0.0; };
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    const Primitive& p = g_pool[i];
    if (front(p)) buffer.splat(p.X_world.cast<float>(), p.normal_world, p.radius);
  }
  std::vector<PrimitiveIndex> expected;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    const Primitive& p = g_pool[i];
    if (buffer.is_visible(p.X_world.cast<float>(), p.normal_world, p.radius)) expected.push_back(i);
  }
  std::vector<PrimitiveIndex> got(listed, listed + count);
  std::sort(got.begin(), got.end());
  CHECK(got == expected);
  CHECK(count > 150);
  // The occluded part of the big sphere is missing: fewer than all its front-facing primitives.
  std::size_t big_front = 0;
  std::size_t big_visible = 0;
  for (PrimitiveIndex i = 0; i < 800; ++i) {
    big_front += front(g_pool[i]) ? 1 : 0;
    big_visible += std::count(got.begin(), got.end(), i) > 0 ? 1 : 0;
  }
  CHECK(big_visible < big_front - 20);
  // Too small an output span: kPoolFull, the full count, and as many indices as fit.
  PrimitiveIndex few[4];
  std::size_t full_count = 0;
  CHECK(g_model.visible_primitives(view, k, g_scratch, Span<PrimitiveIndex>(few, 4), &full_count) == Status::kPoolFull);
  CHECK(full_count == count);
}

TEST_CASE("clusters facing away or outside the frustum are culled") {
  g_pool.clear();
  test::fill_sphere(g_pool, 2000, 8.0, Eigen::Vector3d::Zero(), 1);
  REQUIRE(ok(g_model.refresh(g_pool)));
  CHECK(g_model.cluster_count() == (2000 + kClusterSize - 1) / kClusterSize);
  (void)evaluate_F(g_model, view_from({40.0, 0.0, 0.0}));
  CHECK(g_scratch.clusters_total() == g_model.cluster_count());
  // Coarse clusters at this size (32 of them over a sphere) have wide normal cones; the far side still goes.
  CHECK(g_scratch.clusters_kept() < g_scratch.clusters_total());
  CHECK(g_scratch.clusters_kept() > 0);
  // Looking away from the object: everything culled, F = 0.
  CHECK(evaluate_F(g_model, view_from({40.0, 0.0, 0.0}, {80.0, 0.0, 0.0})) == 0.0);
  CHECK(g_scratch.clusters_kept() == 0);
}

TEST_CASE("refresh rejects bad primitives, names them, and leaves the cache unchanged") {
  g_pool.clear();
  test::fill_sphere(g_pool, 300, 5.0, Eigen::Vector3d::Zero(), 3);
  REQUIRE(ok(g_model.refresh(g_pool)));
  const Viewpoint view = view_from({30.0, 0.0, 0.0});
  const double F_before = evaluate_F(g_model, view);
  const std::size_t count_before = g_model.primitive_count();

  Primitive not_spd = g_pool[0];
  not_spd.Sigma_world = Eigen::Vector3d(0.01, -0.01, 0.01).asDiagonal();
  PrimitiveIndex bad;
  REQUIRE(ok(g_pool.insert(not_spd, &bad)));
  CHECK(g_model.refresh(g_pool) == Status::kNotSpd);
  CHECK(g_model.rejected_index() == bad);
  CHECK(g_model.primitive_count() == count_before);
  CHECK(evaluate_F(g_model, view) == F_before);

  g_pool[bad].Sigma_world = 0.01 * Eigen::Matrix3d::Identity();
  g_pool[bad].saliency_h = 1.5f;
  CHECK(g_model.refresh(g_pool) == Status::kInvalidArgument);
  g_pool[bad].saliency_h = 0.5f;
  g_pool[bad].X_world.x() = std::nan("");  // pools refuse NaN on insert; a buggy writer may still set it
  CHECK(g_model.refresh(g_pool) == Status::kNonFiniteInput);
  CHECK(g_model.rejected_index() == bad);
  g_pool[bad].X_world.x() = 0.0;
  g_pool[bad].normal_world = Eigen::Vector3f::Zero();
  CHECK(g_model.refresh(g_pool) == Status::kInvalidArgument);
  CHECK(evaluate_F(g_model, view) == F_before);

  // More alive primitives than the cache holds: kPoolFull.
  g_pool[bad].normal_world = Eigen::Vector3f::UnitZ();
  CHECK(g_small_model.refresh(g_pool) == Status::kPoolFull);
  CHECK(g_small_model.primitive_count() == 0);
}

TEST_CASE("bad poses and intrinsics give an error status and leave F_out alone") {
  g_pool.clear();
  test::fill_sphere(g_pool, 100, 5.0, Eigen::Vector3d::Zero(), 3);
  REQUIRE(ok(g_model.refresh(g_pool)));
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint good = view_from({30.0, 0.0, 0.0});
  double F = 123.0;
  Viewpoint nan_pose = good;
  nan_pose.R_world_cam(1, 1) = std::nan("");
  CHECK(g_model.evaluate(nan_pose, k, g_scratch, &F) == Status::kNonFiniteInput);
  Viewpoint inf_pose = good;
  inf_pose.position_world.z() = INFINITY;
  CHECK(g_model.evaluate(inf_pose, k, g_scratch, &F) == Status::kNonFiniteInput);
  PinholeIntrinsics nan_k = k;
  nan_k.cy_px = std::nan("");
  CHECK(g_model.evaluate(good, nan_k, g_scratch, &F) == Status::kNonFiniteInput);
  PinholeIntrinsics zero = k;
  zero.height_px = 0;
  CHECK(g_model.evaluate(good, zero, g_scratch, &F) == Status::kInvalidImage);
  CHECK(F == 123.0);
  std::size_t count = 7;
  PrimitiveIndex out[4];
  CHECK(g_model.visible_primitives(nan_pose, k, g_scratch, Span<PrimitiveIndex>(out, 4), &count) ==
        Status::kNonFiniteInput);
  CHECK(count == 0);
  CriterionTerms t;
  CHECK(g_model.primitive_terms(good, zero, g_scratch, 0, &t) == Status::kInvalidImage);
  CHECK(g_model.primitive_terms(good, k, g_scratch, 5000, &t) == Status::kNotFound);
  // A scratch smaller than the model.
  static CriterionScratch<64> small_scratch;
  CHECK(g_model.evaluate(good, k, small_scratch, &F) == Status::kInvalidArgument);
  CHECK(F == 123.0);
}

TEST_CASE("criterion entry points do not allocate") {
  g_pool.clear();
  test::fill_sphere(g_pool, 500, 5.0, Eigen::Vector3d::Zero(), 8);
  const PinholeIntrinsics k = test::test_intrinsics();
  const Viewpoint view = view_from({30.0, 5.0, 3.0});
  double F = 0.0;
  static PrimitiveIndex out[kCap];
  std::size_t count = 0;
  CriterionTerms t;
  Status s1 = Status::kNotFound, s2 = Status::kNotFound, s3 = Status::kNotFound, s4 = Status::kNotFound;
  REQUIRE_NO_ALLOCATION(s1 = g_model.refresh(g_pool); s2 = g_model.evaluate(view, k, g_scratch, &F);
                        s3 = g_model.visible_primitives(view, k, g_scratch, Span<PrimitiveIndex>(out, kCap), &count);
                        s4 = g_model.primitive_terms(view, k, g_scratch, 0, &t));
  CHECK(ok(s1));
  CHECK(ok(s2));
  CHECK(ok(s3));
  CHECK(ok(s4));
  CHECK(F > 0.0);
  CHECK(count > 0);
}
