#pragma once
// Ground-truth depth from the ray-cast camera: CAMERA Z (distance along the optical axis, scene units),
// not range along the ray; +infinity where the ray misses the object. Row-major, width x height.
#include <cstdint>
#include <limits>
#include <vector>

namespace vantage::sim {

struct DepthImage {
  std::int32_t width_px = 0;
  std::int32_t height_px = 0;
  std::vector<float> camera_z;  // width_px * height_px

  void resize(std::int32_t width, std::int32_t height) {
    width_px = width;
    height_px = height;
    camera_z.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height),
                    std::numeric_limits<float>::infinity());
  }
  float at(std::int32_t x, std::int32_t y) const { return camera_z[static_cast<std::size_t>(y) * width_px + x]; }
  bool hit(std::int32_t x, std::int32_t y) const { return at(x, y) < std::numeric_limits<float>::infinity(); }
};

}  // namespace vantage::sim
