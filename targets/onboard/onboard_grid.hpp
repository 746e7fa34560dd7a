#pragma once
// The onboard side of the view grid: a statically held ViewGrid<kOnboardGridSide>, the criterion cache and
// two scratch buffers; evaluates the grid on two std::threads (core starts none) and implements
// core/planning's PlanningGrid for the executive. Cells within keep_out_radius_m of the grid centre are
// blocked (the operator's keep-out around the object); the model's primitives block the cells under them
// (ViewGrid::update_free_mask).
#include <cstdint>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/view_grid.hpp"
#include "core/planning/planning_grid.hpp"

namespace vantage::onboard {

inline constexpr std::int32_t kOnboardGridSide = 60;  // the paper's M; the cell size is configurable

class OnboardGrid final : public PlanningGrid {
 public:
  static constexpr int kThreads = 2;

  // kInvalidArgument when the geometry is not kOnboardGridSide cells per side or is rejected.
  Status configure(const GridGeometry& geometry, const PinholeIntrinsics& intrinsics, double keep_out_radius_m);
  Status evaluate(const PrimitivePoolView& pool);

  GridMapView map() const override { return grid_.map(); }
  Status viewpoint(const GridCell& cell, Viewpoint* out) const override;
  std::size_t visible_primitives(const Viewpoint& view, const PrimitivePoolView& pool,
                                 Span<PrimitiveIndex> out) override;
  void refresh_free_cells(const PrimitivePoolView& pool) override;
  bool is_free_initially(const GridCell& cell) const { return grid_.geometry().contains(cell) && !grid_.is_blocked(cell); }

 private:
  ViewGrid<kOnboardGridSide> grid_;
  PinholeIntrinsics intrinsics_{};
  CriterionModel<> model_;
  CriterionScratch<kDefaultPrimitiveCapacity> scratch_[kThreads];
};

}  // namespace vantage::onboard
