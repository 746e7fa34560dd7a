#pragma once
// Which grid cells the object occupies: a cell is occupied when its square, grown by margin on every
// side, overlaps the vertical (xy) projection of any triangle of the mesh. The robot may not stand there.
#include <cstdint>
#include <vector>

#include "core/grid/grid_geometry.hpp"
#include "sim_hal/scene/triangle_mesh.hpp"

namespace vantage::sim {

class OccupancyGrid {
 public:
  // Throws SimError for a non-positive grid or a negative/non-finite margin.
  OccupancyGrid(const TriangleMesh& mesh, const GridGeometry& grid, double margin);

  const GridGeometry& geometry() const { return grid_; }
  // Outside the grid counts as occupied (not a place the robot may go).
  bool occupied(const GridCell& cell) const;
  bool free(const GridCell& cell) const { return !occupied(cell); }
  // 1 = free, 0 = occupied, flat_index order: feed GridMapView::free.
  const std::vector<std::uint8_t>& free_mask() const { return free_; }
  std::int32_t occupied_count() const;

 private:
  GridGeometry grid_;
  std::vector<std::uint8_t> free_;
};

}  // namespace vantage::sim
