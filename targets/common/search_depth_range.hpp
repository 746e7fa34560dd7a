#pragma once
// The image front end's epipolar search range (camera z) when a mission does not set one.
#include "core/grid/grid_geometry.hpp"

namespace vantage::targets {

struct SearchDepthRange {
  double min_m = 0.0;
  double max_m = 0.0;
};

// From close to the object (the planner goes close: 1/8 of the viewing distance) to a quarter of the
// viewing distance beyond the grid's far corner. Wider ranges (1 unit to the grid's extent) made the
// two-view initialization find nothing: the epipolar segment is then too long for a unique NCC peak.
SearchDepthRange default_search_depth_range(const GridGeometry& grid, double viewing_distance_m);

}  // namespace vantage::targets
