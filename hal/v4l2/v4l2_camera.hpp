#pragma once
// hal::Camera on a V4L2 capture device: single-planar video capture with mmap streaming. open()
// negotiates pixel format, size and frame rate, maps a fixed number of buffers and starts streaming;
// grab() waits for a frame with poll(), dequeues it, converts it to gray into the caller's buffer and
// queues the buffer again. Kernel timestamps (CLOCK_MONOTONIC) are passed through.
//
// Failures: open() returns one line naming the device and the problem (missing node, not a V4L2 device,
// no capture or streaming, a format or size the device lacks, busy). grab() returns kTimeout when no
// frame came in time, kDeviceLost on ENODEV/EIO (unplugged, unbound, module removed: call reopen()),
// kCorruptFrame for a frame the driver flagged or that is short, kBufferTooSmall, kNotStarted.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "hal/camera.hpp"
#include "hal/v4l2/gray_convert.hpp"

namespace vantage::hal {

struct V4l2Config {
  std::string device = "/dev/video0";
  PixelFormat format = PixelFormat::kYuyv;
  std::int32_t width_px = 640;
  std::int32_t height_px = 480;
  double frame_rate_hz = 30.0;  // requested; the device may round it (frame_rate_hz() tells)
  int buffer_count = 4;
  // Intrinsics for this size (hal/calibration); their size must match width_px x height_px.
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
};

class V4l2Camera final : public Camera {
 public:
  static constexpr int kMaxBuffers = 8;

  V4l2Camera() = default;
  ~V4l2Camera();
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  // Empty string on success; otherwise one line saying what is wrong, and the camera stays closed.
  std::string open(const V4l2Config& config);
  // Closes and opens again with the last configuration (after kDeviceLost).
  std::string reopen();
  void close();
  bool is_streaming() const { return streaming_; }

  CaptureStatus grab(MutableGrayImageView& out, FrameInfo& info, std::int32_t timeout_ms) override;
  const PinholeIntrinsics& intrinsics() const override { return config_.intrinsics; }
  const char* name() const override { return name_; }

  double frame_rate_hz() const { return actual_frame_rate_hz_; }
  std::int32_t stride_bytes() const { return stride_bytes_; }
  int buffer_count() const { return buffer_count_; }
  const char* driver() const { return driver_; }
  const char* card() const { return card_; }

 private:
  std::string fail(const std::string& what);
  std::string negotiate_format();
  std::string set_frame_rate();
  std::string map_buffers();
  std::string supported_formats();

  struct Mapping {
    void* start = nullptr;
    std::size_t length = 0;
  };

  V4l2Config config_;
  int fd_ = -1;
  bool streaming_ = false;
  Mapping buffers_[kMaxBuffers];
  int buffer_count_ = 0;
  std::int32_t stride_bytes_ = 0;
  std::size_t image_bytes_ = 0;
  bool monotonic_timestamps_ = true;
  double actual_frame_rate_hz_ = 0.0;
  char name_[96] = "v4l2:closed";
  char driver_[32] = "";
  char card_[64] = "";
};

}  // namespace vantage::hal
