#include "hal/null/null_drivers.hpp"

namespace vantage::hal {

NullCamera::NullCamera(const std::string& reason, const PinholeIntrinsics& intrinsics)
    : name_("null:no camera (" + reason + ")"), intrinsics_(intrinsics) {}

CaptureStatus NullCamera::grab(MutableGrayImageView& /*out*/, FrameInfo& /*info*/, std::int32_t /*timeout_ms*/) {
  return CaptureStatus::kNotStarted;
}

NullMotion::NullMotion(const std::string& reason) : name_("null:no vehicle (" + reason + ")") {}

MotionFault NullMotion::command(const Viewpoint& /*target*/) { return MotionFault::kRejected; }

void NullMotion::update(double /*dt_s*/) {}

}  // namespace vantage::hal
