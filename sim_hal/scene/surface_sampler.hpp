#pragma once
// Area-weighted random points on a mesh surface: the ground-truth samples and the oracle's candidate
// primitive sites. Deterministic for a fixed seed (std::mt19937 with explicit distributions).
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sim_hal/scene/triangle_mesh.hpp"

namespace vantage::sim {

struct SurfaceSample {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // on the surface, world frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // unit outward normal of the triangle
  std::uint32_t triangle = 0;                          // index into TriangleMesh::triangles
};

// count samples, each triangle chosen with probability proportional to its area, the point uniform on
// it. An empty result for an empty or zero-area mesh.
std::vector<SurfaceSample> sample_surface(const TriangleMesh& mesh, std::size_t count, std::uint32_t seed);

}  // namespace vantage::sim
