// Guest program: vantage's V4L2 driver asked for a pixel format the device does not offer. On vimc's
// capture nodes (RGB and Bayer formats only) YUYV, UYVY, NV12 and GREY are all missing: open() must fail
// with one line that names the device and the requested format, and leave the camera closed. Prints PASS/FAIL lines (guest-init.sh's protocol).
// usage: vm_v4l2_missing_format <device> <format>...   (formats as V4L2 fourccs: YUYV, NV12, ...)
#include <cstdio>
#include <string>

#include "hal/v4l2/v4l2_camera.hpp"

using namespace vantage;
using namespace vantage::hal;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::printf("FAIL v4l2_missing_format: usage: vm_v4l2_missing_format <device> <format>...\n");
    return 2;
  }
  int failures = 0;
  for (int i = 2; i < argc; ++i) {
    const std::string name = std::string("v4l2_missing_format_") + argv[i];
    V4l2Config config;
    config.device = argv[1];
    if (!pixel_format_from_string(argv[i], &config.format)) {
      std::printf("FAIL %s: not a format the driver knows\n", name.c_str());
      ++failures;
      continue;
    }
    V4l2Camera camera;
    const std::string error = camera.open(config);
    if (error.empty() || camera.is_streaming()) {
      std::printf("FAIL %s: open() accepted %s on %s\n", name.c_str(), argv[i], argv[1]);
      ++failures;
    } else if (error.find(argv[i]) == std::string::npos || error.find(argv[1]) == std::string::npos) {
      std::printf("FAIL %s: the error does not name the device and the format: %s\n", name.c_str(),
                  error.c_str());
      ++failures;
    } else {
      std::printf("PASS %s: %s\n", name.c_str(), error.c_str());
    }
  }
  return failures == 0 ? 0 : 1;
}
