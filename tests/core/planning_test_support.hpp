#pragma once
// Synthetic grids, a fake measurement source and a mission driver for the planning suites.
#include <cstdint>
#include <memory>
#include <vector>

#include "core/estimation/ekf.hpp"
#include "core/frontend/measurement_source.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/grid/grid_geometry.hpp"
#include "core/model/primitive_pool.hpp"
#include "core/planning/planning_grid.hpp"
#include "core/planning/sensing_executive.hpp"

namespace vantage::test {

// An M x M map with every cell free and cost 1, except what a test changes.
struct SyntheticMap {
  GridGeometry geometry;
  std::vector<std::uint8_t> free;
  std::vector<float> cost;

  explicit SyntheticMap(std::int32_t m, double cell_size_m = 2.0) {
    geometry.cells_per_side = m;
    geometry.cell_size_m = cell_size_m;
    free.assign(static_cast<std::size_t>(m * m), 1);
    cost.assign(static_cast<std::size_t>(m * m), 1.0f);
  }
  void set_free(const GridCell& c, bool is_free) { free[static_cast<std::size_t>(geometry.flat_index(c))] = is_free ? 1 : 0; }
  void set_cost(const GridCell& c, float value) { cost[static_cast<std::size_t>(geometry.flat_index(c))] = value; }
  // Blocks the square [lo, hi] x [lo, hi] of cells.
  void block_square(std::int32_t lo, std::int32_t hi) {
    for (std::int32_t y = lo; y <= hi; ++y)
      for (std::int32_t x = lo; x <= hi; ++x) set_free(GridCell{x, y}, false);
  }
  // Cost grows with the distance from cell: the criterion's optimum sits at cell.
  void cost_bowl(const GridCell& cell) {
    for (std::int32_t i = 0; i < geometry.cell_count(); ++i) {
      const GridCell c = geometry.cell_at(i);
      const double d = std::hypot(c.ix - cell.ix, c.iy - cell.iy);
      cost[static_cast<std::size_t>(i)] = static_cast<float>(d / (2.0 * geometry.cells_per_side));
    }
  }
  GridMapView view() const { return GridMapView{geometry, free.data(), cost.data()}; }
};

// A PlanningGrid over a SyntheticMap: cells look at the grid centre (the object at the origin), every
// primitive in front of the camera is visible. blocked_after_image, when set, turns that cell non-free
// on the given refresh (model update).
struct SyntheticGrid final : PlanningGrid {
  SyntheticMap map_data;
  int refreshes = 0;
  int block_on_refresh = -1;
  GridCell block_cell{};

  explicit SyntheticGrid(std::int32_t m) : map_data(m) {}
  GridMapView map() const override { return map_data.view(); }
  Status viewpoint(const GridCell& cell, Viewpoint* out) const override {
    return look_at(map_data.geometry.cell_center_world(cell), Eigen::Vector3d(0.0, 0.0, 0.0), Eigen::Vector3d::UnitZ(),
                   out);
  }
  std::size_t visible_primitives(const Viewpoint& view, const PrimitivePoolView& pool,
                                 Span<PrimitiveIndex> out) override {
    std::size_t n = 0;
    for (PrimitiveIndex i = 0; i < pool.index_bound() && n < out.size(); ++i) {
      if (!pool.is_alive(i)) continue;
      const Eigen::Vector3d X_cam = view.R_world_cam.transpose() * (pool[i].X_world - view.position_world);
      if (X_cam.z() > 0.1) out[n++] = i;
    }
    return n;
  }
  void refresh_free_cells(const PrimitivePoolView&) override {
    ++refreshes;
    if (refreshes == block_on_refresh) map_data.set_free(block_cell, false);
  }
};

// A measurement source that seeds a ring of primitives and shrinks every covariance by shrink per image.
struct FakeMeasurement final : MeasurementSource {
  PinholeIntrinsics intrinsics_ = PinholeIntrinsics::default_vga();
  double initial_sigma = 0.1;
  double shrink = 0.8;
  int primitives = 24;
  int updates = 0;

  Status initialize(const GrayImageView&, const Viewpoint&, const GrayImageView&, const Viewpoint&,
                    PrimitivePoolView& pool, UpdateReport* report) override {
    for (int k = 0; k < primitives; ++k) {
      Primitive p;
      const double a = 2.0 * 3.14159265358979 * k / primitives;
      p.X_world = Eigen::Vector3d(2.0 * std::cos(a), 2.0 * std::sin(a), 0.5);
      p.Sigma_world = Eigen::Matrix3d::Identity() * initial_sigma * initial_sigma;
      PrimitiveIndex index = 0;
      if (!ok(pool.insert(p, &index))) return Status::kPoolFull;
    }
    if (report != nullptr) report->spawned = static_cast<std::uint32_t>(primitives);
    return Status::kOk;
  }
  Status update(const GrayImageView&, const Viewpoint&, PrimitivePoolView& pool, UpdateReport* report) override {
    ++updates;
    for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
      if (pool.is_alive(i)) pool[i].Sigma_world *= shrink;
    }
    if (report != nullptr) report->updated = static_cast<std::uint32_t>(pool.size());
    return Status::kOk;
  }
  const PinholeIntrinsics& intrinsics() const override { return intrinsics_; }
};

struct MissionLog {
  std::vector<ReplanReason> replans;     // reason of every kEvaluateGrid/plan renewal, in order
  std::vector<std::uint32_t> replan_at;  // images taken when it happened
  std::vector<GridCell> moves;           // every commanded cell
  std::vector<GridCell> captures;
  int steps = 0;
};

inline std::uint8_t g_dummy_pixels[16 * 16] = {};
inline GrayImageView dummy_image() { return GrayImageView{g_dummy_pixels, 16, 16, 16}; }

inline Viewpoint start_view(const SyntheticGrid& grid, const GridCell& cell) {
  Viewpoint v;
  (void)grid.viewpoint(cell, &v);
  return v;
}

// Steps the executive until done/failed (or max_steps), acting as a perfect robot.
inline MissionLog drive(SensingExecutive& exec, int max_steps = 10000) {
  MissionLog log;
  std::uint32_t last_nbv = exec.nbv_iterations();
  for (; log.steps < max_steps; ++log.steps) {
    const SensingAction a = exec.next();
    if (a.kind == SensingActionKind::kDone || a.kind == SensingActionKind::kFailed) break;
    if (a.kind == SensingActionKind::kEvaluateGrid) {
      exec.on_grid_evaluated();
    } else if (a.kind == SensingActionKind::kMoveTo) {
      log.moves.push_back(a.cell);
      exec.on_arrived(a.view);
    } else {
      log.captures.push_back(a.cell);
      exec.on_image(dummy_image(), a.view);
    }
    if (exec.nbv_iterations() != last_nbv) {
      last_nbv = exec.nbv_iterations();
      log.replans.push_back(exec.last_replan_reason());
      log.replan_at.push_back(exec.images());
    }
  }
  return log;
}

}  // namespace vantage::test
