#include "targets/common/search_depth_range.hpp"

#include <cmath>

namespace vantage::targets {

SearchDepthRange default_search_depth_range(const GridGeometry& grid, double viewing_distance_m) {
  const double half_extent_m = 0.5 * grid.cells_per_side * grid.cell_size_m;
  return SearchDepthRange{0.125 * viewing_distance_m, std::sqrt(2.0) * half_extent_m + 0.25 * viewing_distance_m};
}

}  // namespace vantage::targets
