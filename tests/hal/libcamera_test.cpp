// libcamera driver on a machine without cameras: clear errors, no crash, orderly release. Captures from
// a real (virtual) camera are proven in tests/vm on vimc.
#include <catch2/catch.hpp>

#include <vector>

#include "hal/libcamera/libcamera_camera.hpp"

using namespace vantage;
using namespace vantage::hal;

TEST_CASE("libcamera with no camera present is a clear error and can be retried", "[libcamera]") {
  LibcameraCamera camera;
  if (!camera.camera_ids().empty()) {
    WARN("this machine has a libcamera camera: the no-camera path is not exercised here");
    return;
  }
  LibcameraConfig config;
  CHECK(camera.open(config) == "libcamera:(first): no cameras found");
  CHECK_FALSE(camera.is_streaming());
  config.camera_id = "/base/platform/vimc.0/sensor";
  CHECK(camera.open(config) == "libcamera:/base/platform/vimc.0/sensor: no cameras found");
  std::vector<std::uint8_t> pixels(640 * 480);
  MutableGrayImageView view{pixels.data(), 640, 480, 640};
  FrameInfo info;
  CHECK(camera.grab(view, info, 10) == CaptureStatus::kNotStarted);
}

TEST_CASE("libcamera refuses MJPEG and a mismatched calibration before starting", "[libcamera]") {
  LibcameraCamera camera;
  LibcameraConfig config;
  config.format = PixelFormat::kMjpeg;
  CHECK(camera.open(config) == "libcamera:(first): pixel format MJPG is not supported (no decoder in this build)");
  config.format = PixelFormat::kYuyv;
  config.width_px = 320;
  CHECK(camera.open(config) == "libcamera:(first): the calibration is for 640x480 but capture is set to 320x480");
}
