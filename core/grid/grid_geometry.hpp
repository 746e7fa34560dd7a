#pragma once
// The navigation/view grid of the paper (section V): an M x M grid of square cells on the plane
// z = elevation_m, centred on the object. Cell (ix, iy) has its centre at
//   center_xy + ((ix + 0.5) - M/2, (iy + 0.5) - M/2) * cell_size_m
// and flat index iy * M + ix. Planners and the criterion share this geometry and the per-cell arrays
// (free mask, cost) through GridMapView.
#include <cstdint>

#include <Eigen/Core>

namespace vantage {

struct GridCell {
  std::int32_t ix = 0;
  std::int32_t iy = 0;
  bool operator==(const GridCell& o) const { return ix == o.ix && iy == o.iy; }
  bool operator!=(const GridCell& o) const { return !(*this == o); }
};

struct GridGeometry {
  std::int32_t cells_per_side = 60;          // M
  double cell_size_m = 2.0;                  // scene units per cell side
  double elevation_m = 0.0;                  // sensor height (world z) of every cell's viewpoint
  Eigen::Vector2d center_xy = Eigen::Vector2d::Zero();  // grid centre = object centre, world x, y

  std::int32_t cell_count() const { return cells_per_side * cells_per_side; }
  bool contains(const GridCell& c) const {
    return c.ix >= 0 && c.iy >= 0 && c.ix < cells_per_side && c.iy < cells_per_side;
  }
  std::int32_t flat_index(const GridCell& c) const { return c.iy * cells_per_side + c.ix; }
  GridCell cell_at(std::int32_t flat) const { return GridCell{flat % cells_per_side, flat / cells_per_side}; }
  Eigen::Vector2d cell_center_xy(const GridCell& c) const {
    const double half = 0.5 * cells_per_side;
    return center_xy + Eigen::Vector2d((c.ix + 0.5) - half, (c.iy + 0.5) - half) * cell_size_m;
  }
  Eigen::Vector3d cell_center_world(const GridCell& c) const {
    const Eigen::Vector2d xy = cell_center_xy(c);
    return Eigen::Vector3d(xy.x(), xy.y(), elevation_m);
  }
  // The cell containing world point xy (may lie outside the grid: check contains()).
  GridCell cell_of(const Eigen::Vector2d& xy) const {
    const Eigen::Vector2d local = (xy - center_xy) / cell_size_m + Eigen::Vector2d::Constant(0.5 * cells_per_side);
    return GridCell{static_cast<std::int32_t>(local.x() < 0 ? local.x() - 1.0 : local.x()),
                    static_cast<std::int32_t>(local.y() < 0 ? local.y() - 1.0 : local.y())};
  }
};

// Read-only view of a grid's per-cell arrays (row-major, flat_index order). free[i] != 0 when a robot
// may stand in cell i; cost[i] in [0, 1], lower is better (the inverse of F scaled linearly, section V).
struct GridMapView {
  GridGeometry geometry;
  const std::uint8_t* free = nullptr;
  const float* cost = nullptr;

  bool is_free(const GridCell& c) const { return geometry.contains(c) && free[geometry.flat_index(c)] != 0; }
  float cost_at(const GridCell& c) const { return cost[geometry.flat_index(c)]; }
};

}  // namespace vantage
