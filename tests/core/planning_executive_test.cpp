#include <algorithm>
#include <memory>
#include <string>

#include <catch2/catch.hpp>

#include "core/planning/precision_level.hpp"
#include "core/planning/sensing_executive.hpp"
#include "tests/core/planning_test_support.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using namespace vantage::test;

namespace {

// A 20 x 20 grid of 2-unit cells around an object blocking the centre 4 x 4 cells; the criterion's
// optimum is at nbv_cell. The robot starts at start_cell.
struct Fixture {
  std::unique_ptr<PrimitivePool<256>> pool = std::make_unique<PrimitivePool<256>>();
  FakeMeasurement measurement;
  SyntheticGrid grid{20};
  std::unique_ptr<SensingExecutive> exec;
  GridCell start_cell{1, 10};
  SensingConfig config;

  explicit Fixture(const GridCell& nbv_cell = GridCell{18, 10}) {
    grid.map_data.block_square(8, 11);
    grid.map_data.cost_bowl(nbv_cell);
    exec = std::make_unique<SensingExecutive>(*pool, measurement, grid, nullptr);
    config.rho_sigma = 0.0;  // never stop on precision unless a test says so
    config.max_images = 60;
  }
  Status begin() {
    const Viewpoint v = start_view(grid, start_cell);
    return exec->begin(config, dummy_image(), v, dummy_image(), v);
  }
};

// The fake source's ring plus a ghost at the object's centre (sigma 5 units) that no image updates, as
// a measurement source leaves a primitive whose observations are all rejected; ghost_flags are its flags.
struct GhostMeasurement final : MeasurementSource {
  FakeMeasurement ring;
  std::uint16_t ghost_flags = primitive_flags::kNone;
  PrimitiveIndex ghost = kInvalidPrimitive;

  Status initialize(const GrayImageView& a, const Viewpoint& va, const GrayImageView& b, const Viewpoint& vb,
                    PrimitivePoolView& pool, UpdateReport* report) override {
    const Status s = ring.initialize(a, va, b, vb, pool, report);
    if (!ok(s)) return s;
    Primitive p;
    p.X_world = Eigen::Vector3d(0.0, 0.0, 0.5);
    p.Sigma_world = Eigen::Matrix3d::Identity() * 25.0;
    p.flags = ghost_flags;
    return pool.insert(p, &ghost);
  }
  Status update(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                UpdateReport* report) override {
    const Eigen::Matrix3d Sigma_ghost = pool[ghost].Sigma_world;
    const Status s = ring.update(image, view, pool, report);
    pool[ghost].Sigma_world = Sigma_ghost;  // every observation of it rejected
    return s;
  }
  const PinholeIntrinsics& intrinsics() const override { return ring.intrinsics(); }
};

}  // namespace

TEST_CASE("ExecuteSensing: a primitive flagged kUnconsumed is left out of PredictModel and U") {
  struct Run {
    std::size_t predicted = 0;
    double utility_planned = 0.0;
    int utility_replans = 0;
  };
  auto run = [](std::uint16_t ghost_flags) {
    auto pool = std::make_unique<PrimitivePool<256>>();
    GhostMeasurement measurement;
    measurement.ghost_flags = ghost_flags;
    measurement.ring.shrink = 0.5;
    SyntheticGrid grid{20};
    grid.map_data.block_square(8, 11);
    grid.map_data.cost_bowl(GridCell{18, 10});
    auto exec = std::make_unique<SensingExecutive>(*pool, measurement, grid, nullptr);
    SensingConfig config;
    config.rho_sigma = 0.0;
    config.eta_utility = 0.0;
    config.max_images = 12;
    const Viewpoint v = start_view(grid, GridCell{1, 10});
    REQUIRE(exec->begin(config, dummy_image(), v, dummy_image(), v) == Status::kOk);
    exec->on_grid_evaluated();
    Run r;
    r.predicted = exec->predicted_count();
    r.utility_planned = exec->utility();
    const MissionLog log = drive(*exec);
    r.utility_replans = static_cast<int>(std::count(log.replans.begin(), log.replans.end(), ReplanReason::kUtility));
    return r;
  };
  const Run flagged = run(primitive_flags::kUnconsumed);
  const Run plain = run(primitive_flags::kNone);
  CHECK(plain.predicted == 25u);
  CHECK(flagged.predicted == 24u);  // the ring only
  CHECK(plain.utility_planned > 1000.0 * flagged.utility_planned);
  CHECK(flagged.utility_planned > 0.0);
  // Unflagged, the ghost's predicted gain never comes true and U never falls below eta: no replan on U.
  CHECK(plain.utility_replans == 0);
  // Flagged, U is the ring's: the images consume it and the plan is renewed on U.
  CHECK(flagged.utility_replans >= 1);
}

