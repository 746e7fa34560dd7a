#include "core/planning/split_path.hpp"

#include <cmath>

namespace vantage {

Status SplitPathConfig::validate() const {
  if (!std::isfinite(epsilon_cells) || epsilon_cells < 0.5) return Status::kInvalidArgument;
  return Status::kOk;
}

bool SplitPath::choose(const GridMapView& map, const GridCell& a, const GridCell& b, double epsilon,
                       const PathQuery& query, GridCell* chosen) {
  const double ax = a.ix, ay = a.iy, bx = b.ix, by = b.iy;
  const double mx = 0.5 * (ax + bx), my = 0.5 * (ay + by);
  const double d = std::hypot(bx - ax, by - ay);
  const double ux = (bx - ax) / d, uy = (by - ay) / d;
  const double radius = 0.5 * d;
  const std::int32_t x_lo = static_cast<std::int32_t>(std::floor(mx - radius));
  const std::int32_t x_hi = static_cast<std::int32_t>(std::ceil(mx + radius));
  const std::int32_t y_lo = static_cast<std::int32_t>(std::floor(my - radius));
  const std::int32_t y_hi = static_cast<std::int32_t>(std::ceil(my + radius));
  bool found = false;
  float best_cost = 0.0f;
  double best_offset = 0.0;
  for (std::int32_t iy = y_lo; iy <= y_hi; ++iy) {
    for (std::int32_t ix = x_lo; ix <= x_hi; ++ix) {
      const double rx = ix - mx, ry = iy - my;
      if (std::abs(rx * ux + ry * uy) > epsilon) continue;       // outside the epsilon band
      const double offset2 = rx * rx + ry * ry;
      if (offset2 > radius * radius) continue;                   // farther than d/2 from the mid-point
      const GridCell y{ix, iy};
      if (!map.is_free(y) || !query.in_component(y)) continue;   // no PathQry(x0, y, x1)
      ++candidates_examined_;
      const float cost = map.cost_at(y);
      // Minimal cost; ties go to the cell nearest the mid-point (then scan order), so plans are stable.
      if (!found || cost < best_cost || (cost == best_cost && offset2 < best_offset)) {
        found = true;
        best_cost = cost;
        best_offset = offset2;
        *chosen = y;
      }
    }
  }
  return found;
}

Status SplitPath::plan(const GridMapView& map, const GridCell& start, const GridCell& goal,
                       const SplitPathConfig& config, PathQuery& query) {
  size_ = 0;
  candidates_examined_ = 0;
  const Status config_status = config.validate();
  if (!ok(config_status)) return config_status;
  if (map.cost == nullptr) return Status::kInvalidArgument;
  const Status label_status = query.label_component(map, start);
  if (!ok(label_status)) return label_status;
  if (!map.is_free(goal)) return Status::kNoFreeCell;
  if (!query.in_component(goal)) return Status::kNoPath;

  const double epsilon = config.epsilon_cells;
  std::int32_t top = 0;
  stack_[top++] = Item{start, goal, goal, false};
  while (top > 0) {
    const Item item = stack_[--top];
    if (item.emit) {
      if (size_ >= kMaxPlanningGridCells - 1) {  // keep one slot for the goal
        size_ = 0;
        return Status::kPoolFull;
      }
      waypoints_[size_] = item.mid;
      records_[size_] = SplitRecord{item.a, item.b};
      ++size_;
      continue;
    }
    const double d = std::hypot(static_cast<double>(item.b.ix - item.a.ix), static_cast<double>(item.b.iy - item.a.iy));
    if (d <= 2.0 * epsilon) continue;  // proximity threshold: return TRUE
    GridCell chosen{};
    if (!choose(map, item.a, item.b, epsilon, query, &chosen)) {  // x* = empty: return FALSE
      size_ = 0;
      return Status::kNoPath;
    }
    if (top + 3 > kSplitStackCapacity) {
      size_ = 0;
      return Status::kPoolFull;
    }
    // LIFO: the left half runs first, then x* is inserted, then the right half (Fig. 2's order).
    stack_[top++] = Item{chosen, item.b, chosen, false};
    stack_[top++] = Item{item.a, item.b, chosen, true};
    stack_[top++] = Item{item.a, chosen, chosen, false};
  }
  waypoints_[size_] = goal;
  records_[size_] = SplitRecord{start, goal};
  ++size_;
  return Status::kOk;
}

}  // namespace vantage
