#include <cmath>
#include <memory>

#include <catch2/catch.hpp>

#include "core/planning/path_query.hpp"
#include "tests/core/planning_test_support.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::SyntheticMap;

namespace {

bool path_is_connected_and_free(const GridMapView& map, Span<const GridCell> path) {
  for (std::size_t i = 0; i < path.size(); ++i) {
    if (!map.is_free(path[i])) return false;
    if (i > 0 && !PathQuery::step_allowed(map, path[i - 1], path[i])) return false;
  }
  return true;
}

}  // namespace

TEST_CASE("PathQuery: open grid gives the octile-length straight path") {
  SyntheticMap m(20);
  auto q = std::make_unique<PathQuery>();
  REQUIRE(q->find(m.view(), GridCell{2, 3}, GridCell{12, 7}) == Status::kOk);
  const Span<const GridCell> path = q->path();
  REQUIRE(path.size() == 11u);  // 10 steps: 4 diagonal + 6 straight
  CHECK(path[0] == GridCell{2, 3});
  CHECK(path[path.size() - 1] == GridCell{12, 7});
  CHECK(q->length_cells() == Approx(6.0 + 4.0 * std::sqrt(2.0)));
  CHECK(path_is_connected_and_free(m.view(), path));
}

TEST_CASE("PathQuery: routes around an obstacle without entering or corner-cutting it") {
  SyntheticMap m(20);
  m.block_square(6, 13);
  auto q = std::make_unique<PathQuery>();
  REQUIRE(q->find(m.view(), GridCell{2, 10}, GridCell{17, 10}) == Status::kOk);
  CHECK(path_is_connected_and_free(m.view(), q->path()));
  // The detour must go past the square's rows 6..13: longer than the 15-cell straight line.
  CHECK(q->length_cells() > 15.0 + 1.0);
}

TEST_CASE("PathQuery: a diagonal between two blocked orthogonal cells is not allowed") {
  SyntheticMap m(5);
  // Free only the two diagonal cells (1,1) and (2,2): their shared corner is pinched by blocked cells.
  for (std::int32_t i = 0; i < 25; ++i) m.free[static_cast<std::size_t>(i)] = 0;
  m.set_free(GridCell{1, 1}, true);
  m.set_free(GridCell{2, 2}, true);
  auto q = std::make_unique<PathQuery>();
  CHECK(q->find(m.view(), GridCell{1, 1}, GridCell{2, 2}) == Status::kNoPath);
  CHECK(q->path().empty());
}

TEST_CASE("PathQuery: an enclosed goal has no path, a non-free end has no free cell") {
  SyntheticMap m(12);
  for (std::int32_t k = 3; k <= 7; ++k) {
    m.set_free(GridCell{k, 3}, false);
    m.set_free(GridCell{k, 7}, false);
    m.set_free(GridCell{3, k}, false);
    m.set_free(GridCell{7, k}, false);
  }
  auto q = std::make_unique<PathQuery>();
  CHECK(q->find(m.view(), GridCell{0, 0}, GridCell{5, 5}) == Status::kNoPath);
  CHECK(q->find(m.view(), GridCell{0, 0}, GridCell{3, 3}) == Status::kNoFreeCell);
  CHECK(q->find(m.view(), GridCell{0, 0}, GridCell{-1, 3}) == Status::kNoFreeCell);
  REQUIRE(q->label_component(m.view(), GridCell{0, 0}) == Status::kOk);
  CHECK(q->in_component(GridCell{11, 11}));
  CHECK_FALSE(q->in_component(GridCell{5, 5}));
  CHECK(q->component_size() == 144 - 16 - 9);
}

TEST_CASE("PathQuery: start equal to goal is a one-cell path of length zero") {
  SyntheticMap m(8);
  auto q = std::make_unique<PathQuery>();
  REQUIRE(q->find(m.view(), GridCell{4, 4}, GridCell{4, 4}) == Status::kOk);
  CHECK(q->path().size() == 1u);
  CHECK(q->length_cells() == 0.0);
}

TEST_CASE("PathQuery: grids beyond the capacity and maps without a free mask are rejected") {
  SyntheticMap m(8);
  GridMapView view = m.view();
  view.geometry.cells_per_side = kMaxPlanningGridSide + 1;
  auto q = std::make_unique<PathQuery>();
  CHECK(q->find(view, GridCell{0, 0}, GridCell{1, 1}) == Status::kInvalidArgument);
  GridMapView no_free = m.view();
  no_free.free = nullptr;
  CHECK(q->find(no_free, GridCell{0, 0}, GridCell{1, 1}) == Status::kInvalidArgument);
}

TEST_CASE("PathQuery: shortest length matches a brute-force Dijkstra on random maps") {
  std::uint64_t seed = 7;
  auto next = [&seed]() {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint32_t>(seed >> 33);
  };
  auto q = std::make_unique<PathQuery>();
  for (int trial = 0; trial < 30; ++trial) {
    SyntheticMap m(16);
    for (auto& f : m.free) f = (next() % 100) < 25 ? 0 : 1;
    const GridCell a{0, 0}, b{15, 15};
    m.set_free(a, true);
    m.set_free(b, true);
    // Reference: Bellman-Ford-style relaxation until stable.
    std::vector<double> dist(256, 1e18);
    dist[0] = 0.0;
    for (bool changed = true; changed;) {
      changed = false;
      for (int i = 0; i < 256; ++i) {
        if (dist[static_cast<std::size_t>(i)] >= 1e18) continue;
        const GridCell c = m.geometry.cell_at(i);
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const GridCell n{c.ix + dx, c.iy + dy};
            if (!PathQuery::step_allowed(m.view(), c, n)) continue;
            const double nd = dist[static_cast<std::size_t>(i)] + ((dx != 0 && dy != 0) ? std::sqrt(2.0) : 1.0);
            double& slot = dist[static_cast<std::size_t>(m.geometry.flat_index(n))];
            if (nd < slot - 1e-9) {
              slot = nd;
              changed = true;
            }
          }
      }
    }
    const Status s = q->find(m.view(), a, b);
    if (dist[255] >= 1e18) {
      CHECK(s == Status::kNoPath);
    } else {
      REQUIRE(s == Status::kOk);
      CHECK(q->length_cells() == Approx(dist[255]).epsilon(1e-5));
      CHECK(path_is_connected_and_free(m.view(), q->path()));
    }
  }
}

TEST_CASE("PathQuery: find and label_component do not allocate") {
  SyntheticMap m(60);
  m.block_square(25, 34);
  auto q = std::make_unique<PathQuery>();
  Status s = Status::kNotFound;
  REQUIRE_NO_ALLOCATION(s = q->find(m.view(), GridCell{0, 30}, GridCell{59, 30}));
  CHECK(s == Status::kOk);
  REQUIRE_NO_ALLOCATION(s = q->label_component(m.view(), GridCell{0, 0}));
  CHECK(s == Status::kOk);
}
