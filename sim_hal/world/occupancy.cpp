#include "sim_hal/world/occupancy.hpp"

#include <algorithm>
#include <cmath>

#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

// Separating-axis test of a 2D triangle against an axis-aligned rectangle [lo, hi].
bool triangle_overlaps_box(const Eigen::Vector2d (&p)[3], const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  for (int axis = 0; axis < 2; ++axis) {
    const double mn = std::min({p[0][axis], p[1][axis], p[2][axis]});
    const double mx = std::max({p[0][axis], p[1][axis], p[2][axis]});
    if (mx < lo[axis] || mn > hi[axis]) return false;
  }
  const Eigen::Vector2d corners[4] = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
  for (int e = 0; e < 3; ++e) {
    const Eigen::Vector2d edge = p[(e + 1) % 3] - p[e];
    const Eigen::Vector2d axis(-edge.y(), edge.x());
    if (axis.squaredNorm() == 0.0) continue;
    double tmin = std::min({axis.dot(p[0]), axis.dot(p[1]), axis.dot(p[2])});
    double tmax = std::max({axis.dot(p[0]), axis.dot(p[1]), axis.dot(p[2])});
    double bmin = axis.dot(corners[0]);
    double bmax = bmin;
    for (const auto& c : corners) {
      bmin = std::min(bmin, axis.dot(c));
      bmax = std::max(bmax, axis.dot(c));
    }
    if (tmax < bmin || tmin > bmax) return false;
  }
  return true;
}

}  // namespace

OccupancyGrid::OccupancyGrid(const TriangleMesh& mesh, const GridGeometry& grid, double margin) : grid_(grid) {
  if (grid.cells_per_side < 1 || !(grid.cell_size_m > 0.0) || !grid.center_xy.allFinite()) {
    throw SimError("occupancy: invalid grid geometry");
  }
  if (!(margin >= 0.0) || !std::isfinite(margin)) throw SimError("occupancy: margin must be finite and >= 0");
  free_.assign(static_cast<std::size_t>(grid.cell_count()), 1);
  const double half = 0.5 * grid.cell_size_m + margin;
  for (const auto& tri : mesh.triangles) {
    Eigen::Vector2d p[3];
    for (int i = 0; i < 3; ++i) p[i] = mesh.vertices[tri[i]].head<2>().cast<double>();
    const Eigen::Vector2d mn = p[0].cwiseMin(p[1]).cwiseMin(p[2]) - Eigen::Vector2d::Constant(margin);
    const Eigen::Vector2d mx = p[0].cwiseMax(p[1]).cwiseMax(p[2]) + Eigen::Vector2d::Constant(margin);
    const GridCell c0 = grid.cell_of(mn);
    const GridCell c1 = grid.cell_of(mx);
    for (int iy = std::max(0, c0.iy); iy <= std::min(grid.cells_per_side - 1, c1.iy); ++iy) {
      for (int ix = std::max(0, c0.ix); ix <= std::min(grid.cells_per_side - 1, c1.ix); ++ix) {
        const GridCell cell{ix, iy};
        const std::int32_t flat = grid.flat_index(cell);
        if (free_[flat] == 0) continue;
        const Eigen::Vector2d centre = grid.cell_center_xy(cell);
        if (triangle_overlaps_box(p, centre - Eigen::Vector2d::Constant(half), centre + Eigen::Vector2d::Constant(half))) {
          free_[flat] = 0;
        }
      }
    }
  }
}

bool OccupancyGrid::occupied(const GridCell& cell) const {
  return !grid_.contains(cell) || free_[grid_.flat_index(cell)] == 0;
}

std::int32_t OccupancyGrid::occupied_count() const {
  return static_cast<std::int32_t>(std::count(free_.begin(), free_.end(), 0));
}

}  // namespace vantage::sim
