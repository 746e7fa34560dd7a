// V4L2 driver: gray conversion of every supported format, and the open/grab errors that need no camera.
// Captures from a real (virtual) device are proven in tests/vm on vivid.
#include <catch2/catch.hpp>

#include <vector>

#include "hal/v4l2/gray_convert.hpp"
#include "hal/v4l2/v4l2_camera.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;
using namespace vantage::hal;

namespace {

struct Target {
  std::vector<std::uint8_t> pixels;
  MutableGrayImageView view;
  Target(int w, int h) : pixels(static_cast<std::size_t>(w * h), 0xEE) { view = {pixels.data(), w, h, w}; }
};

}  // namespace

TEST_CASE("YUYV and UYVY take the luma bytes, skipping line padding", "[v4l2]") {
  const int w = 4, h = 2, stride = 2 * w + 4;  // 4 bytes of padding per line
  std::vector<std::uint8_t> yuyv(static_cast<std::size_t>(stride * h), 0x77);
  std::vector<std::uint8_t> uyvy(yuyv.size(), 0x77);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::uint8_t luma = static_cast<std::uint8_t>(10 * y + x);
      yuyv[static_cast<std::size_t>(y * stride + 2 * x)] = luma;
      yuyv[static_cast<std::size_t>(y * stride + 2 * x + 1)] = 200;  // chroma
      uyvy[static_cast<std::size_t>(y * stride + 2 * x + 1)] = luma;
      uyvy[static_cast<std::size_t>(y * stride + 2 * x)] = 200;
    }
  }
  for (PixelFormat format : {PixelFormat::kYuyv, PixelFormat::kUyvy}) {
    Target t(w, h);
    const auto& src = format == PixelFormat::kYuyv ? yuyv : uyvy;
    REQUIRE(convert_to_gray(format, src.data(), src.size(), w, h, stride, &t.view));
    CHECK(t.view.width_px == w);
    CHECK(t.view.stride_bytes == w);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) CHECK(t.view.at(x, y) == 10 * y + x);
    }
  }
}

TEST_CASE("GREY and NV12 copy the luma plane", "[v4l2]") {
  const int w = 3, h = 2, stride = 8;
  std::vector<std::uint8_t> nv12(frame_bytes(PixelFormat::kNv12, w, h, stride), 128);
  CHECK(nv12.size() == static_cast<std::size_t>(stride * h * 3 / 2));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) nv12[static_cast<std::size_t>(y * stride + x)] = static_cast<std::uint8_t>(1 + x + 3 * y);
  }
  for (PixelFormat format : {PixelFormat::kGrey, PixelFormat::kNv12}) {
    Target t(w, h);
    REQUIRE(convert_to_gray(format, nv12.data(), nv12.size(), w, h, stride, &t.view));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) CHECK(t.view.at(x, y) == 1 + x + 3 * y);
    }
  }
}

TEST_CASE("RGB formats give BT.601 luma in their byte order", "[v4l2]") {
  // One pixel each of red, green, blue and white, per memory order.
  const std::uint8_t rgb[] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
  const std::uint8_t bgr[] = {0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255};
  const std::uint8_t bgrx[] = {0, 0, 255, 9, 0, 255, 0, 9, 255, 0, 0, 9, 255, 255, 255, 9};
  const std::uint8_t expected[] = {77, 149, 29, 255};  // (77 R + 150 G + 29 B + 128) / 256
  struct Case { PixelFormat format; const std::uint8_t* data; std::size_t size; };
  for (const Case& c : {Case{PixelFormat::kRgb24, rgb, sizeof rgb}, Case{PixelFormat::kBgr24, bgr, sizeof bgr},
                        Case{PixelFormat::kBgrx32, bgrx, sizeof bgrx}}) {
    Target t(4, 1);
    REQUIRE(convert_to_gray(c.format, c.data, c.size, 4, 1, static_cast<std::int32_t>(c.size), &t.view));
    for (int x = 0; x < 4; ++x) CHECK(t.view.at(x, 0) == expected[x]);
  }
}

