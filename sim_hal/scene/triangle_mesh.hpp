#pragma once
// An indexed triangle mesh in world (or file) coordinates, scene units. Triangles wind counter-clockwise
// seen from outside, so the geometric normal (v1 - v0) x (v2 - v0) points out of a closed object.
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vantage::sim {

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;

  // Axis-aligned bounds of the vertices actually used by triangles (empty box for an empty mesh).
  Eigen::AlignedBox3d bounds() const;
  // Sum of triangle areas, units^2.
  double surface_area() const;
  // Unit outward normal of triangle t (zero for a degenerate triangle).
  Eigen::Vector3d triangle_normal(std::size_t t) const;
  double triangle_area(std::size_t t) const;
};

}  // namespace vantage::sim
