#include "targets/onboard/onboard_grid.hpp"

#include "targets/common/grid_evaluation_threads.hpp"
#include "targets/common/visible_primitives.hpp"

namespace vantage::onboard {

Status OnboardGrid::configure(const GridGeometry& geometry, const PinholeIntrinsics& intrinsics, double keep_out_radius_m) {
  if (geometry.cells_per_side != kOnboardGridSide) return Status::kInvalidArgument;
  grid_.clear_blocked();
  const Status s = grid_.configure(geometry, Eigen::Vector3d(geometry.center_xy.x(), geometry.center_xy.y(), 0.0));
  if (!ok(s)) return s;
  for (std::int32_t i = 0; i < geometry.cell_count(); ++i) {
    const GridCell cell = geometry.cell_at(i);
    if ((geometry.cell_center_xy(cell) - geometry.center_xy).norm() < keep_out_radius_m) (void)grid_.set_blocked(cell, true);
  }
  intrinsics_ = intrinsics;
  return Status::kOk;
}

Status OnboardGrid::evaluate(const PrimitivePoolView& pool) {
  Status s = model_.refresh(pool);
  if (!ok(s)) return s;
  s = grid_.update_free_mask(model_, kDefaultSafetyMargin);
  if (!ok(s)) return s;
  return targets::evaluate_grid_on_two_threads(grid_, model_, intrinsics_, scratch_[0], scratch_[1]);
}

Status OnboardGrid::viewpoint(const GridCell& cell, Viewpoint* out) const {
  if (!grid_.geometry().contains(cell) || !grid_.has_viewpoint(cell)) return Status::kNotFound;
  *out = grid_.viewpoint(cell);
  return Status::kOk;
}

std::size_t OnboardGrid::visible_primitives(const Viewpoint& view, const PrimitivePoolView& pool,
                                           Span<PrimitiveIndex> out) {
  return targets::visible_primitives_refreshed(model_, pool, view, intrinsics_, scratch_[0], out);
}

void OnboardGrid::refresh_free_cells(const PrimitivePoolView& pool) {
  if (!ok(model_.refresh(pool))) return;
  (void)grid_.update_free_mask(model_, kDefaultSafetyMargin);
}

}  // namespace vantage::onboard
