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

// Smooth-shading normals, one per triangle corner (3 * t + corner), unit length, on the side of triangle
// t's own winding normal: the angle-weighted mean of the normals of the triangles around the corner's
// vertex whose planes lie within crease_angle_rad of triangle t's (so a box stays flat-faced while a
// finely tessellated curved surface shades smoothly). Neighbours wound the other way count with their
// normal flipped. A degenerate triangle's corners get its neighbours' mean, or zero when there is none.
std::vector<Eigen::Vector3f> smooth_corner_normals(const TriangleMesh& mesh, double crease_angle_rad);

}  // namespace vantage::sim
