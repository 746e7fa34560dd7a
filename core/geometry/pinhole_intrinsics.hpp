#pragma once
// Pinhole camera intrinsics with two-term radial distortion (Brown's k1, k2; plumb_bob without the
// tangential terms). Pixel coordinates: u right, v down, origin at the centre of the top-left pixel.
#include <cstdint>

#include "core/common/status.hpp"

namespace vantage {

struct PinholeIntrinsics {
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  std::int32_t width_px = 0;
  std::int32_t height_px = 0;
  double k1 = 0.0;  // radial distortion on r^2 of normalized coordinates
  double k2 = 0.0;  // radial distortion on r^4

  // kOk, kNonFiniteInput or kInvalidArgument (non-positive focal length or size, principal point
  // outside the image).
  Status validate() const;

  // The paper's camera: 640x480, focal length chosen for a 45 degree vertical field of view, no
  // distortion. At 40 units the bunny (normalized by sim_hal) fills about half the image.
  static PinholeIntrinsics default_vga();
};

}  // namespace vantage
