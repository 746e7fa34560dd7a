#include "core/planning/baselines.hpp"

#include <cmath>
#include <cstring>

#include "core/planning/planner_policy.hpp"

namespace vantage {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

const char* to_string(PlannerPolicy policy) {
  switch (policy) {
    case PlannerPolicy::kNbv: return "nbv";
    case PlannerPolicy::kReactive: return "reactive";
    case PlannerPolicy::kDirect: return "direct";
    case PlannerPolicy::kOrbit: return "orbit";
    case PlannerPolicy::kRandom: return "random";
  }
  return "unknown";
}

bool parse_planner_policy(const char* name, PlannerPolicy* policy) {
  if (name == nullptr) return false;
  for (const PlannerPolicy candidate : kAllPlannerPolicies) {
    if (std::strcmp(name, to_string(candidate)) == 0) {
      *policy = candidate;
      return true;
    }
  }
  return false;
}

Status orbit_cells(const GridMapView& map, double radius_m, const Eigen::Vector2d& from_xy, Span<GridCell> out,
                   std::size_t* count) {
  *count = 0;
  const GridGeometry& geo = map.geometry;
  const double half_extent_m = 0.5 * geo.cells_per_side * geo.cell_size_m;
  if (!std::isfinite(radius_m) || radius_m <= 0.0 || radius_m >= half_extent_m || geo.cell_size_m <= 0.0) {
    return Status::kInvalidArgument;
  }
  const Eigen::Vector2d rel = from_xy - geo.center_xy;
  const double start_angle = rel.norm() > 0.0 ? std::atan2(rel.y(), rel.x()) : 0.0;
  // Eight samples per cell of circumference: no cell the circle crosses is skipped.
  const int samples = static_cast<int>(std::ceil(8.0 * 2.0 * kPi * radius_m / geo.cell_size_m));
  std::size_t n = 0;
  GridCell last{-1, -1};
  for (int s = 0; s < samples; ++s) {
    const double angle = start_angle + 2.0 * kPi * s / samples;
    const GridCell cell = geo.cell_of(geo.center_xy + radius_m * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
    if (cell == last || !map.is_free(cell)) continue;
    if (n > 0 && cell == out[0]) break;  // closed the lap
    if (n == out.size()) return Status::kPoolFull;
    out[n++] = cell;
    last = cell;
  }
  if (n == 0) return Status::kNoFreeCell;
  *count = n;
  return Status::kOk;
}

Status random_component_cell(const GridMapView& map, const PathQuery& query, const GridCell& exclude, SplitMix64& rng,
                             GridCell* out) {
  const std::int32_t others = query.component_size() - (query.in_component(exclude) ? 1 : 0);
  if (others <= 0) return Status::kNoFreeCell;
  std::int32_t pick = static_cast<std::int32_t>(rng.below(static_cast<std::uint64_t>(others)));
  const GridGeometry& geo = map.geometry;
  for (std::int32_t i = 0; i < geo.cell_count(); ++i) {
    const GridCell cell = geo.cell_at(i);
    if (cell == exclude || !query.in_component(cell)) continue;
    if (pick-- == 0) {
      *out = cell;
      return Status::kOk;
    }
  }
  return Status::kNoFreeCell;
}

}  // namespace vantage
