#pragma once
// Mesh files (OBJ, PLY, OFF, anything assimp reads) to a TriangleMesh, and the normalization that puts
// any object into the paper's setup.
#include <string>

#include <Eigen/Core>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "sim_hal/scene/triangle_mesh.hpp"

namespace vantage::sim {

// Loads every mesh of the file into one TriangleMesh (assimp: triangulate, join identical vertices,
// node transforms applied). Throws SimError with one line naming the file when it is missing, cannot be
// parsed, or holds no triangles.
TriangleMesh load_mesh(const std::string& path);

// Which file axis points up. The world is z-up; a y-up file (the glmark2 bunny, most OBJ exports) is
// rotated +90 degrees about x: (x, y, z)_file -> (x, -z, y)_world, which keeps the mesh right-handed.
// kX: (x, y, z)_file -> (y, z, x)_world (a cyclic permutation, also a rotation).
enum class UpAxis { kX, kY, kZ };
const char* to_string(UpAxis axis);

struct NormalizationConfig {
  UpAxis up_axis = UpAxis::kY;
  // The paper's setup: from viewing_distance, looking horizontally at the object's bounding-box centre
  // with the given camera, the object's silhouette covers target_area_fraction of the image (mean over
  // kNormalizationAzimuths azimuths).
  double viewing_distance = 40.0;
  double target_area_fraction = 0.5;
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
  // > 0: use this scale (file units -> scene units) instead of the silhouette fit.
  double fixed_scale = 0.0;
};

inline constexpr int kNormalizationAzimuths = 8;

struct NormalizationResult {
  double scale = 1.0;                                         // scene units per file unit
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();      // applied after rotation and scaling
  double mean_area_fraction = 0.0;                            // silhouette fraction measured at the end
};

// Rotates the mesh to z-up, scales it, and moves its bounding-box centre to the world origin. Throws
// SimError for an empty mesh or a non-positive/non-finite configuration value.
NormalizationResult normalize_for_paper_setup(TriangleMesh& mesh, const NormalizationConfig& config);

// The rotation alone (file frame -> z-up world frame).
void rotate_to_z_up(TriangleMesh& mesh, UpAxis up_axis);

// Mean fraction of image pixels covered by the mesh seen from `distance` at kNormalizationAzimuths
// azimuths, horizontal view at the height of the origin, looking at the origin.
double mean_silhouette_fraction(const TriangleMesh& mesh, double distance, const PinholeIntrinsics& intrinsics);

}  // namespace vantage::sim
