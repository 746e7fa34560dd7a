#include <cmath>

#include <catch2/catch.hpp>

#include "core/criterion/view_grid.hpp"
#include "tests/core/criterion_fixtures.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::make_primitive;

namespace {

constexpr std::size_t kCap = 1024;
constexpr std::int32_t kM = 12;
PrimitivePool<kCap> g_pool;
CriterionModel<kCap> g_model;
CriterionScratch<kCap> g_scratch;
CriterionScratch<kCap> g_scratch_b;
ViewGrid<kM> g_grid;
ViewGrid<kM> g_grid_b;

GridGeometry small_geometry() {
  GridGeometry g;
  g.cells_per_side = kM;
  g.cell_size_m = 4.0;
  g.elevation_m = 6.0;
  return g;
}

void make_model() {
  g_pool.clear();
  test::fill_sphere(g_pool, 600, 5.0, Eigen::Vector3d::Zero(), 21);
  REQUIRE(ok(g_model.refresh(g_pool)));
}

}  // namespace

TEST_CASE("every cell looks from its centre at the target with image up towards +z") {
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d::Zero())));
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const GridCell c = g_grid.geometry().cell_at(i);
    REQUIRE(g_grid.has_viewpoint(c));
    const Viewpoint& v = g_grid.viewpoint(c);
    CHECK((v.position_world - g_grid.geometry().cell_center_world(c)).norm() < 1e-12);
    CHECK(v.R_world_cam.col(2).dot(-v.position_world.normalized()) == Approx(1.0));
    CHECK(v.R_world_cam.col(1).z() < 0.0);  // image y (down) points down in the world
  }
}

TEST_CASE("cells within the margin of a primitive's xy are not free, and set_blocked adds obstacles") {
  g_pool.clear();
  const Eigen::Matrix3d Sigma = 0.01 * Eigen::Matrix3d::Identity();
  // One primitive far below the grid at the centre of cell (3, 3) of the small grid.
  GridGeometry g = small_geometry();
  REQUIRE(ok(g_grid.configure(g, Eigen::Vector3d::Zero())));
  const Eigen::Vector2d xy = g.cell_center_xy(GridCell{3, 3});
  REQUIRE(ok(g_pool.insert(make_primitive({xy.x(), xy.y(), -50.0}, Eigen::Vector3f::UnitZ(), 0.1f, Sigma, 0.5f), nullptr)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  REQUIRE(ok(g_grid.update_free_mask(g_model, 1.0)));  // less than a cell: only its own cell
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const GridCell c = g.cell_at(i);
    CHECK(g_grid.is_free(c) == !(c == GridCell{3, 3}));
  }
  REQUIRE(ok(g_grid.update_free_mask(g_model, 4.0)));  // exactly one cell: the 4-neighbours too
  CHECK_FALSE(g_grid.is_free({2, 3}));
  CHECK_FALSE(g_grid.is_free({3, 4}));
  CHECK(g_grid.is_free({2, 2}));  // diagonal, 5.66 away
  CHECK(ok(g_grid.set_blocked({9, 9}, true)));
  CHECK_FALSE(g_grid.is_free({9, 9}));
  CHECK(g_grid.is_blocked({9, 9}));
  CHECK(g_grid.set_blocked({12, 0}, true) == Status::kNotFound);
  // Blocked cells survive a new free mask; clear_blocked frees them.
  REQUIRE(ok(g_grid.update_free_mask(g_model, 1.0)));
  CHECK_FALSE(g_grid.is_free({9, 9}));
  g_grid.clear_blocked();
  CHECK(g_grid.is_free({9, 9}));
  // The map view sees the same mask.
  const GridMapView map = g_grid.map();
  CHECK_FALSE(map.is_free({3, 3}));
  CHECK(map.is_free({9, 9}));
  CHECK(g_grid.update_free_mask(g_model, -1.0) == Status::kInvalidArgument);
  CHECK(g_grid.update_free_mask(g_model, std::nan("")) == Status::kNonFiniteInput);
  CHECK_FALSE(map.is_free({3, 3}));
}

TEST_CASE("costs are the inverse of F scaled to [0, 1], and the NBV is the free cell of largest F") {
  make_model();
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d::Zero())));
  REQUIRE(ok(g_grid.update_free_mask(g_model, kDefaultSafetyMargin)));
  REQUIRE(ok(g_grid.evaluate(g_model, test::test_intrinsics(), 0, g_grid.cell_count(), g_scratch)));
  REQUIRE(ok(g_grid.finalize()));
  REQUIRE(g_grid.has_nbv());
  double F_max = 0.0, F_min = 1e300;
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const double F = g_grid.F(g_grid.geometry().cell_at(i));
    if (F > 0.0) {
      F_max = std::fmax(F_max, F);
      F_min = std::fmin(F_min, F);
    }
  }
  REQUIRE(F_max > F_min);
  double best_free_F = 0.0;
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const GridCell c = g_grid.geometry().cell_at(i);
    const double F = g_grid.F(c);
    const float cost = g_grid.cost(c);
    CHECK(cost >= 0.0f);
    CHECK(cost <= 1.0f);
    if (F > 0.0) CHECK(cost == Approx((1.0 / F - 1.0 / F_max) / (1.0 / F_min - 1.0 / F_max)).margin(1e-6));
    if (g_grid.is_free(c)) best_free_F = std::fmax(best_free_F, F);
    CHECK(g_grid.map().cost_at(c) == cost);
  }
  CHECK(g_grid.is_free(g_grid.nbv()));
  CHECK(g_grid.F(g_grid.nbv()) == best_free_F);
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const GridCell c = g_grid.geometry().cell_at(i);
    if (g_grid.is_free(c)) CHECK(g_grid.cost(g_grid.nbv()) <= g_grid.cost(c));
  }
  // The cells under the sphere (radius 5 + margin 2) are not free.
  CHECK_FALSE(g_grid.is_free({5, 5}));
  CHECK_FALSE(g_grid.is_free({6, 6}));
}

