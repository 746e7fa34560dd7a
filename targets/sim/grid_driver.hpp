#pragma once
// The target's side of the view grid: owns the criterion cache, the ViewGrid (any M up to
// kMaxPlanningGridSide, chosen at run time), two scratch buffers, and evaluates the grid on two
// std::threads (core starts none). Implements core/planning's PlanningGrid for the executive.
//
// Free cells: the simulator's occupancy (the object's true footprint) is given to the grid as blocked
// cells: the paper's "open environment where the only inaccessible regions of the grid are those
// occupied by our object model", known to the motion planner, so the robot is never sent into the
// object through a region the model has not seen yet. With use_model_free_mask, ViewGrid also marks the
// cells under the model's primitives after every model update (paths can then become blocked mid-way);
// off by default because badly triangulated primitives (small initial baseline) land near the cameras
// and fence the robot in.
#include <memory>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/view_grid.hpp"
#include "core/planning/planning_grid.hpp"
#include "sim_hal/world/occupancy.hpp"

namespace vantage::simtarget {

struct ViewGridHolder {
  virtual ~ViewGridHolder() = default;
  virtual ViewGridView& grid() = 0;
};

class GridDriver final : public PlanningGrid {
 public:
  static constexpr int kThreads = 2;

  // Throws sim::SimError when the grid side is larger than the planner supports or the grid rejects
  // the geometry.
  void configure(const GridGeometry& geometry, const PinholeIntrinsics& intrinsics, const sim::OccupancyGrid& occupancy,
                 bool use_model_free_mask = false, double safety_margin = kDefaultSafetyMargin);

  // Refreshes the criterion cache and the free mask, evaluates F of every cell on kThreads threads,
  // finalizes the costs. kOk also when no free cell sees a primitive (all costs equal) or no cell is
  // free (the executive reports that).
  Status evaluate(const PrimitivePoolView& pool);

  GridMapView map() const override;
  Status viewpoint(const GridCell& cell, Viewpoint* out) const override;
  std::size_t visible_primitives(const Viewpoint& view, const PrimitivePoolView& pool,
                                 Span<PrimitiveIndex> out) override;
  void refresh_free_cells(const PrimitivePoolView& pool) override;

 private:
  std::unique_ptr<ViewGridHolder> holder_;
  PinholeIntrinsics intrinsics_{};
  double safety_margin_ = kDefaultSafetyMargin;
  bool use_model_free_mask_ = false;
  CriterionModel<> model_;
  CriterionScratch<kDefaultPrimitiveCapacity> scratch_[kThreads];
};

}  // namespace vantage::simtarget
