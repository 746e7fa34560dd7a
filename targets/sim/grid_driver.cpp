#include "targets/sim/grid_driver.hpp"

#include <array>
#include <string>
#include <utility>

#include "core/planning/path_query.hpp"
#include "targets/common/grid_evaluation_threads.hpp"
#include "targets/common/visible_primitives.hpp"
#include "sim_hal/sim_error.hpp"

namespace vantage::simtarget {

namespace {

template <int M>
struct ViewGridOf final : ViewGridHolder {
  ViewGrid<M> view_grid;
  ViewGridView& grid() override { return view_grid; }
};

using Factory = std::unique_ptr<ViewGridHolder> (*)();

template <int M>
std::unique_ptr<ViewGridHolder> make_view_grid() {
  return std::make_unique<ViewGridOf<M>>();
}

template <int... Ms>
constexpr std::array<Factory, sizeof...(Ms)> factories(std::integer_sequence<int, Ms...>) {
  return {&make_view_grid<Ms + 1>...};
}

// One factory per grid side 1 .. kMaxPlanningGridSide: ViewGrid's M is a template parameter.
constexpr auto kFactories = factories(std::make_integer_sequence<int, kMaxPlanningGridSide>{});

}  // namespace

void GridDriver::configure(const GridGeometry& geometry, const PinholeIntrinsics& intrinsics,
                           const sim::OccupancyGrid& occupancy, bool use_model_free_mask, double safety_margin) {
  const int m = geometry.cells_per_side;
  if (m < 1 || m > kMaxPlanningGridSide) {
    throw sim::SimError("grid.cells_per_side: " + std::to_string(m) + " is outside 1.." +
                        std::to_string(kMaxPlanningGridSide) + " (the planner's capacity)");
  }
  holder_ = kFactories[static_cast<std::size_t>(m - 1)]();
  ViewGridView& grid = holder_->grid();
  const Status s = grid.configure(geometry, Eigen::Vector3d(geometry.center_xy.x(), geometry.center_xy.y(), 0.0));
  if (!ok(s)) throw sim::SimError(std::string("view grid: ") + to_string(s));
  for (std::int32_t i = 0; i < geometry.cell_count(); ++i) {
    const GridCell cell = geometry.cell_at(i);
    if (occupancy.occupied(cell)) (void)grid.set_blocked(cell, true);
  }
  intrinsics_ = intrinsics;
  safety_margin_ = safety_margin;
  use_model_free_mask_ = use_model_free_mask;
}

Status GridDriver::evaluate(const PrimitivePoolView& pool) {
  ViewGridView& grid = holder_->grid();
  Status s = model_.refresh(pool);
  if (!ok(s)) return s;
  if (use_model_free_mask_) {
    s = grid.update_free_mask(model_, safety_margin_);
    if (!ok(s)) return s;
  }
  return targets::evaluate_grid_on_two_threads(grid, model_, intrinsics_, scratch_[0], scratch_[1]);
}

GridMapView GridDriver::map() const {
  if (!holder_) return GridMapView{};
  return holder_->grid().map();
}

Status GridDriver::viewpoint(const GridCell& cell, Viewpoint* out) const {
  const ViewGridView& grid = holder_->grid();
  if (!grid.geometry().contains(cell) || !grid.has_viewpoint(cell)) return Status::kNotFound;
  *out = grid.viewpoint(cell);
  return Status::kOk;
}

std::size_t GridDriver::visible_primitives(const Viewpoint& view, const PrimitivePoolView& pool,
                                          Span<PrimitiveIndex> out) {
  return targets::visible_primitives_refreshed(model_, pool, view, intrinsics_, scratch_[0], out);
}

void GridDriver::refresh_free_cells(const PrimitivePoolView& pool) {
  // The primitives moved (EKF) and new ones appeared: cells under them are no longer free.
  if (!use_model_free_mask_ || !ok(model_.refresh(pool))) return;
  (void)holder_->grid().update_free_mask(model_, safety_margin_);
}

}  // namespace vantage::simtarget
