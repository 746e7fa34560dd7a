// Proposition 1 of the paper: repeated sensing from the NBV strictly lowers F there until the NBV moves.
#include <catch2/catch.hpp>

#include "core/criterion/view_grid.hpp"
#include "core/estimation/ekf.hpp"
#include "core/geometry/projection.hpp"
#include "tests/core/criterion_fixtures.hpp"

using namespace vantage;

namespace {

constexpr std::size_t kCap = 1024;
constexpr std::int32_t kM = 10;
PrimitivePool<kCap> g_pool;
CriterionModel<kCap> g_model;
CriterionScratch<kCap> g_scratch;
ViewGrid<kM> g_grid;
PrimitiveIndex g_visible[kCap];

GridCell compute_nbv(const PinholeIntrinsics& k) {
  REQUIRE(ok(g_model.refresh(g_pool)));
  REQUIRE(ok(g_grid.update_free_mask(g_model, kDefaultSafetyMargin)));
  REQUIRE(ok(g_grid.evaluate(g_model, k, 0, g_grid.cell_count(), g_scratch)));
  REQUIRE(ok(g_grid.finalize()));
  REQUIRE(g_grid.has_nbv());
  return g_grid.nbv();
}

}  // namespace

TEST_CASE("Proposition 1: EKF updates from the NBV strictly reduce F there until the NBV moves") {
  g_pool.clear();
  test::fill_sphere(g_pool, 400, 4.0, Eigen::Vector3d::Zero(), 77);  // a single convex object
  GridGeometry geometry;
  geometry.cells_per_side = kM;
  geometry.cell_size_m = 5.0;
  geometry.elevation_m = 3.0;
  REQUIRE(ok(g_grid.configure(geometry, Eigen::Vector3d::Zero())));
  const PinholeIntrinsics k = test::test_intrinsics();
  EkfConfig config;

  const GridCell first = compute_nbv(k);
  const Viewpoint nbv_view = g_grid.viewpoint(first);
  double F_previous = g_grid.F(first);
  REQUIRE(F_previous > 0.0);
  bool moved = false;
  int iterations = 0;
  for (; iterations < 40 && !moved; ++iterations) {
    std::size_t count = 0;
    REQUIRE(ok(g_model.visible_primitives(nbv_view, k, g_scratch, Span<PrimitiveIndex>(g_visible, kCap), &count)));
    REQUIRE(count > 0);
    for (std::size_t v = 0; v < count; ++v) {
      Primitive& p = g_pool[g_visible[v]];
      Eigen::Vector2d exact;
      REQUIRE(ok(project(p.X_world, nbv_view, k, &exact)));
      REQUIRE(ok(ekf_update(p, exact, nbv_view, k, config, nullptr)));
    }
    g_pool.mark_modified();
    const GridCell next = compute_nbv(k);
    const double F_now = g_grid.F(first);
    CHECK(F_now < F_previous);  // (10): F(P^{t+1}, nu*) < F(P^t, nu*)
    F_previous = F_now;
    moved = next != first;
  }
  CHECK(moved);
  INFO("updates until the NBV moved: " << iterations);
  CHECK(iterations >= 1);
}
