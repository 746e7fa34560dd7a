#pragma once
// What the sensing executive needs from the view grid: the cell map (free mask and cost), the
// viewpoint nu_ij of a cell, and the primitives a view sees (for PredictModel). The criterion's
// ViewGrid<M> is wrapped by view_grid_adapter.hpp; tests provide synthetic grids.
//
// The grid's expensive evaluation (criterion over every cell) is NOT called through this interface:
// the executive asks the target for it (SensingActionKind::kEvaluateGrid) so the target can spread it
// over its own threads; core starts no threads.
#include <cstddef>

#include "core/common/span.hpp"
#include "core/common/status.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/grid/grid_geometry.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage {

class PlanningGrid {
 public:
  // Free mask and cost of the last evaluation. The free mask may also change between evaluations when
  // refresh_free_cells() learns about newly occupied cells from the model.
  virtual GridMapView map() const = 0;
  // The cell's sensing configuration nu_ij (centre of the cell, oriented as the grid defines).
  virtual Status viewpoint(const GridCell& cell, Viewpoint* out) const = 0;
  // Writes the indices of primitives visible from view into out (at most out.size()) and returns how
  // many it wrote.
  virtual std::size_t visible_primitives(const Viewpoint& view, const PrimitivePoolView& pool,
                                         Span<PrimitiveIndex> out) = 0;
  // Called after every model update, before the path is checked: a grid that derives free cells from
  // the model updates them here (cheap, no criterion evaluation). Default: the free mask is static.
  virtual void refresh_free_cells(const PrimitivePoolView& pool) { (void)pool; }

 protected:
  ~PlanningGrid() = default;
};

// A task-level goal the core cannot evaluate itself, such as ground-truth coverage in simulation.
// ExecuteSensing stops only when PrecisionLevel(M) < rho AND reached() (when one is given).
class ExternalGoal {
 public:
  virtual bool reached(const PrimitivePoolView& pool) = 0;

 protected:
  ~ExternalGoal() = default;
};

}  // namespace vantage
