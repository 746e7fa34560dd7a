#include <cmath>
#include <memory>

#include <catch2/catch.hpp>

#include "core/planning/split_path.hpp"
#include "tests/core/planning_test_support.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using vantage::test::SyntheticMap;

namespace {

struct Planner {
  std::unique_ptr<PathQuery> query = std::make_unique<PathQuery>();
  std::unique_ptr<SplitPath> split = std::make_unique<SplitPath>();
};

// Every waypoint is free, lies in its segment's band and disk, and PathQry connects consecutive ones.
void check_plan(const GridMapView& map, const GridCell& start, const GridCell& goal, const SplitPath& split,
                double epsilon, PathQuery& query) {
  const Span<const GridCell> w = split.waypoints();
  REQUIRE(!w.empty());
  CHECK(w[w.size() - 1] == goal);
  GridCell previous = start;
  for (std::size_t i = 0; i < w.size(); ++i) {
    CHECK(map.is_free(w[i]));
    CHECK(w[i] != previous);
    CHECK(query.find(map, previous, w[i]) == Status::kOk);
    previous = w[i];
    if (i + 1 == w.size()) break;
    const SplitRecord r = split.records()[i];
    const Eigen::Vector2d a(r.from.ix, r.from.iy), b(r.to.ix, r.to.iy), y(w[i].ix, w[i].iy);
    const Eigen::Vector2d mid = 0.5 * (a + b);
    const double d = (b - a).norm();
    CHECK(d > 2.0 * epsilon);
    CHECK(std::abs((y - mid).dot((b - a) / d)) <= epsilon + 1e-12);
    CHECK((y - mid).norm() <= 0.5 * d + 1e-12);
  }
}

}  // namespace

TEST_CASE("SplitPath: open grid with default epsilon places a waypoint at every cell displacement") {
  SyntheticMap m(30);
  const GridCell start{2, 2}, goal{25, 14};
  Planner p;
  SplitPathConfig config;
  REQUIRE(p.split->plan(m.view(), start, goal, config, *p.query) == Status::kOk);
  check_plan(m.view(), start, goal, *p.split, config.epsilon_cells, *p.query);
  GridCell previous = start;
  for (const GridCell& c : p.split->waypoints()) {
    CHECK(std::hypot(c.ix - previous.ix, c.iy - previous.iy) <= 2.0 * config.epsilon_cells);
    previous = c;
  }
}

TEST_CASE("SplitPath: the chosen point is the minimal-cost element of S") {
  SyntheticMap m(21);
  // Start and goal on row 10; the bisector is column 10. Make (10, 4) the cheapest cell on it.
  m.set_cost(GridCell{10, 4}, 0.0f);
  Planner p;
  SplitPathConfig config;
  config.epsilon_cells = 0.75;
  REQUIRE(p.split->plan(m.view(), GridCell{2, 10}, GridCell{18, 10}, config, *p.query) == Status::kOk);
  bool found = false;
  for (std::size_t i = 0; i + 1 < p.split->waypoints().size(); ++i) {
    if (p.split->records()[i].from == GridCell{2, 10} && p.split->records()[i].to == GridCell{18, 10}) {
      CHECK(p.split->waypoints()[i] == GridCell{10, 4});
      found = true;
    }
  }
  CHECK(found);
  check_plan(m.view(), GridCell{2, 10}, GridCell{18, 10}, *p.split, 0.75, *p.query);
}

TEST_CASE("SplitPath: a cheap cell outside S (beyond d/2 from the mid-point) is not chosen") {
  SyntheticMap m(41);
  m.set_cost(GridCell{20, 2}, 0.0f);  // on the bisector but 18 cells from the mid-point (d/2 = 8)
  Planner p;
  REQUIRE(p.split->plan(m.view(), GridCell{12, 20}, GridCell{28, 20}, SplitPathConfig{}, *p.query) == Status::kOk);
  for (const GridCell& c : p.split->waypoints()) CHECK(c != GridCell{20, 2});
}

TEST_CASE("SplitPath: plans around the object and never enters non-free cells") {
  SyntheticMap m(30);
  m.block_square(11, 18);
  m.cost_bowl(GridCell{15, 27});
  Planner p;
  const GridCell start{15, 2}, goal{15, 27};
  SplitPathConfig config;
  REQUIRE(p.split->plan(m.view(), start, goal, config, *p.query) == Status::kOk);
  check_plan(m.view(), start, goal, *p.split, config.epsilon_cells, *p.query);
}

TEST_CASE("SplitPath: larger epsilon gives fewer waypoints that still satisfy the bands") {
  SyntheticMap m(40);
  Planner p;
  SplitPathConfig fine, coarse;
  coarse.epsilon_cells = 3.0;
  REQUIRE(p.split->plan(m.view(), GridCell{1, 1}, GridCell{38, 30}, fine, *p.query) == Status::kOk);
  const std::size_t fine_count = p.split->waypoints().size();
  REQUIRE(p.split->plan(m.view(), GridCell{1, 1}, GridCell{38, 30}, coarse, *p.query) == Status::kOk);
  check_plan(m.view(), GridCell{1, 1}, GridCell{38, 30}, *p.split, 3.0, *p.query);
  CHECK(p.split->waypoints().size() < fine_count);
}

TEST_CASE("SplitPath: start equal to goal, enclosed goal, bad config") {
  SyntheticMap m(12);
  Planner p;
  REQUIRE(p.split->plan(m.view(), GridCell{3, 3}, GridCell{3, 3}, SplitPathConfig{}, *p.query) == Status::kOk);
  REQUIRE(p.split->waypoints().size() == 1u);
  CHECK(p.split->waypoints()[0] == GridCell{3, 3});
  for (std::int32_t k = 5; k <= 9; ++k) {
    m.set_free(GridCell{k, 5}, false);
    m.set_free(GridCell{k, 9}, false);
    m.set_free(GridCell{5, k}, false);
    m.set_free(GridCell{9, k}, false);
  }
  CHECK(p.split->plan(m.view(), GridCell{0, 0}, GridCell{7, 7}, SplitPathConfig{}, *p.query) == Status::kNoPath);
  CHECK(p.split->waypoints().empty());
  SplitPathConfig bad;
  bad.epsilon_cells = 0.2;
  CHECK(p.split->plan(m.view(), GridCell{0, 0}, GridCell{3, 3}, bad, *p.query) == Status::kInvalidArgument);
}

TEST_CASE("SplitPath: Fig. 2 returns FALSE when S is empty across a thin wall") {
  SyntheticMap m(12);
  for (std::int32_t y = 0; y < 11; ++y) m.set_free(GridCell{5, y}, false);  // wall with a gap at the top row
  Planner p;
  // (4,0) and (6,0): d = 2 > 1.5, S = {(5,0), ...} all non-free -> FALSE although PathQry connects them.
  CHECK(p.split->plan(m.view(), GridCell{4, 0}, GridCell{6, 0}, SplitPathConfig{}, *p.query) == Status::kNoPath);
  CHECK(p.query->find(m.view(), GridCell{4, 0}, GridCell{6, 0}) == Status::kOk);
}

TEST_CASE("SplitPath: plan does not allocate") {
  SyntheticMap m(60);
  m.block_square(25, 34);
  m.cost_bowl(GridCell{30, 58});
  Planner p;
  Status s = Status::kNotFound;
  REQUIRE_NO_ALLOCATION(s = p.split->plan(m.view(), GridCell{30, 2}, GridCell{30, 58}, SplitPathConfig{}, *p.query));
  CHECK(s == Status::kOk);
}
