#pragma once
// Explicit null drivers for hardware a target lacks (the ArduPilot AP_HAL_Empty habit): they say what is
// missing instead of pretending. The camera never delivers a frame (kNotStarted) and names the reason; the
// motion driver refuses every command (kRejected) and never has a pose.
#include <string>

#include "hal/camera.hpp"
#include "hal/motion.hpp"

namespace vantage::hal {

class NullCamera final : public Camera {
 public:
  // reason: what is missing, e.g. "built without libcamera".
  explicit NullCamera(const std::string& reason, const PinholeIntrinsics& intrinsics = PinholeIntrinsics::default_vga());
  CaptureStatus grab(MutableGrayImageView& out, FrameInfo& info, std::int32_t timeout_ms) override;
  const PinholeIntrinsics& intrinsics() const override { return intrinsics_; }
  const char* name() const override { return name_.c_str(); }

 private:
  std::string name_;
  PinholeIntrinsics intrinsics_;
};

class NullMotion final : public Motion {
 public:
  explicit NullMotion(const std::string& reason);
  MotionFault command(const Viewpoint& target) override;
  void update(double dt_s) override;
  PoseReport current_pose() const override { return PoseReport{}; }
  bool arrived() const override { return false; }
  MotionFault fault() const override { return MotionFault::kRejected; }
  const char* name() const { return name_.c_str(); }

 private:
  std::string name_;
};

}  // namespace vantage::hal
