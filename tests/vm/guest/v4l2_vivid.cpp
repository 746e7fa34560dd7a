// Guest program: vantage's V4L2 driver (hal/v4l2) against the kernel's vivid test driver, in the VM.
//  - captures in several pixel formats and sizes, converts to gray, and checks each frame against a
//    golden hash (vivid's test pattern is deterministic once its OSD text is off) and frame to frame,
//    and the YUYV gray against the Y bytes of a frame read() without our driver;
//  - asks for a size vivid lacks, MJPEG and a missing node, and expects a clear error each;
//  - unbinds vivid from its driver mid-stream and expects kDeviceLost, a clean failure to reopen while it
//    is gone, and a working reopen() once it is bound again.
// Prints PASS/FAIL lines (guest-init.sh's protocol); with --print-goldens it prints GOLDEN lines
// instead of comparing (tests/vm/regenerate-goldens.sh).
// usage: vm_v4l2_vivid <device> <goldens-file> [--print-goldens]
#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "hal/v4l2/v4l2_camera.hpp"
#include "tests/vm/guest/guest_checks.hpp"

using namespace vantage;
using namespace vantage::hal;
using namespace vantage::vm_guest;

namespace {

// vivid's private controls (drivers/media/test-drivers/vivid/vivid-ctrls.c): OSD text mode 2 = none,
// so no timestamp or counter is drawn into the frames.
constexpr std::uint32_t kVividCidOsdTextMode = 0x00f0f000 + 1;
constexpr const char* kPlatformDevice = "vivid.0";
constexpr const char* kDriverDir = "/sys/bus/platform/drivers/vivid";

std::int64_t monotonic_now_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

PinholeIntrinsics intrinsics_for(std::int32_t width_px, std::int32_t height_px) {
  PinholeIntrinsics k;
  k.fx_px = k.fy_px = 0.8 * width_px;
  k.cx_px = 0.5 * (width_px - 1);
  k.cy_px = 0.5 * (height_px - 1);
  k.width_px = width_px;
  k.height_px = height_px;
  return k;
}

bool set_vivid_control(const char* device, std::uint32_t id, std::int32_t value, std::string* error) {
  const int fd = ::open(device, O_RDWR);
  if (fd < 0) {
    *error = std::string(device) + ": " + std::strerror(errno);
    return false;
  }
  v4l2_control control{};
  control.id = id;
  control.value = value;
  const bool ok = ::ioctl(fd, VIDIOC_S_CTRL, &control) == 0;
  if (!ok) *error = std::string("VIDIOC_S_CTRL: ") + std::strerror(errno);
  ::close(fd);
  return ok;
}

bool write_sysfs(const std::string& path, const char* text, std::string* error) {
  const int fd = ::open(path.c_str(), O_WRONLY);
  if (fd < 0) {
    *error = path + ": " + std::strerror(errno);
    return false;
  }
  const ssize_t n = ::write(fd, text, std::strlen(text));
  const int saved = errno;
  ::close(fd);
  if (n < 0) {
    *error = path + ": " + std::strerror(saved);
    return false;
  }
  return true;
}

bool wait_for_node(const char* device, int timeout_ms) {
  for (int waited = 0; waited < timeout_ms; waited += 20) {
    if (::access(device, F_OK) == 0) return true;
    ::usleep(20000);
  }
  return ::access(device, F_OK) == 0;
}

// An independent reference for the golden hashes: a YUYV frame read with plain read() I/O (no driver of
// ours), hashed over its Y bytes. Empty on failure, with the reason in *error.
std::string reference_yuyv_hash(const char* device, std::int32_t width_px, std::int32_t height_px,
                                std::string* error) {
  const int fd = ::open(device, O_RDWR);
  if (fd < 0) {
    *error = std::string(device) + ": " + std::strerror(errno);
    return {};
  }
  v4l2_format format{};
  format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  format.fmt.pix.width = static_cast<std::uint32_t>(width_px);
  format.fmt.pix.height = static_cast<std::uint32_t>(height_px);
  format.fmt.pix.pixelformat = V4L2_PIX_FMT_YUYV;
  format.fmt.pix.field = V4L2_FIELD_NONE;
  if (::ioctl(fd, VIDIOC_S_FMT, &format) != 0 || format.fmt.pix.pixelformat != V4L2_PIX_FMT_YUYV ||
      format.fmt.pix.width != static_cast<std::uint32_t>(width_px) ||
      format.fmt.pix.height != static_cast<std::uint32_t>(height_px)) {
    *error = std::string("VIDIOC_S_FMT YUYV: ") + std::strerror(errno);
    ::close(fd);
    return {};
  }
  std::vector<std::uint8_t> frame(format.fmt.pix.sizeimage);
  const ssize_t n = ::read(fd, frame.data(), frame.size());
  ::close(fd);
  const std::size_t stride = format.fmt.pix.bytesperline;
  if (n < static_cast<ssize_t>(stride * static_cast<std::size_t>(height_px))) {
    *error = "read() gave " + std::to_string(n) + " bytes: " + std::strerror(errno);
    return {};
  }
  std::uint64_t h = 14695981039346656037ull;
  for (std::int32_t y = 0; y < height_px; ++y) {
    for (std::int32_t x = 0; x < width_px; ++x) {
      h ^= frame[static_cast<std::size_t>(y) * stride + 2 * static_cast<std::size_t>(x)];
      h *= 1099511628211ull;
    }
  }
  return hex(h);
}

// Frame buffer big enough for every case below (1280x720).
std::uint8_t g_pixels[1280 * 720];

struct CaptureCase {
  PixelFormat format;
  std::int32_t width_px;
  std::int32_t height_px;
};

// Opens the camera in this format and size, grabs a few frames, checks them, and returns the hash of
// the gray frame (empty on failure).
std::string capture_case(const char* device, const CaptureCase& c) {
  char name[64];
  std::snprintf(name, sizeof name, "v4l2_capture_%s_%dx%d", to_string(c.format), c.width_px, c.height_px);
  V4l2Config config;
  config.device = device;
  config.format = c.format;
  config.width_px = c.width_px;
  config.height_px = c.height_px;
  config.intrinsics = intrinsics_for(c.width_px, c.height_px);
  V4l2Camera camera;
  const std::string error = camera.open(config);
  if (!error.empty()) {
    fail(name, "open: " + error);
    return {};
  }
  constexpr int kFrames = 4;
  std::uint64_t hashes[kFrames] = {};
  FrameInfo infos[kFrames];
  MutableGrayImageView gray{g_pixels, c.width_px, c.height_px, c.width_px};
  for (int i = 0; i < kFrames; ++i) {
    const CaptureStatus status = camera.grab(gray, infos[i], 2000);
    if (status != CaptureStatus::kOk) {
      fail(name, std::string("grab ") + std::to_string(i) + ": " + to_string(status));
      return {};
    }
    if (gray.width_px != c.width_px || gray.height_px != c.height_px) {
      fail(name, "frame is " + std::to_string(gray.width_px) + "x" + std::to_string(gray.height_px));
      return {};
    }
    hashes[i] = hash_gray(gray);
  }
  const std::int64_t now_ns = monotonic_now_ns();
  for (int i = 1; i < kFrames; ++i) {
    if (hashes[i] != hashes[0]) {
      fail(name, "frame " + std::to_string(i) + " differs from frame 0 (" + hex(hashes[i]) + " vs " + hex(hashes[0]) +
                     "): the pattern is not static");
      return {};
    }
    if (infos[i].sequence <= infos[i - 1].sequence || infos[i].timestamp_ns <= infos[i - 1].timestamp_ns) {
      fail(name, "sequence or timestamp did not increase between frames " + std::to_string(i - 1) + " and " +
                     std::to_string(i));
      return {};
    }
  }
  // Kernel timestamps are CLOCK_MONOTONIC: the last frame is from the last two seconds. vivid stamps a
  // frame with its nominal end-of-frame time, which under emulation can lead the clock a little.
  const std::int64_t age_ns = now_ns - infos[kFrames - 1].timestamp_ns;
  if (age_ns < -200000000 || age_ns > 2000000000) {
    fail(name, "last frame's timestamp is " + std::to_string(age_ns) + " ns from CLOCK_MONOTONIC now");
    return {};
  }
  const int distinct = distinct_values(gray);
  if (distinct < 6) {
    fail(name, "only " + std::to_string(distinct) + " gray levels: not vivid's colour bars");
    return {};
  }
  char detail[160];
  std::snprintf(detail, sizeof detail, "%d frames, %d gray levels, %.1f Hz, stride %d, %s", kFrames, distinct,
                camera.frame_rate_hz(), camera.stride_bytes(), camera.name());
  pass(name, detail);
  return hex(hashes[0]);
}

// A size vivid does not offer, MJPEG (which this build cannot decode) and a missing node: open() fails
// with one line naming what is wrong. (A pixel format the device lacks is checked on vimc, which has no
// Y'CbCr formats: vivid offers every format the driver converts; see v4l2_missing_format.cpp.)
void check_missing(const char* device) {
  V4l2Config config;
  config.device = device;
  config.format = PixelFormat::kMjpeg;
  V4l2Camera camera;
  std::string error = camera.open(config);
  if (error.empty() || camera.is_streaming()) {
    fail("v4l2_mjpeg_refused", "MJPEG opened, but this build has no JPEG decoder");
  } else if (error.find("MJPEG") == std::string::npos) {
    fail("v4l2_mjpeg_refused", "the error does not name the format: " + error);
  } else {
    pass("v4l2_mjpeg_refused", error);
  }

  config.format = PixelFormat::kYuyv;
  config.width_px = 800;
  config.height_px = 600;  // vivid's webcam input offers 320x180 ... 3840x2160, not 800x600
  config.intrinsics = intrinsics_for(800, 600);
  error = camera.open(config);
  if (error.empty() || camera.is_streaming()) {
    fail("v4l2_missing_size", "800x600 opened on vivid's webcam input, which lacks it");
  } else if (error.find("800") == std::string::npos) {
    fail("v4l2_missing_size", "the error does not name the size: " + error);
  } else {
    pass("v4l2_missing_size", error);
  }

  config.device = "/dev/video9";
  config.width_px = 640;
  config.height_px = 480;
  config.intrinsics = intrinsics_for(640, 480);
  error = camera.open(config);
  if (error.empty() || error.find("/dev/video9") == std::string::npos) {
    fail("v4l2_missing_device", "no clear error for a missing node: '" + error + "'");
  } else {
    pass("v4l2_missing_device", error);
  }
}

// Unbinds vivid from another thread while grab() waits for frames: the driver must report kDeviceLost
// (not hang, not crash), fail to reopen while the device is gone, and capture again after a rebind.
void check_device_loss(const char* device) {
  V4l2Config config;
  config.device = device;
  V4l2Camera camera;
  std::string error = camera.open(config);
  if (!error.empty()) {
    fail("v4l2_unbind", "open: " + error);
    return;
  }
  MutableGrayImageView gray{g_pixels, 640, 480, 640};
  FrameInfo info;
  if (camera.grab(gray, info, 2000) != CaptureStatus::kOk) {
    fail("v4l2_unbind", "no first frame");
    return;
  }
  std::atomic<bool> unbound{false};
  std::string unbind_error;
  std::thread unbinder([&] {
    ::usleep(300000);
    unbound = write_sysfs(std::string(kDriverDir) + "/unbind", kPlatformDevice, &unbind_error);
  });
  CaptureStatus status = CaptureStatus::kOk;
  int frames = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (status == CaptureStatus::kOk && std::chrono::steady_clock::now() < deadline) {
    status = camera.grab(gray, info, 1000);
    if (status == CaptureStatus::kOk) ++frames;
  }
  unbinder.join();
  if (!unbound) {
    fail("v4l2_unbind", "could not unbind vivid: " + unbind_error);
    return;
  }
  if (status != CaptureStatus::kDeviceLost) {
    fail("v4l2_unbind", std::string("after the unbind grab() said ") + to_string(status) + ", expected device lost");
    return;
  }
  pass("v4l2_unbind", "device lost after " + std::to_string(frames) + " frames; grab() said " + to_string(status));

  error = camera.reopen();
  if (error.empty()) {
    fail("v4l2_reopen_while_gone", "reopen() succeeded with vivid unbound");
  } else {
    pass("v4l2_reopen_while_gone", error);
  }

  if (!write_sysfs(std::string(kDriverDir) + "/bind", kPlatformDevice, &error)) {
    fail("v4l2_rebind", "could not bind vivid again: " + error);
    return;
  }
  if (!wait_for_node(device, 5000)) {
    fail("v4l2_rebind", std::string(device) + " did not come back after the bind");
    return;
  }
  // The rebound instance starts with its OSD text on again; the frames only need to arrive here.
  error = camera.reopen();
  if (!error.empty()) {
    fail("v4l2_rebind", "reopen() after the bind: " + error);
    return;
  }
  status = camera.grab(gray, info, 2000);
  if (status != CaptureStatus::kOk) {
    fail("v4l2_rebind", std::string("grab() after reopen(): ") + to_string(status));
    return;
  }
  pass("v4l2_rebind", "reopen() after the bind captures again (" + std::string(camera.name()) + ")");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::printf("FAIL v4l2_vivid: usage: vm_v4l2_vivid <device> <goldens-file> [--print-goldens]\n");
    return 2;
  }
  const char* device = argv[1];
  const bool print_goldens = argc > 3 && std::strcmp(argv[3], "--print-goldens") == 0;
  std::string goldens_error;
  const std::map<std::string, std::string> goldens = read_goldens(argv[2], &goldens_error);
  if (!print_goldens && goldens.empty()) {
    fail("v4l2_goldens", goldens_error);
    return 1;
  }

