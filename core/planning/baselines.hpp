#pragma once
// Cell choices of the baseline policies (see planner_policy.hpp): heap-free helpers the executive uses.
#include <cstddef>
#include <cstdint>

#include "core/common/span.hpp"
#include "core/common/status.hpp"
#include "core/grid/grid_geometry.hpp"
#include "core/planning/path_query.hpp"

namespace vantage {

// splitmix64: a small deterministic generator, so a seed reproduces a random baseline run exactly.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed = 1) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, n) for n > 0 (the modulo bias is below 2^-40 for grid-sized n).
  std::uint64_t below(std::uint64_t n) { return next() % n; }

 private:
  std::uint64_t state_;
};

// The free cells of a circle of radius_m around the grid centre, one lap counter-clockwise starting at
// the cell nearest the angle of from_xy, consecutive cells 8-adjacent where the circle is free (cells on
// non-free stretches are skipped: PathQry then routes around them). kInvalidArgument for a non-positive
// radius or one that leaves the grid; kNoFreeCell when no cell of the circle is free; kPoolFull when
// out is too small. *count gets the number of cells written.
Status orbit_cells(const GridMapView& map, double radius_m, const Eigen::Vector2d& from_xy, Span<GridCell> out,
                   std::size_t* count);

// A uniformly random cell of query's last labelled component other than exclude. kNoFreeCell when the
// component holds no other cell.
Status random_component_cell(const GridMapView& map, const PathQuery& query, const GridCell& exclude, SplitMix64& rng,
                             GridCell* out);

}  // namespace vantage