TEST_CASE("ExecuteSensing: a mission starts with a grid evaluation, then follows SplitPath to the NBV") {
  Fixture f;
  f.config.eta_utility = -1.0;  // never on utility
  REQUIRE(f.begin() == Status::kOk);
  REQUIRE(f.exec->next().kind == SensingActionKind::kEvaluateGrid);
  CHECK(f.exec->next().replan == ReplanReason::kInitial);
  f.exec->on_grid_evaluated();
  CHECK(f.exec->nbv_cell() == GridCell{18, 10});
  CHECK(f.exec->nbv_iterations() == 1u);
  const Span<const GridCell> plan = f.exec->plan();
  REQUIRE(!plan.empty());
  CHECK(plan[plan.size() - 1] == GridCell{18, 10});
  REQUIRE(f.exec->next().kind == SensingActionKind::kMoveTo);
  CHECK(f.exec->predicted_count() > 0u);
  CHECK(f.exec->utility() > 0.0);  // the prediction lowers every visible determinant
}

TEST_CASE("ExecuteSensing: moves never enter non-free cells and are single-cell steps") {
  Fixture f;
  f.config.eta_utility = -1.0;
  f.config.max_images = 40;
  REQUIRE(f.begin() == Status::kOk);
  const MissionLog log = drive(*f.exec);
  REQUIRE(!log.moves.empty());
  GridCell previous = f.start_cell;
  const GridMapView map = f.grid.map();
  for (const GridCell& c : log.moves) {
    CHECK(map.is_free(c));
    CHECK(PathQuery::step_allowed(map, previous, c));
    previous = c;
  }
  CHECK(f.exec->next().kind == SensingActionKind::kDone);
  CHECK(f.exec->next().done == DoneReason::kBudgetExhausted);
  CHECK(f.exec->images() == 40u);
}

TEST_CASE("ExecuteSensing: replans when U falls below eta") {
  Fixture f;
  f.measurement.shrink = 0.5;  // each image shrinks every covariance: det falls by 8 per image
  f.config.eta_utility = 0.0;
  f.config.max_images = 12;
  REQUIRE(f.begin() == Status::kOk);
  const MissionLog log = drive(*f.exec);
  REQUIRE(log.replans.size() >= 2u);
  CHECK(log.replans[0] == ReplanReason::kInitial);
  CHECK(log.replans[1] == ReplanReason::kUtility);
  // The first path is long (the NBV is across the object): U ran out before its end.
  CHECK(log.replan_at[1] < 2u + 17u);
}

TEST_CASE("ExecuteSensing: replans when U falls below a fraction of its value after PredictModel") {
  auto utility_replans = [](double eta_relative) {
    Fixture f;
    f.measurement.shrink = 0.9;  // det falls by 0.73 per image: U never reaches 0 within the budget
    f.config.eta_utility = -1.0;
    f.config.eta_relative = eta_relative;
    f.config.max_images = 12;
    REQUIRE(f.begin() == Status::kOk);
    const MissionLog log = drive(*f.exec);
    return static_cast<int>(std::count(log.replans.begin(), log.replans.end(), ReplanReason::kUtility));
  };
  CHECK(utility_replans(0.0) == 0);
  CHECK(utility_replans(0.5) >= 1);
  SensingConfig bad;
  bad.eta_relative = 1.0;
  CHECK(bad.validate() == Status::kInvalidArgument);
  CHECK(std::string(bad.invalid_field()) == "eta_relative");
}

TEST_CASE("ExecuteSensing: replans when the path to the NBV gets blocked") {
  Fixture f;
  f.config.eta_utility = -1.0;
  f.grid.block_on_refresh = 2;  // the second model update reveals the NBV cell as occupied
  f.grid.block_cell = GridCell{18, 10};
  REQUIRE(f.begin() == Status::kOk);
  const MissionLog log = drive(*f.exec, 60);
  REQUIRE(log.replans.size() >= 2u);
  CHECK(log.replans[1] == ReplanReason::kPathBlocked);
  CHECK(log.replan_at[1] == 4u);  // 2 initial + 2 captured
  CHECK(f.exec->nbv_cell() != GridCell{18, 10});
}

