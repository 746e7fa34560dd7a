#pragma once
// Camera capability: grab one 8-bit gray frame into a buffer the caller owns. Implemented by the V4L2
// and libcamera drivers (hal/) and by the ray-cast camera (sim_hal/); the planner cannot tell which.
#include <cstdint>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/image/gray_image.hpp"

namespace vantage::hal {

enum class CaptureStatus : std::uint8_t {
  kOk = 0,
  kTimeout,          // no frame within the timeout
  kDeviceLost,       // unplugged, EIO, module removed: reopen() may bring it back
  kBufferTooSmall,   // the caller's buffer cannot hold the configured frame size
  kNotStarted,       // streaming was not started or failed to start
  kCorruptFrame,     // a truncated or malformed frame (dropped)
};

const char* to_string(CaptureStatus status);

struct FrameInfo {
  std::int64_t timestamp_ns = 0;    // capture time, CLOCK_MONOTONIC (kernel timestamp where available)
  std::uint32_t sequence = 0;       // frame counter from the driver
};

class Camera {
 public:
  // Fills out.pixels (the caller's buffer, at least intrinsics().width_px x height_px) and sets the view's
  // size; on error the buffer content is unspecified and info untouched.
  virtual CaptureStatus grab(MutableGrayImageView& out, FrameInfo& info, std::int32_t timeout_ms) = 0;
  virtual const PinholeIntrinsics& intrinsics() const = 0;
  // A short human-readable name ("v4l2:/dev/video0", "libcamera:<id>", "sim:raycast").
  virtual const char* name() const = 0;

 protected:
  ~Camera() = default;
};

}  // namespace vantage::hal
