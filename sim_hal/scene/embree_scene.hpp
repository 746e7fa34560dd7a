#pragma once
// The world's geometry for ray casting and closest-point queries: one Embree 3 device and scene holding a
// TriangleMesh (kept alongside). Thread-safe for concurrent queries after construction.
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <embree3/rtcore.h>

#include "sim_hal/scene/triangle_mesh.hpp"

namespace vantage::sim {

// Neighbouring triangles whose planes differ by more than this are not smoothed across (a box's edges,
// a cut's rim); the bunny's neighbouring facets differ by far less.
inline constexpr double kSmoothCreaseAngleRad = 60.0 * 3.14159265358979323846 / 180.0;

struct ClosestPoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double distance = 0.0;
  std::uint32_t triangle = 0;
  bool found = false;  // false when nothing lies within the query radius
};

class EmbreeScene {
 public:
  // Throws SimError when the mesh is empty or Embree fails.
  explicit EmbreeScene(TriangleMesh mesh);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  const TriangleMesh& mesh() const { return mesh_; }
  // Smooth-shading normals per triangle corner (smooth_corner_normals with kSmoothCreaseAngleRad),
  // computed once here after the mesh has its final placement.
  const std::vector<Eigen::Vector3f>& corner_normals() const { return corner_normals_; }
  RTCScene handle() const { return scene_; }

  // True when the open segment from `from` to `to` hits the mesh (ends shortened by `epsilon` units).
  bool occluded(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double epsilon = 1e-3) const;
  // Ray distance to the first hit along unit direction, or +inf.
  double first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, std::uint32_t* triangle = nullptr) const;
  // Closest point on the mesh within max_distance (Embree point query).
  ClosestPoint closest_point(const Eigen::Vector3d& query, double max_distance) const;

 private:
  TriangleMesh mesh_;
  std::vector<Eigen::Vector3f> corner_normals_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace vantage::sim