TEST_CASE("ExecuteSensing: replans at the end of the path") {
  Fixture f(GridCell{4, 10});  // NBV three cells away
  f.config.eta_utility = -1.0;
  f.config.max_images = 10;
  REQUIRE(f.begin() == Status::kOk);
  const MissionLog log = drive(*f.exec);
  REQUIRE(log.replans.size() >= 2u);
  CHECK(log.replans[1] == ReplanReason::kPathEnd);
  CHECK(log.replan_at[1] == 2u + 3u);  // one image per cell displacement over three cells
  CHECK(log.captures[2] == GridCell{4, 10});
}

TEST_CASE("ExecuteSensing: stops when PrecisionLevel < rho and the external goal holds") {
  struct CountingGoal final : ExternalGoal {
    int calls = 0;
    bool reached(const PrimitivePoolView&) override { return ++calls >= 2; }
  } goal;
  Fixture f;
  f.exec = std::make_unique<SensingExecutive>(*f.pool, f.measurement, f.grid, &goal);
  f.config.eta_utility = -1.0;
  // Each image multiplies variances by 0.8: sigma = 0.1 * 0.8^(k/2); below 0.05 after k = 7 images.
  f.config.rho_sigma = 0.05;
  REQUIRE(f.begin() == Status::kOk);
  drive(*f.exec);
  REQUIRE(f.exec->next().kind == SensingActionKind::kDone);
  CHECK(f.exec->next().done == DoneReason::kGoalsReached);
  CHECK(f.exec->precision_level() < 0.05);
  CHECK(f.exec->images() == 2u + 8u);  // precision first met at 7, the external goal one image later
  CHECK(goal.calls == 2);
  CHECK(f.exec->precision_level() == Approx(average_sigma(*f.pool)));
}

TEST_CASE("ExecuteSensing: an enclosed NBV is replaced by the best reachable cell") {
  Fixture f(GridCell{17, 17});
  for (std::int32_t k = 15; k <= 19; ++k) {  // a closed ring around (17, 17)
    f.grid.map_data.set_free(GridCell{k, 15}, false);
    f.grid.map_data.set_free(GridCell{15, k}, false);
  }
  f.config.eta_utility = -1.0;
  REQUIRE(f.begin() == Status::kOk);
  f.exec->on_grid_evaluated();
  REQUIRE(f.exec->next().kind == SensingActionKind::kMoveTo);
  CHECK(f.exec->unreachable_nbv_count() == 1u);
  // The cheapest reachable cells are three cells from (17, 17), just outside the ring: (17, 14) comes
  // first in scan order.
  CHECK(f.exec->nbv_cell() == GridCell{17, 14});
}

TEST_CASE("ExecuteSensing: no free cell fails with a reason") {
  Fixture f;
  std::fill(f.grid.map_data.free.begin(), f.grid.map_data.free.end(), std::uint8_t{0});
  REQUIRE(f.begin() == Status::kOk);
  f.exec->on_grid_evaluated();
  REQUIRE(f.exec->next().kind == SensingActionKind::kFailed);
  CHECK(f.exec->next().failure == Status::kNoFreeCell);
  CHECK(std::string(f.exec->next().reason).find("free") != std::string::npos);
}

TEST_CASE("ExecuteSensing: a robot alone in its free cell senses where it stands") {
  Fixture f;
  std::fill(f.grid.map_data.free.begin(), f.grid.map_data.free.end(), std::uint8_t{0});
  f.grid.map_data.set_free(f.start_cell, true);
  f.config.max_images = 4;
  REQUIRE(f.begin() == Status::kOk);
  f.exec->on_grid_evaluated();
  REQUIRE(f.exec->next().kind == SensingActionKind::kCapture);
  CHECK(f.exec->next().cell == f.start_cell);
}

TEST_CASE("ExecuteSensing: invalid config and unexpected calls fail without crashing") {
  Fixture f;
  f.config.max_images = 1;
  CHECK(f.begin() == Status::kInvalidArgument);
  CHECK(f.exec->next().kind == SensingActionKind::kFailed);
  CHECK(std::string(f.config.invalid_field()) == "max_images");
  f.config.max_images = 10;
  REQUIRE(f.begin() == Status::kOk);
  f.exec->on_image(dummy_image(), start_view(f.grid, f.start_cell));  // no capture pending
  CHECK(f.exec->next().kind == SensingActionKind::kFailed);
}

