#include "core/planning/path_query.hpp"

#include <cmath>
#include <cstdlib>

namespace vantage {

namespace {

constexpr std::int32_t kDx[8] = {1, -1, 0, 0, 1, 1, -1, -1};
constexpr std::int32_t kDy[8] = {0, 0, 1, -1, 1, -1, 1, -1};

float octile(const GridCell& a, const GridCell& b) {
  const std::int32_t dx = std::abs(a.ix - b.ix);
  const std::int32_t dy = std::abs(a.iy - b.iy);
  const std::int32_t lo = dx < dy ? dx : dy;
  const std::int32_t hi = dx < dy ? dy : dx;
  return static_cast<float>((hi - lo) + kSqrt2 * lo);
}

}  // namespace

Status PathQuery::check_map(const GridMapView& map) {
  const std::int32_t m = map.geometry.cells_per_side;
  if (m <= 0 || m > kMaxPlanningGridSide || map.free == nullptr) return Status::kInvalidArgument;
  return Status::kOk;
}

bool PathQuery::step_allowed(const GridMapView& map, const GridCell& a, const GridCell& b) {
  const std::int32_t dx = b.ix - a.ix;
  const std::int32_t dy = b.iy - a.iy;
  if (dx < -1 || dx > 1 || dy < -1 || dy > 1 || (dx == 0 && dy == 0)) return false;
  if (!map.is_free(a) || !map.is_free(b)) return false;
  if (dx != 0 && dy != 0) {
    return map.is_free(GridCell{a.ix + dx, a.iy}) && map.is_free(GridCell{a.ix, a.iy + dy});
  }
  return true;
}

Status PathQuery::find(const GridMapView& map, const GridCell& start, const GridCell& goal) {
  path_size_ = 0;
  length_cells_ = 0.0;
  expanded_ = 0;
  const Status map_status = check_map(map);
  if (!ok(map_status)) return map_status;
  if (!map.is_free(start) || !map.is_free(goal)) return Status::kNoFreeCell;

  const GridGeometry& geo = map.geometry;
  const std::int32_t n = geo.cell_count();
  for (std::int32_t i = 0; i < n; ++i) {
    state_[i] = 0;
    heap_pos_[i] = -1;
  }
  heap_size_ = 0;
  const std::int32_t start_i = geo.flat_index(start);
  const std::int32_t goal_i = geo.flat_index(goal);
  g_[start_i] = 0.0f;
  parent_[start_i] = -1;
  state_[start_i] = 1;
  heap_push(start_i, octile(start, goal));

  bool found = false;
  while (heap_size_ > 0) {
    const std::int32_t current_i = heap_pop();
    state_[current_i] = 2;
    ++expanded_;
    if (current_i == goal_i) {
      found = true;
      break;
    }
    const GridCell current = geo.cell_at(current_i);
    for (int k = 0; k < 8; ++k) {
      const GridCell next{current.ix + kDx[k], current.iy + kDy[k]};
      if (!step_allowed(map, current, next)) continue;
      const std::int32_t next_i = geo.flat_index(next);
      if (state_[next_i] == 2) continue;
      const float step = (kDx[k] != 0 && kDy[k] != 0) ? static_cast<float>(kSqrt2) : 1.0f;
      const float g = g_[current_i] + step;
      if (state_[next_i] == 0) {
        g_[next_i] = g;
        parent_[next_i] = current_i;
        state_[next_i] = 1;
        heap_push(next_i, g + octile(next, goal));
      } else if (g < g_[next_i]) {
        g_[next_i] = g;
        parent_[next_i] = current_i;
        heap_decrease(next_i, g + octile(next, goal));
      }
    }
  }
  if (!found) return Status::kNoPath;

  // Walk the parents back, then reverse in place so the path runs start -> goal.
  std::int32_t count = 0;
  for (std::int32_t i = goal_i; i != -1; i = parent_[i]) path_[count++] = geo.cell_at(i);
  for (std::int32_t a = 0, b = count - 1; a < b; ++a, --b) {
    const GridCell t = path_[a];
    path_[a] = path_[b];
    path_[b] = t;
  }
  path_size_ = count;
  double length = 0.0;
  for (std::int32_t i = 1; i < count; ++i) {
    length += (path_[i].ix != path_[i - 1].ix && path_[i].iy != path_[i - 1].iy) ? kSqrt2 : 1.0;
  }
  length_cells_ = length;
  return Status::kOk;
}

Status PathQuery::label_component(const GridMapView& map, const GridCell& start) {
  component_size_ = 0;
  component_geometry_ = GridGeometry{};
  component_geometry_.cells_per_side = 0;
  const Status map_status = check_map(map);
  if (!ok(map_status)) return map_status;
  if (!map.is_free(start)) return Status::kNoFreeCell;
  const GridGeometry& geo = map.geometry;
  const std::int32_t n = geo.cell_count();
  for (std::int32_t i = 0; i < n; ++i) component_[i] = 0;
  // Breadth-first flood fill; heap_ doubles as the FIFO queue (each cell enters it once).
  std::int32_t head = 0;
  std::int32_t tail = 0;
  const std::int32_t start_i = geo.flat_index(start);
  component_[start_i] = 1;
  heap_[tail++] = start_i;
  while (head < tail) {
    const GridCell current = geo.cell_at(heap_[head++]);
    for (int k = 0; k < 8; ++k) {
      const GridCell next{current.ix + kDx[k], current.iy + kDy[k]};
      if (!step_allowed(map, current, next)) continue;
      const std::int32_t next_i = geo.flat_index(next);
      if (component_[next_i] != 0) continue;
      component_[next_i] = 1;
      heap_[tail++] = next_i;
    }
  }
  heap_size_ = 0;
  component_size_ = tail;
  component_geometry_ = geo;
  return Status::kOk;
}

bool PathQuery::in_component(const GridCell& cell) const {
  if (!component_geometry_.contains(cell)) return false;
  return component_[component_geometry_.flat_index(cell)] != 0;
}

void PathQuery::heap_push(std::int32_t cell, float key) {
  f_[cell] = key;
  heap_[heap_size_] = cell;
  heap_pos_[cell] = heap_size_;
  ++heap_size_;
  sift_up(heap_size_ - 1);
}

void PathQuery::heap_decrease(std::int32_t cell, float key) {
  f_[cell] = key;
  sift_up(heap_pos_[cell]);
}

std::int32_t PathQuery::heap_pop() {
  const std::int32_t top = heap_[0];
  heap_pos_[top] = -1;
  --heap_size_;
  if (heap_size_ > 0) {
    heap_[0] = heap_[heap_size_];
    heap_pos_[heap_[0]] = 0;
    sift_down(0);
  }
  return top;
}

// Ties on f are broken towards larger g (deeper nodes), which keeps A* from spreading over plateaus.
namespace {
inline bool heap_less(const float* f, const float* g, std::int32_t a, std::int32_t b) {
  if (f[a] != f[b]) return f[a] < f[b];
  return g[a] > g[b];
}
}  // namespace

void PathQuery::sift_up(std::int32_t pos) {
  while (pos > 0) {
    const std::int32_t parent = (pos - 1) / 2;
    if (!heap_less(f_, g_, heap_[pos], heap_[parent])) break;
    const std::int32_t t = heap_[pos];
    heap_[pos] = heap_[parent];
    heap_[parent] = t;
    heap_pos_[heap_[pos]] = pos;
    heap_pos_[heap_[parent]] = parent;
    pos = parent;
  }
}

void PathQuery::sift_down(std::int32_t pos) {
  for (;;) {
    const std::int32_t left = 2 * pos + 1;
    const std::int32_t right = left + 1;
    std::int32_t best = pos;
    if (left < heap_size_ && heap_less(f_, g_, heap_[left], heap_[best])) best = left;
    if (right < heap_size_ && heap_less(f_, g_, heap_[right], heap_[best])) best = right;
    if (best == pos) break;
    const std::int32_t t = heap_[pos];
    heap_[pos] = heap_[best];
    heap_[best] = t;
    heap_pos_[heap_[pos]] = pos;
    heap_pos_[heap_[best]] = best;
    pos = best;
  }
}

}  // namespace vantage
