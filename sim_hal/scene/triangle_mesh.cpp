#include "sim_hal/scene/triangle_mesh.hpp"

namespace vantage::sim {

Eigen::AlignedBox3d TriangleMesh::bounds() const {
  Eigen::AlignedBox3d box;
  for (const auto& t : triangles) {
    for (std::uint32_t i : t) box.extend(vertices[i].cast<double>());
  }
  return box;
}

double TriangleMesh::triangle_area(std::size_t t) const {
  const auto& tri = triangles[t];
  const Eigen::Vector3d a = vertices[tri[0]].cast<double>();
  const Eigen::Vector3d b = vertices[tri[1]].cast<double>();
  const Eigen::Vector3d c = vertices[tri[2]].cast<double>();
  return 0.5 * (b - a).cross(c - a).norm();
}

Eigen::Vector3d TriangleMesh::triangle_normal(std::size_t t) const {
  const auto& tri = triangles[t];
  const Eigen::Vector3d a = vertices[tri[0]].cast<double>();
  const Eigen::Vector3d b = vertices[tri[1]].cast<double>();
  const Eigen::Vector3d c = vertices[tri[2]].cast<double>();
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0.0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

double TriangleMesh::surface_area() const {
  double area = 0.0;
  for (std::size_t t = 0; t < triangles.size(); ++t) area += triangle_area(t);
  return area;
}

}  // namespace vantage::sim