TEST_CASE("evaluating the grid in ranges with two scratches gives the same F as one pass") {
  make_model();
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d::Zero())));
  REQUIRE(ok(g_grid_b.configure(small_geometry(), Eigen::Vector3d::Zero())));
  const PinholeIntrinsics k = test::test_intrinsics();
  REQUIRE(ok(g_grid.evaluate(g_model, k, 0, g_grid.cell_count(), g_scratch)));
  REQUIRE(ok(g_grid_b.evaluate(g_model, k, 0, 50, g_scratch)));
  CHECK(g_grid_b.finalize() == Status::kInvalidArgument);  // cells 50.. not evaluated yet
  REQUIRE(ok(g_grid_b.evaluate(g_model, k, 50, g_grid_b.cell_count(), g_scratch_b)));
  REQUIRE(ok(g_grid.finalize()));
  REQUIRE(ok(g_grid_b.finalize()));
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const GridCell c = g_grid.geometry().cell_at(i);
    CHECK(g_grid.F(c) == g_grid_b.F(c));
  }
  CHECK(g_grid.nbv() == g_grid_b.nbv());
  CHECK(g_grid.finalize() == Status::kInvalidArgument);  // finalize consumed the evaluation
}

TEST_CASE("ties for the NBV go to the lowest flat index") {
  g_pool.clear();
  // One up-facing primitive with isotropic covariance straight below the grid centre: F depends on the
  // distance only, so the four cells around the centre are symmetric candidates. Float rounding may or
  // may not make them tie exactly; either way the NBV must be the lowest index of maximal F.
  REQUIRE(ok(g_pool.insert(make_primitive({0.0, 0.0, 0.0}, Eigen::Vector3f::UnitZ(), 0.5f,
                                          0.01 * Eigen::Matrix3d::Identity(), 0.0f), nullptr)));
  REQUIRE(ok(g_model.refresh(g_pool)));
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d::Zero())));
  REQUIRE(ok(g_grid.evaluate(g_model, test::test_intrinsics(), 0, g_grid.cell_count(), g_scratch)));
  REQUIRE(ok(g_grid.finalize()));
  std::int32_t first_best = -1;
  double best = -1.0;
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) {
    const double F = g_grid.F(g_grid.geometry().cell_at(i));
    if (F > best) {
      best = F;
      first_best = i;
    }
  }
  CHECK(g_grid.geometry().flat_index(g_grid.nbv()) == first_best);
}