TEST_CASE("ExecuteSensing: baselines run to their budget on the same harness") {
  for (const PlannerPolicy policy : kAllPlannerPolicies) {
    Fixture f;
    f.config.policy = policy;
    f.config.orbit_radius_m = 14.0;
    f.config.max_images = 20;
    REQUIRE(f.begin() == Status::kOk);
    const MissionLog log = drive(*f.exec);
    INFO(to_string(policy));
    REQUIRE(f.exec->next().kind == SensingActionKind::kDone);
    CHECK(f.exec->images() == 20u);
    for (const GridCell& c : log.moves) CHECK(f.grid.map().is_free(c));
    if (policy == PlannerPolicy::kReactive) CHECK(f.exec->nbv_iterations() == 18u);  // one per image
    if (policy == PlannerPolicy::kDirect) {
      // No intermediate sensing: every capture is at an NBV, reached after a whole PathQry segment.
      CHECK(log.captures.size() == f.exec->nbv_iterations());
    }
    if (policy == PlannerPolicy::kOrbit) {
      for (const GridCell& c : log.captures) {
        const Eigen::Vector2d xy = f.grid.map().geometry.cell_center_xy(c);
        CHECK(std::abs(xy.norm() - 14.0) < 2.0);
      }
    }
  }
}

TEST_CASE("ExecuteSensing: parse and print planner names") {
  PlannerPolicy p = PlannerPolicy::kNbv;
  CHECK(parse_planner_policy("orbit", &p));
  CHECK(p == PlannerPolicy::kOrbit);
  CHECK_FALSE(parse_planner_policy("greedy", &p));
  CHECK(p == PlannerPolicy::kOrbit);
  CHECK(std::string(to_string(PlannerPolicy::kReactive)) == "reactive");
}

TEST_CASE("ExecuteSensing: whole planner steps run without allocation") {
  Fixture f;
  f.config.eta_utility = 0.0;
  f.measurement.shrink = 0.5;
  REQUIRE(f.begin() == Status::kOk);
  int steps = 0;
  REQUIRE_NO_ALLOCATION(for (; steps < 200; ++steps) {
    const SensingAction a = f.exec->next();
    if (a.kind == SensingActionKind::kDone || a.kind == SensingActionKind::kFailed) break;
    if (a.kind == SensingActionKind::kEvaluateGrid) f.exec->on_grid_evaluated();
    else if (a.kind == SensingActionKind::kMoveTo) f.exec->on_arrived(a.view);
    else f.exec->on_image(dummy_image(), a.view);
  });
  CHECK(f.exec->nbv_iterations() >= 2u);
  CHECK(f.exec->next().kind == SensingActionKind::kDone);
}

TEST_CASE("ExecuteSensing: the robot's own cell marked non-free by the model still plans") {
  Fixture f;
  f.grid.map_data.set_free(f.start_cell, false);  // e.g. a badly triangulated primitive near the camera
  f.config.eta_utility = -1.0;
  REQUIRE(f.begin() == Status::kOk);
  f.exec->on_grid_evaluated();
  REQUIRE(f.exec->next().kind == SensingActionKind::kMoveTo);
  CHECK(f.exec->nbv_cell() == GridCell{18, 10});
}

TEST_CASE("ExecuteSensing: an NBV that images do not consume is set aside after repeated visits") {
  Fixture f(GridCell{1, 10});  // the criterion's optimum is the robot's own cell
  f.measurement.shrink = 1.0;  // images change nothing: the criterion is never consumed
  f.config.eta_utility = -1.0;
  f.config.stagnation_repeats = 3;
  f.config.max_images = 12;
  REQUIRE(f.begin() == Status::kOk);
  const MissionLog log = drive(*f.exec);
  CHECK(f.exec->stagnation_count() >= 1u);
  REQUIRE(log.captures.size() >= 5u);
  for (int k = 0; k < 3; ++k) CHECK(log.captures[static_cast<std::size_t>(k)] == f.start_cell);
  CHECK(log.captures[3] != f.start_cell);
  CHECK(log.replans.size() >= 5u);
  // The fourth plan goes to another cell: the robot moves.
  CHECK(!log.moves.empty());

  Fixture off(GridCell{1, 10});
  off.measurement.shrink = 1.0;
  off.config.eta_utility = -1.0;
  off.config.stagnation_repeats = 0;  // the paper's behaviour: stays
  off.config.max_images = 12;
  REQUIRE(off.begin() == Status::kOk);
  const MissionLog stay = drive(*off.exec);
  CHECK(stay.moves.empty());
  CHECK(off.exec->stagnation_count() == 0u);
}
