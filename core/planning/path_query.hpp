#pragma once
// PathQry (paper section V.A): the shortest path between two grid cells that never enters a non-free
// cell. A* over the 8-connected grid: a diagonal step is allowed only when both cells it cuts past are
// free too, so the straight segment between two consecutive cell centres never crosses a non-free
// cell's square (no corner cutting). Step costs are 1 (edge) and sqrt(2) (diagonal) in cell units;
// the heuristic is the octile distance, which is admissible and consistent for these costs, so the
// first expansion of the goal is optimal.
//
// All buffers are members sized by kMaxPlanningGridCells (no heap). The object is about 300 KB:
// callers keep it in static storage or inside another statically held object.
#include <cstdint>

#include "core/common/span.hpp"
#include "core/common/status.hpp"
#include "core/grid/grid_geometry.hpp"

namespace vantage {

// The largest grid the planner accepts: M <= 128 (the paper uses M = 60).
inline constexpr std::int32_t kMaxPlanningGridSide = 128;
inline constexpr std::int32_t kMaxPlanningGridCells = kMaxPlanningGridSide * kMaxPlanningGridSide;

inline constexpr double kSqrt2 = 1.4142135623730951;

class PathQuery {
 public:
  // Finds the shortest path from start to goal. kOk: path() holds start ... goal (start == goal gives a
  // one-cell path of length 0). kNoPath when the goal is not reachable; kNoFreeCell when start or goal
  // is outside the grid or not free; kInvalidArgument when the grid is empty, larger than
  // kMaxPlanningGridSide, or its arrays are null. On error path() is empty.
  Status find(const GridMapView& map, const GridCell& start, const GridCell& goal);

  // Cells of the last found path, start first, goal last.
  Span<const GridCell> path() const { return Span<const GridCell>(path_, path_size_); }
  // Its length in cell units (edge steps 1, diagonal steps sqrt 2); multiply by cell_size_m for units.
  double length_cells() const { return length_cells_; }
  // Cells expanded by the last find() (for tests and benchmarks).
  std::int32_t expanded() const { return expanded_; }

  // Marks every cell reachable from start (its connected free component under the same moves as find()).
  // PathQry between two cells exists exactly when both are in one component, because the moves are
  // symmetric. kNoFreeCell when start is not free, kInvalidArgument as for find().
  Status label_component(const GridMapView& map, const GridCell& start);
  // True when cell was reached by the last label_component(); false outside the grid.
  bool in_component(const GridCell& cell) const;
  std::int32_t component_size() const { return component_size_; }

  // True when a step from a to its 8-neighbour b stays in free cells (both cells free and, for a
  // diagonal, both cells it passes). Exposed for tests and for path checks by callers.
  static bool step_allowed(const GridMapView& map, const GridCell& a, const GridCell& b);

 private:
  static Status check_map(const GridMapView& map);
  void heap_push(std::int32_t cell, float key);
  void heap_decrease(std::int32_t cell, float key);
  std::int32_t heap_pop();
  void sift_up(std::int32_t pos);
  void sift_down(std::int32_t pos);

  // Per-cell A* state, indexed by flat cell index.
  float g_[kMaxPlanningGridCells];
  float f_[kMaxPlanningGridCells];
  std::int32_t parent_[kMaxPlanningGridCells];
  std::int32_t heap_pos_[kMaxPlanningGridCells];  // -1: not in the heap
  std::uint8_t state_[kMaxPlanningGridCells];     // 0 unseen, 1 open, 2 closed
  // Binary min-heap of flat cell indices keyed by f_ (also the BFS queue of label_component()).
  std::int32_t heap_[kMaxPlanningGridCells];
  std::int32_t heap_size_ = 0;

  GridCell path_[kMaxPlanningGridCells];
  std::int32_t path_size_ = 0;
  double length_cells_ = 0.0;
  std::int32_t expanded_ = 0;

  std::uint8_t component_[kMaxPlanningGridCells];
  GridGeometry component_geometry_{};
  std::int32_t component_size_ = 0;
};

}  // namespace vantage
