#pragma once
// SplitPath (paper Fig. 2): recursive, cost-guided choice of intermediate sensing positions between
// the current cell x0 and the NBV cell x1.
//
//   x_m = (x0 + x1) / 2, d = |x0 - x1|; halt when d <= 2 epsilon.
//   x_hat = (x1 - x0) / d.
//   S = { cells y : |(y - x_m)^T x_hat| <= epsilon  and  |y - x_m| <= d / 2 }
//   x* = the free cell of S with minimal cost that PathQry connects to both x0 and x1; none -> FALSE.
//   SplitPath(x0, x*), insert x*, SplitPath(x*, x1).
//
// Coordinates are cell indices (a cell's centre is (ix, iy)), so epsilon is in cells. S is a strip of
// fixed width 2 epsilon along the perpendicular bisector of x0-x1, cut to the disk of radius d/2 around
// the mid-point: its length along the bisector is d, so "the extent of S is proportional to the distance
// between the end points" (Fig. 1) and shrinks with every level. Every y in S is strictly closer to both
// ends than d while d > 2 epsilon (|y - x0|^2 <= d^2/2 + d epsilon < d^2), so the recursion terminates.
// With the default epsilon = 0.75 recursion stops at 8-neighbours (d <= 1.5): one sample per single
// cell displacement, the paper's sampling rate (section VI). Larger epsilon gives sparser waypoints.
//
// "Reachable from both ends" is tested by one connected-component labelling of x0 (PathQuery::
// label_component): moves are symmetric, so PathQry(x0, y, x1) exists exactly when y lies in x0's
// component, and x1 does too. That is the same answer as running A* per candidate, at a fraction of
// the cost.
//
// The recursion runs on a fixed-size explicit stack (no heap, no call recursion): kSplitStackCapacity
// entries; overflow returns kPoolFull.
#include <cstdint>

#include "core/common/span.hpp"
#include "core/common/status.hpp"
#include "core/grid/grid_geometry.hpp"
#include "core/planning/path_query.hpp"

namespace vantage {

struct SplitPathConfig {
  double epsilon_cells = 0.75;  // band half-width and halting threshold (halt at d <= 2 epsilon), cells

  // kInvalidArgument unless epsilon is finite and >= 0.5 (narrower bands can miss every cell centre).
  Status validate() const;
};

// Which segment a waypoint was chosen for (the goal itself carries from = start, to = goal).
struct SplitRecord {
  GridCell from;
  GridCell to;
};

inline constexpr std::int32_t kSplitStackCapacity = 512;

class SplitPath {
 public:
  // Plans from start to goal. kOk: waypoints() runs from start (exclusive) to goal (inclusive); when
  // start == goal it holds just goal. kNoPath when goal is not reachable from start or Fig. 2 returns
  // FALSE (an empty set S at some level); kNoFreeCell when start or goal is not free; kInvalidArgument
  // for a bad config or a map without cost; kPoolFull when the stack or the output overflows.
  // On error waypoints() is empty. query is scratch (its component labelling is overwritten).
  Status plan(const GridMapView& map, const GridCell& start, const GridCell& goal, const SplitPathConfig& config,
              PathQuery& query);

  Span<const GridCell> waypoints() const { return Span<const GridCell>(waypoints_, size_); }
  Span<const SplitRecord> records() const { return Span<const SplitRecord>(records_, size_); }
  // Cells of S examined in the last plan (cost evaluations), for the paper's efficiency argument.
  std::int32_t candidates_examined() const { return candidates_examined_; }

 private:
  struct Item {
    GridCell a;
    GridCell b;
    GridCell mid;
    bool emit;  // true: append mid (chosen for segment a-b); false: split segment a-b
  };

  // Fig. 2's argmin over S; false when S has no valid element.
  bool choose(const GridMapView& map, const GridCell& a, const GridCell& b, double epsilon, const PathQuery& query,
              GridCell* chosen);

  Item stack_[kSplitStackCapacity];
  GridCell waypoints_[kMaxPlanningGridCells];
  SplitRecord records_[kMaxPlanningGridCells];
  std::int32_t size_ = 0;
  std::int32_t candidates_examined_ = 0;
};

}  // namespace vantage
