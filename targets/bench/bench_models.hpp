#pragma once
// Shared benchmark fixtures: the paper's bunny as a 70K-primitive model, built once per process.
#include <cstddef>
#include <string>

#include "core/grid/grid_geometry.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage::bench {

inline constexpr std::size_t kBunnyPrimitives = 70000;  // the paper's model: 70K triangles

struct BunnyModel {
  bool ok = false;
  std::string error;  // why the model could not be built (missing mesh file, ...)
  double surface_area = 0.0;
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
  GridGeometry grid;  // the paper's grid: M = 60, 2 units per cell, elevation 0
};

// Loads the glmark2 bunny (sim_hal's loader and normalization: 40 units away it fills half the image),
// samples kBunnyPrimitives area-weighted surface points (seed fixed) and turns each into a primitive: disc
// radius from the area per sample, a random anisotropic covariance (standard deviations 0.01 to 0.2
// units along random axes, like a young model), random saliency h in [0, 1]. Fills the returned pool.
const BunnyModel& bunny_model(PrimitivePoolView** pool_out);

}  // namespace vantage::bench
