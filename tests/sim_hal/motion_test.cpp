#include <catch2/catch.hpp>
#include <limits>

#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/kinematic_robot.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/world/occupancy.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

GridGeometry small_grid() {
  GridGeometry g;
  g.cells_per_side = 20;
  g.cell_size_m = 2.0;
  return g;
}

Viewpoint at_cell(const GridGeometry& g, int ix, int iy) { return grid_cell_viewpoint(g, GridCell{ix, iy}); }

}  // namespace

TEST_CASE("occupancy marks the cells under the object's footprint plus margin", "[sim_hal][motion]") {
  const TriangleMesh box = test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5));
  const OccupancyGrid occupancy(box, small_grid(), 0.5);
  // Cell centres at +-1, +-3, ...: a cell (half side 1, plus margin 0.5) overlaps [-5, 5] iff |c| <= 6.5.
  CHECK(occupancy.occupied_count() == 36);
  CHECK(occupancy.occupied(GridCell{10, 10}));
  CHECK(occupancy.occupied(GridCell{12, 12}));   // centre (5, 5)
  CHECK(!occupancy.occupied(GridCell{13, 10}));  // centre (7, 1)
  CHECK(occupancy.occupied(GridCell{-1, 3}));    // off the grid
  CHECK(occupancy.free_mask().size() == 400);
}

TEST_CASE("the robot refuses occupied and off-grid and non-finite targets", "[sim_hal][motion]") {
  const GridGeometry g = small_grid();
  const OccupancyGrid occupancy(test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5)), g, 0.5);
  KinematicRobotConfig config;
  KinematicRobot robot(config, occupancy, at_cell(g, 0, 0));
  CHECK(robot.command(at_cell(g, 10, 10)) == hal::MotionFault::kTargetOccupied);
  CHECK(robot.fault() == hal::MotionFault::kTargetOccupied);
  CHECK(robot.arrived());
  Viewpoint off = at_cell(g, 0, 0);
  off.position_world.x() = -100.0;
  CHECK(robot.command(off) == hal::MotionFault::kTargetOccupied);
  Viewpoint nan = at_cell(g, 0, 0);
  nan.position_world.y() = std::numeric_limits<double>::quiet_NaN();
  CHECK(robot.command(nan) == hal::MotionFault::kNonFiniteTarget);
  Viewpoint high = at_cell(g, 0, 5);
  high.position_world.z() = 3.0;
  CHECK(robot.command(high) == hal::MotionFault::kRejected);
  CHECK(robot.camera_pose().position_world.isApprox(at_cell(g, 0, 0).position_world));
  CHECK(robot.command(at_cell(g, 0, 5)) == hal::MotionFault::kNone);
  CHECK(robot.fault() == hal::MotionFault::kNone);
}

TEST_CASE("the robot moves at its speed and counts distance and time", "[sim_hal][motion]") {
  const GridGeometry g = small_grid();
  const OccupancyGrid occupancy(test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5)), g, 0.5);
  KinematicRobotConfig config;
  config.speed = 4.0;
  KinematicRobot robot(config, occupancy, at_cell(g, 0, 0));
  const Viewpoint target = at_cell(g, 0, 5);  // 10 units along +y
  REQUIRE(robot.command(target) == hal::MotionFault::kNone);
  CHECK(robot.camera_pose().R_world_cam.isApprox(target.R_world_cam));
  CHECK(!robot.arrived());
  robot.update(1.0);
  CHECK(robot.distance_travelled() == Approx(4.0));
  CHECK((robot.camera_pose().position_world - at_cell(g, 0, 0).position_world).norm() == Approx(4.0));
  robot.update(1.0);
  CHECK(!robot.arrived());
  robot.update(1.0);
  CHECK(robot.arrived());
  CHECK(robot.distance_travelled() == Approx(10.0));
  CHECK(robot.simulated_time_s() == Approx(3.0));
  CHECK(robot.camera_pose().position_world.isApprox(target.position_world));
}

TEST_CASE("pose noise goes on the reported pose and not the true one", "[sim_hal][motion]") {
  const GridGeometry g = small_grid();
  const OccupancyGrid occupancy(test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5)), g, 0.5);
  KinematicRobotConfig config;
  config.pose_noise.position_sigma = 0.1;
  config.pose_noise.rotation_sigma_rad = 0.01;
  SimClock clock;
  clock.advance(2.5);
  const KinematicRobot robot(config, occupancy, at_cell(g, 0, 0), &clock);
  const hal::PoseReport report = robot.current_pose();
  CHECK(report.valid);
  CHECK(report.timestamp_ns == 2500000000);
  CHECK(robot.camera_pose().position_world == at_cell(g, 0, 0).position_world);
  const double offset = (report.pose.position_world - robot.camera_pose().position_world).norm();
  CHECK(offset > 0.0);
  CHECK(offset < 1.0);
  CHECK(ok(report.pose.validate()));
}

TEST_CASE("SimClock only runs forward", "[sim_hal][motion]") {
  SimClock clock;
  clock.advance(0.5);
  clock.advance(-1.0);
  clock.advance(std::numeric_limits<double>::quiet_NaN());
  CHECK(clock.now_ns() == 500000000);
}
