#pragma once
// Surface appearance shared by the renderer and tests: the procedural solid texture and pixel noise.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sim_hal/scene/scene_config.hpp"

namespace vantage::sim {

// A 3D value-noise solid texture: trilinear, smoothstep-interpolated random values on a cubic lattice of
// spacing feature_size; albedo = constant + contrast * noise, clamped to [0, 1].
// The lattice values come from a fixed table indexed by a spatial hash, so the texture is the same for
// every run and seed (the scene's look does not depend on the noise seed).
class SolidTexture {
 public:
  explicit SolidTexture(const AlbedoConfig& config);
  float albedo(float x, float y, float z) const;

 private:
  float noise(float x, float y, float z) const;  // in [-1, 1]

  AlbedoConfig config_;
  float inv_feature_size_;
  std::vector<float> table_;  // kTableSize values in [-1, 1]
};

// A standard normal variate that depends only on (seed, stream, index): deterministic pixel noise.
float hashed_gaussian(std::uint32_t seed, std::uint64_t stream, std::uint64_t index);

}  // namespace vantage::sim
