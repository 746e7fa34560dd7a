#pragma once
// hal::Camera on libcamera (0.0.3, Debian 12), in the pattern of libcamera's simple-cam: a
// CameraManager, one camera chosen by id, one stream configured and validated, buffers
// (FrameBufferAllocator) and one request per buffer created once at open(), every completed request
// requeued. The completion callback runs on libcamera's thread and only queues the request; grab() waits
// for it, converts plane 0 (mmap of its dmabuf, mapped once at open) to gray, and requeues it.
// close() stops the camera, frees buffers, releases the camera and only then stops the manager.
//
// libcamera allows one CameraManager per process, so one LibcameraCamera per process.
// LIBCAMERA_LOG_LEVELS='*:ERROR' quiets libcamera's own logging.
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "hal/camera.hpp"
#include "hal/v4l2/gray_convert.hpp"

namespace libcamera {
class Camera;
class CameraConfiguration;
class CameraManager;
class FrameBufferAllocator;
class Request;
class Stream;
}  // namespace libcamera

namespace vantage::hal {

struct LibcameraConfig {
  std::string camera_id;  // empty: the first camera libcamera lists
  PixelFormat format = PixelFormat::kYuyv;  // GREY=R8, YUYV, UYVY, NV12, RGB3=BGR888, BGR3=RGB888, XR24=XRGB8888
  std::int32_t width_px = 640;
  std::int32_t height_px = 480;
  int buffer_count = 4;
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
};

class LibcameraCamera final : public Camera {
 public:
  static constexpr int kMaxBuffers = 8;

  LibcameraCamera();
  ~LibcameraCamera();
  LibcameraCamera(const LibcameraCamera&) = delete;
  LibcameraCamera& operator=(const LibcameraCamera&) = delete;

  // Empty string on success, else one line (no cameras, unknown id with the ids present, busy, a format
  // or size the stream cannot give, allocation failures). On failure everything is released.
  std::string open(const LibcameraConfig& config);
  void close();
  bool is_streaming() const { return streaming_; }
  // Ids of the cameras libcamera sees (starts and stops its own manager when none is running).
  std::vector<std::string> camera_ids();

  CaptureStatus grab(MutableGrayImageView& out, FrameInfo& info, std::int32_t timeout_ms) override;
  const PinholeIntrinsics& intrinsics() const override { return config_.intrinsics; }
  const char* name() const override { return name_; }

 private:
  void on_request_completed(libcamera::Request* request);
  void on_camera_removed(std::shared_ptr<libcamera::Camera> camera);
  std::string fail(const std::string& what);

  struct Mapping {
    void* base = nullptr;
    std::size_t map_length = 0;
    std::size_t offset = 0;
    std::size_t length = 0;
  };

  LibcameraConfig config_;
  std::unique_ptr<libcamera::CameraManager> manager_;
  std::shared_ptr<libcamera::Camera> camera_;
  std::unique_ptr<libcamera::CameraConfiguration> configuration_;
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator_;
  libcamera::Stream* stream_ = nullptr;
  std::vector<std::unique_ptr<libcamera::Request>> requests_;
  Mapping mappings_[kMaxBuffers];
  int buffer_count_ = 0;
  std::int32_t stride_bytes_ = 0;
  bool acquired_ = false;
  bool started_ = false;
  bool streaming_ = false;

  // Completed requests waiting for grab(): a fixed ring filled by the callback.
  std::mutex mutex_;
  std::condition_variable completed_cv_;
  libcamera::Request* completed_[kMaxBuffers] = {};
  int completed_head_ = 0;
  int completed_count_ = 0;
  bool lost_ = false;

  char name_[96] = "libcamera:closed";
};

}  // namespace vantage::hal