  std::string error;
  if (!set_vivid_control(device, kVividCidOsdTextMode, 2, &error)) {
    fail("vivid_osd_off", error);
    return 1;
  }
  pass("vivid_osd_off", "vivid's OSD text mode set to none");

  const CaptureCase cases[] = {
      {PixelFormat::kYuyv, 640, 480}, {PixelFormat::kNv12, 640, 480},  {PixelFormat::kGrey, 640, 480},
      {PixelFormat::kUyvy, 640, 480}, {PixelFormat::kRgb24, 640, 480}, {PixelFormat::kYuyv, 1280, 720},
      {PixelFormat::kYuyv, 320, 180},
  };
  std::map<std::string, std::string> hashes;
  for (const CaptureCase& c : cases) {
    const std::string key = std::string(to_string(c.format)) + " " + std::to_string(c.width_px) + "x" +
                            std::to_string(c.height_px);
    const std::string hash = capture_case(device, c);
    if (hash.empty()) continue;
    hashes[key] = hash;
    if (print_goldens) {
      std::printf("GOLDEN vivid %s %s\n", key.c_str(), hash.c_str());
      continue;
    }
    const auto golden = goldens.find("vivid " + key);
    const std::string name = "v4l2_golden_" + key.substr(0, key.find(' ')) + "_" + key.substr(key.find(' ') + 1);
    if (golden == goldens.end()) {
      fail(name.c_str(), "no golden hash for 'vivid " + key + "' in " + argv[2]);
    } else if (golden->second != hash) {
      fail(name.c_str(), "gray frame hash " + hash + ", golden " + golden->second);
    } else {
      pass(name.c_str(), "gray frame matches the golden hash " + hash);
    }
  }
  // The same luma in every Y'CbCr layout: YUYV, UYVY and NV12 carry identical Y samples.
  if (!hashes["YUYV 640x480"].empty() && hashes["YUYV 640x480"] == hashes["NV12 640x480"] &&
      hashes["YUYV 640x480"] == hashes["UYVY 640x480"]) {
    pass("v4l2_same_luma", "YUYV, UYVY and NV12 give the same gray frame");
  } else {
    fail("v4l2_same_luma", "YUYV " + hashes["YUYV 640x480"] + ", UYVY " + hashes["UYVY 640x480"] + ", NV12 " +
                               hashes["NV12 640x480"] + " differ");
  }

  // The goldens are our driver's output; this ties them to the raw Y bytes the kernel produced.
  std::string reference_error;
  const std::string reference = reference_yuyv_hash(device, 640, 480, &reference_error);
  if (reference.empty()) {
    fail("v4l2_reference_YUYV_640x480", "read() I/O: " + reference_error);
  } else if (reference != hashes["YUYV 640x480"]) {
    fail("v4l2_reference_YUYV_640x480", "driver gray " + hashes["YUYV 640x480"] + ", Y bytes of a frame read() " +
                                            "without our driver " + reference);
  } else {
    pass("v4l2_reference_YUYV_640x480", "driver gray equals the Y bytes of a frame read() without our driver (" +
                                            reference + ")");
  }

  check_missing(device);
  check_device_loss(device);
  return g_failures == 0 ? 0 : 1;
}
