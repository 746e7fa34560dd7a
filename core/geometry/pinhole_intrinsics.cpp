#include "core/geometry/pinhole_intrinsics.hpp"

#include <cmath>

namespace vantage {

Status PinholeIntrinsics::validate() const {
  const double values[] = {fx_px, fy_px, cx_px, cy_px, k1, k2};
  for (double v : values) {
    if (!std::isfinite(v)) return Status::kNonFiniteInput;
  }
  if (fx_px <= 0.0 || fy_px <= 0.0 || width_px <= 0 || height_px <= 0) return Status::kInvalidArgument;
  if (cx_px < 0.0 || cy_px < 0.0 || cx_px > width_px || cy_px > height_px) return Status::kInvalidArgument;
  return Status::kOk;
}

PinholeIntrinsics PinholeIntrinsics::default_vga() {
  PinholeIntrinsics k;
  k.width_px = 640;
  k.height_px = 480;
  const double kVerticalFovRad = 45.0 * 3.14159265358979323846 / 180.0;
  k.fy_px = 0.5 * k.height_px / std::tan(0.5 * kVerticalFovRad);
  k.fx_px = k.fy_px;
  k.cx_px = 0.5 * (k.width_px - 1);
  k.cy_px = 0.5 * (k.height_px - 1);
  return k;
}

}  // namespace vantage
