#include "sim_hal/scene/triangle_mesh.hpp"

#include <algorithm>
#include <cmath>

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

std::vector<Eigen::Vector3f> smooth_corner_normals(const TriangleMesh& mesh, double crease_angle_rad) {
  const std::size_t triangle_count = mesh.triangles.size();
  const std::size_t vertex_count = mesh.vertices.size();
  // Unit face normals and each corner's interior angle (the weight of Thuermer and Wuethrich).
  std::vector<Eigen::Vector3d> face_normal(triangle_count);
  std::vector<double> corner_angle(3 * triangle_count, 0.0);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    face_normal[t] = mesh.triangle_normal(t);
    const auto& tri = mesh.triangles[t];
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d p = mesh.vertices[tri[c]].cast<double>();
      const Eigen::Vector3d a = mesh.vertices[tri[(c + 1) % 3]].cast<double>() - p;
      const Eigen::Vector3d b = mesh.vertices[tri[(c + 2) % 3]].cast<double>() - p;
      const double na = a.norm(), nb = b.norm();
      if (na > 0.0 && nb > 0.0) corner_angle[3 * t + c] = std::acos(std::clamp(a.dot(b) / (na * nb), -1.0, 1.0));
    }
  }
  // Corners around each vertex (compressed rows).
  std::vector<std::uint32_t> first(vertex_count + 1, 0);
  for (const auto& tri : mesh.triangles) {
    for (std::uint32_t v : tri) ++first[v + 1];
  }
  for (std::size_t v = 0; v < vertex_count; ++v) first[v + 1] += first[v];
  std::vector<std::uint32_t> corners(first[vertex_count]);
  std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    for (int c = 0; c < 3; ++c) corners[fill[mesh.triangles[t][c]]++] = static_cast<std::uint32_t>(3 * t + c);
  }
  const double cos_crease = std::cos(crease_angle_rad);
  std::vector<Eigen::Vector3f> out(3 * triangle_count, Eigen::Vector3f::Zero());
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const Eigen::Vector3d& own = face_normal[t];
    const bool degenerate = own.isZero();
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t v = mesh.triangles[t][c];
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (std::uint32_t k = first[v]; k < first[v + 1]; ++k) {
        const std::size_t other = corners[k] / 3;
        const Eigen::Vector3d& n = face_normal[other];
        const double cos_between = own.dot(n);
        if (!degenerate && other != t && std::abs(cos_between) < cos_crease) continue;  // across a crease
        sum += (cos_between < 0.0 ? -1.0 : 1.0) * corner_angle[corners[k]] * n;
      }
      const double length = sum.norm();
      if (length > 0.0) out[3 * t + c] = (sum / length).cast<float>();
    }
  }
  return out;
}

}  // namespace vantage::sim