TEST_CASE("short frames, thin strides and MJPEG are refused without touching the output", "[v4l2]") {
  const int w = 4, h = 4;
  std::vector<std::uint8_t> src(static_cast<std::size_t>(2 * w * h), 1);
  Target t(w, h);
  CHECK_FALSE(convert_to_gray(PixelFormat::kYuyv, src.data(), src.size() - 1, w, h, 2 * w, &t.view));
  CHECK_FALSE(convert_to_gray(PixelFormat::kYuyv, src.data(), src.size(), w, h, 2 * w - 1, &t.view));
  CHECK_FALSE(convert_to_gray(PixelFormat::kMjpeg, src.data(), src.size(), w, h, w, &t.view));
  CHECK_FALSE(convert_to_gray(PixelFormat::kGrey, nullptr, src.size(), w, h, w, &t.view));
  CHECK(t.pixels[0] == 0xEE);
}

TEST_CASE("gray conversion does not allocate", "[v4l2]") {
  const int w = 640, h = 480;
  std::vector<std::uint8_t> src(static_cast<std::size_t>(2 * w * h), 9);
  Target t(w, h);
  bool converted = false;
  REQUIRE_NO_ALLOCATION(converted = convert_to_gray(PixelFormat::kYuyv, src.data(), src.size(), w, h, 2 * w, &t.view));
  CHECK(converted);
}

TEST_CASE("pixel format names round-trip", "[v4l2]") {
  PixelFormat f = PixelFormat::kGrey;
  for (const char* name : {"GREY", "YUYV", "UYVY", "NV12", "RGB3", "BGR3", "XR24", "MJPG"}) {
    REQUIRE(pixel_format_from_string(name, &f));
    CHECK(std::string(to_string(f)) == name);
  }
  CHECK_FALSE(pixel_format_from_string("RGBP", &f));
  CHECK_FALSE(pixel_format_from_string("yuyv", &f));
}

TEST_CASE("a missing device path is a clear error", "[v4l2]") {
  V4l2Camera camera;
  V4l2Config config;
  config.device = "/dev/video-does-not-exist";
  CHECK(camera.open(config) == "v4l2:/dev/video-does-not-exist: cannot open: No such file or directory");
  CHECK_FALSE(camera.is_streaming());
}

TEST_CASE("a character device that is not V4L2 is refused", "[v4l2]") {
  V4l2Camera camera;
  V4l2Config config;
  config.device = "/dev/null";
  const std::string error = camera.open(config);
  CHECK(error.find("v4l2:/dev/null: not a V4L2 device (VIDIOC_QUERYCAP: ") == 0);
}

TEST_CASE("a regular file is refused", "[v4l2]") {
  V4l2Camera camera;
  V4l2Config config;
  config.device = "/proc/self/status";
  CHECK(camera.open(config) == "v4l2:/proc/self/status: not a character device, so not a V4L2 device");
}

TEST_CASE("MJPEG and a calibration of another size are refused before touching the device", "[v4l2]") {
  V4l2Camera camera;
  V4l2Config config;
  config.device = "/dev/null";
  config.format = PixelFormat::kMjpeg;
  CHECK(camera.open(config).find("MJPEG needs a JPEG decoder") != std::string::npos);
  config.format = PixelFormat::kYuyv;
  config.width_px = 1280;
  config.height_px = 720;
  CHECK(camera.open(config) == "v4l2:/dev/null: the calibration is for 640x480 but capture is set to 1280x720");
}

TEST_CASE("grab before open says the camera is not streaming", "[v4l2]") {
  V4l2Camera camera;
  Target t(640, 480);
  FrameInfo info;
  CHECK(camera.grab(t.view, info, 10) == CaptureStatus::kNotStarted);
}
