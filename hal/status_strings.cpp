#include "hal/camera.hpp"
#include "hal/motion.hpp"

namespace vantage::hal {

const char* to_string(CaptureStatus status) {
  switch (status) {
    case CaptureStatus::kOk: return "ok";
    case CaptureStatus::kTimeout: return "capture timed out";
    case CaptureStatus::kDeviceLost: return "camera device lost";
    case CaptureStatus::kBufferTooSmall: return "frame buffer too small";
    case CaptureStatus::kNotStarted: return "camera not streaming";
    case CaptureStatus::kCorruptFrame: return "corrupt frame";
  }
  return "unknown capture status";
}

const char* to_string(MotionFault fault) {
  switch (fault) {
    case MotionFault::kNone: return "none";
    case MotionFault::kTargetOccupied: return "target cell is occupied";
    case MotionFault::kNonFiniteTarget: return "target has NaN or Inf";
    case MotionFault::kLinkLost: return "link to the vehicle lost";
    case MotionFault::kRejected: return "vehicle rejected the command";
  }
  return "unknown motion fault";
}

}  // namespace vantage::hal