TEST_CASE("no free cell or nothing visible: no NBV and a status that says so") {
  make_model();
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d::Zero())));
  for (std::int32_t i = 0; i < g_grid.cell_count(); ++i) REQUIRE(ok(g_grid.set_blocked(g_grid.geometry().cell_at(i), true)));
  REQUIRE(ok(g_grid.evaluate(g_model, test::test_intrinsics(), 0, g_grid.cell_count(), g_scratch)));
  CHECK(g_grid.finalize() == Status::kNoFreeCell);
  CHECK_FALSE(g_grid.has_nbv());
  g_grid.clear_blocked();
  // Target far away from the object: no cell sees anything.
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d(0.0, 0.0, 500.0))));
  REQUIRE(ok(g_grid.evaluate(g_model, test::test_intrinsics(), 0, g_grid.cell_count(), g_scratch)));
  CHECK(g_grid.finalize() == Status::kNotFound);
  CHECK_FALSE(g_grid.has_nbv());
  CHECK(g_grid.cost({0, 0}) == 1.0f);
}

TEST_CASE("bad grid inputs are refused and change nothing") {
  make_model();
  REQUIRE(ok(g_grid.configure(small_geometry(), Eigen::Vector3d::Zero())));
  GridGeometry wrong = small_geometry();
  wrong.cells_per_side = kM + 1;
  CHECK(g_grid.configure(wrong, Eigen::Vector3d::Zero()) == Status::kInvalidArgument);
  wrong = small_geometry();
  wrong.cell_size_m = std::nan("");
  CHECK(g_grid.configure(wrong, Eigen::Vector3d::Zero()) == Status::kNonFiniteInput);
  CHECK(g_grid.configure(small_geometry(), Eigen::Vector3d(0.0, INFINITY, 0.0)) == Status::kNonFiniteInput);
  CHECK(g_grid.geometry().cell_size_m == 4.0);
  const PinholeIntrinsics k = test::test_intrinsics();
  CHECK(g_grid.evaluate(g_model, k, -1, 3, g_scratch) == Status::kInvalidArgument);
  CHECK(g_grid.evaluate(g_model, k, 5, 4, g_scratch) == Status::kInvalidArgument);
  CHECK(g_grid.evaluate(g_model, k, 0, g_grid.cell_count() + 1, g_scratch) == Status::kInvalidArgument);
  PinholeIntrinsics zero = k;
  zero.width_px = 0;
  CHECK(g_grid.evaluate(g_model, zero, 0, 4, g_scratch) == Status::kInvalidImage);
  PinholeIntrinsics nan_k = k;
  nan_k.fx_px = std::nan("");
  CHECK(g_grid.evaluate(g_model, nan_k, 0, 4, g_scratch) == Status::kNonFiniteInput);
  CHECK(g_grid.F({0, 0}) == 0.0);
}

TEST_CASE("view grid entry points do not allocate") {
  make_model();
  const PinholeIntrinsics k = test::test_intrinsics();
  const GridGeometry geometry = small_geometry();
  Status s[5] = {Status::kNotFound, Status::kNotFound, Status::kNotFound, Status::kNotFound, Status::kNotFound};
  GridMapView map;
  REQUIRE_NO_ALLOCATION(s[0] = g_grid.configure(geometry, Eigen::Vector3d::Zero());
                        s[1] = g_grid.update_free_mask(g_model, 2.0); s[2] = g_grid.set_blocked({0, 0}, true);
                        s[3] = g_grid.evaluate(g_model, k, 0, g_grid.cell_count(), g_scratch);
                        s[4] = g_grid.finalize(); map = g_grid.map());
  for (Status status : s) CHECK(ok(status));
  CHECK(map.free != nullptr);
}
