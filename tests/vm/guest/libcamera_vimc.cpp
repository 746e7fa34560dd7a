// Guest program: vantage's libcamera driver (hal/libcamera) against the kernel's vimc, through
// libcamera's own vimc pipeline handler and IPA module, in the VM.
//  - turns Sensor B's OSD text off (vimc's "Show Information" control = None) so frames are fixed;
//  - enumerates the cameras and finds vimc's;
//  - captures in the stream formats vimc offers, converts to gray, checks frame to frame and against
//    golden hashes;
//  - asks for an unknown camera id and a format the stream lacks, and expects a clear error each;
//  - holds the camera while a second process tries it (busy), then releases it and checks that a second
//    process can now take it and that this process can open it again.
// Prints PASS/FAIL lines (guest-init.sh's protocol); with --print-goldens it prints GOLDEN lines.
// usage: vm_libcamera_vimc <goldens-file> [--print-goldens]
//        vm_libcamera_vimc --try-open <camera-id>   (the second process: prints "OPENED" or the error)
#include <fcntl.h>
#include <linux/videodev2.h>
#include <spawn.h>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "hal/libcamera/libcamera_camera.hpp"
#include "tests/vm/guest/guest_checks.hpp"

extern char** environ;

using namespace vantage;
using namespace vantage::hal;
using namespace vantage::vm_guest;

namespace {

// vimc's private sensor control (drivers/media/test-drivers/vimc/vimc-common.h): VIMC_CID_OSD_TEXT_MODE,
// shown as "Show Information"; 2 = None, so no timestamp or counter is drawn.
constexpr std::uint32_t kVimcCidOsdTextMode = 0x00f0f000 + 2;

std::string read_line(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

// Finds the subdevice node of the entity with this name and sets a control on it.
bool set_subdev_control(const char* entity, std::uint32_t id, std::int32_t value, std::string* detail) {
  for (int i = 0; i < 64; ++i) {
    const std::string sys = "/sys/class/video4linux/v4l-subdev" + std::to_string(i);
    if (read_line(sys + "/name") != entity) continue;
    const std::string node = "/dev/v4l-subdev" + std::to_string(i);
    const int fd = ::open(node.c_str(), O_RDWR);
    if (fd < 0) {
      *detail = node + ": " + std::strerror(errno);
      return false;
    }
    v4l2_queryctrl query{};
    query.id = id;
    if (::ioctl(fd, VIDIOC_QUERYCTRL, &query) != 0) {
      *detail = node + " (" + entity + ") has no control " + hex(id) + ": " + std::strerror(errno);
      ::close(fd);
      return false;
    }
    v4l2_control control{};
    control.id = id;
    control.value = value;
    const bool ok = ::ioctl(fd, VIDIOC_S_CTRL, &control) == 0;
    *detail = ok ? node + " (" + entity + "): '" + reinterpret_cast<const char*>(query.name) + "' = " +
                       std::to_string(value)
                 : node + ": VIDIOC_S_CTRL: " + std::strerror(errno);
    ::close(fd);
    return ok;
  }
  *detail = std::string("no subdevice named '") + entity + "'";
  return false;
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

LibcameraConfig config_for(const std::string& id, PixelFormat format, std::int32_t width_px, std::int32_t height_px) {
  LibcameraConfig config;
  config.camera_id = id;
  config.format = format;
  config.width_px = width_px;
  config.height_px = height_px;
  config.intrinsics = intrinsics_for(width_px, height_px);
  return config;
}

std::uint8_t g_pixels[960 * 720];

// Grabs a few frames from an open camera; returns the gray hash, empty on failure (reported).
std::string grab_frames(LibcameraCamera& camera, const std::string& name, std::int32_t width_px,
                        std::int32_t height_px) {
  constexpr int kFrames = 4;
  MutableGrayImageView gray{g_pixels, width_px, height_px, width_px};
  std::uint64_t hashes[kFrames] = {};
  FrameInfo infos[kFrames];
  for (int i = 0; i < kFrames; ++i) {
    const CaptureStatus status = camera.grab(gray, infos[i], 3000);
    if (status != CaptureStatus::kOk) {
      fail(name, "grab " + std::to_string(i) + ": " + to_string(status));
      return {};
    }
    if (gray.width_px != width_px || gray.height_px != height_px) {
      fail(name, "frame is " + std::to_string(gray.width_px) + "x" + std::to_string(gray.height_px));
      return {};
    }
    hashes[i] = hash_gray(gray);
  }
  for (int i = 1; i < kFrames; ++i) {
    if (hashes[i] != hashes[0]) {
      fail(name, "frame " + std::to_string(i) + " differs from frame 0: the pattern is not static");
      return {};
    }
    if (infos[i].sequence <= infos[i - 1].sequence || infos[i].timestamp_ns <= infos[i - 1].timestamp_ns) {
      fail(name, "sequence or timestamp did not increase at frame " + std::to_string(i));
      return {};
    }
  }
  const int distinct = distinct_values(gray);
  if (distinct < 6) {
    fail(name, "only " + std::to_string(distinct) + " gray levels: not vimc's colour bars");
    return {};
  }
  pass(name, std::to_string(kFrames) + " frames, " + std::to_string(distinct) + " gray levels, " + camera.name());
  return hex(hashes[0]);
}

// Runs this program again as a second process that tries to open the camera; returns its output line.
std::string try_open_in_child(const std::string& id, int* exit_code) {
  char self[] = "/proc/self/exe";
  int fds[2];
  if (::pipe(fds) != 0) return "pipe failed";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  std::string id_copy = id;
  char try_open[] = "--try-open";
  char* argv[] = {self, try_open, id_copy.data(), nullptr};
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, self, &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[1]);
  std::string output;
  char chunk[512];
  ssize_t n = 0;
  while (spawned == 0 && (n = ::read(fds[0], chunk, sizeof chunk)) > 0) output.append(chunk, static_cast<std::size_t>(n));
  ::close(fds[0]);
  if (spawned != 0) return std::string("posix_spawn: ") + std::strerror(spawned);
  int status = 0;
  ::waitpid(pid, &status, 0);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
  while (!output.empty() && output.back() == '\n') output.pop_back();
  return output;
}

int try_open_main(const std::string& id) {
  LibcameraCamera camera;
  const std::string error = camera.open(config_for(id, PixelFormat::kRgb24, 636, 480));
  if (error.empty()) {
    std::printf("OPENED %s\n", camera.name());
    camera.close();
    return 0;
  }
  std::printf("%s\n", error.c_str());
  return 1;
}

struct StreamCase {
  PixelFormat format;
  std::int32_t width_px;
  std::int32_t height_px;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::strcmp(argv[1], "--try-open") == 0) return try_open_main(argv[2]);
  if (argc < 2) {
    std::printf("FAIL libcamera_vimc: usage: vm_libcamera_vimc <goldens-file> [--print-goldens]\n");
    return 2;
  }
  const bool print_goldens = argc > 2 && std::strcmp(argv[2], "--print-goldens") == 0;
  std::string goldens_error;
  const std::map<std::string, std::string> goldens = read_goldens(argv[1], &goldens_error);
  if (!print_goldens && goldens.empty()) {
    fail("libcamera_goldens", goldens_error);
    return 1;
  }

  std::string detail;
  if (!set_subdev_control("Sensor B", kVimcCidOsdTextMode, 2, &detail)) {
    fail("vimc_osd_off", detail);
    return 1;
  }
  pass("vimc_osd_off", detail);

  LibcameraCamera camera;
  const std::vector<std::string> ids = camera.camera_ids();
  std::string id;
  for (const std::string& candidate : ids) {
    if (candidate.find("vimc") != std::string::npos) id = candidate;
  }
  if (ids.size() != 1 || id.empty()) {
    std::string all;
    for (const std::string& candidate : ids) all += " '" + candidate + "'";
    fail("libcamera_enumerate", "expected exactly vimc's camera, libcamera lists" + (all.empty() ? " none" : all));
    return 1;
  }
  pass("libcamera_enumerate", "one camera: " + id);

  // libcamera 0.0.3's vimc pipeline offers BGR888 and RGB888 (our RGB3 and BGR3) at widths that are
  // multiples of 6 (it adjusts 640x480 to 636x480: the scaler triples the sensor's size).
  const StreamCase cases[] = {
      {PixelFormat::kRgb24, 636, 480},
      {PixelFormat::kBgr24, 636, 480},
      {PixelFormat::kRgb24, 960, 720},
  };
  std::map<std::string, std::string> hashes;
  for (const StreamCase& c : cases) {
    const std::string key =
        std::string(to_string(c.format)) + " " + std::to_string(c.width_px) + "x" + std::to_string(c.height_px);
    const std::string name = "libcamera_capture_" + std::string(to_string(c.format)) + "_" +
                             std::to_string(c.width_px) + "x" + std::to_string(c.height_px);
    const std::string error = camera.open(config_for(id, c.format, c.width_px, c.height_px));
    if (!error.empty()) {
      fail(name, "open: " + error);
      continue;
    }
    const std::string hash = grab_frames(camera, name, c.width_px, c.height_px);
    camera.close();
    if (hash.empty()) continue;
    hashes[key] = hash;
    if (print_goldens) {
      std::printf("GOLDEN vimc %s %s\n", key.c_str(), hash.c_str());
      continue;
    }
    const auto golden = goldens.find("vimc " + key);
    const std::string golden_name = "libcamera_golden_" + name.substr(std::strlen("libcamera_capture_"));
    if (golden == goldens.end()) {
      fail(golden_name, "no golden hash for 'vimc " + key + "' in " + argv[1]);
    } else if (golden->second != hash) {
      fail(golden_name, "gray frame hash " + hash + ", golden " + golden->second);
    } else {
      pass(golden_name, "gray frame matches the golden hash " + hash);
    }
  }

  // Both byte orders carry the same picture, so the same gray (the conversion weighs the right channels).
  if (!hashes["RGB3 636x480"].empty() && hashes["RGB3 636x480"] == hashes["BGR3 636x480"]) {
    pass("libcamera_same_gray", "RGB3 and BGR3 give the same gray frame");
  } else {
    fail("libcamera_same_gray", "RGB3 " + hashes["RGB3 636x480"] + " and BGR3 " + hashes["BGR3 636x480"] + " differ");
  }

  // Bad requests: clear one-line errors, nothing left open.
  std::string error = camera.open(config_for("no-such-camera", PixelFormat::kRgb24, 640, 480));
  if (error.empty() || error.find(id) == std::string::npos) {
    fail("libcamera_unknown_id", "no error listing the cameras present: '" + error + "'");
  } else {
    pass("libcamera_unknown_id", error);
  }
  error = camera.open(config_for(id, PixelFormat::kNv12, 636, 480));
  if (error.empty() || error.find("NV12") == std::string::npos || camera.is_streaming()) {
    fail("libcamera_missing_format", "NV12 (vimc has no Y'CbCr output) gave: '" + error + "'");
  } else {
    pass("libcamera_missing_format", error);
  }

  // Held here, busy for another process; released, free for it; and this process can take it again.
  error = camera.open(config_for(id, PixelFormat::kRgb24, 636, 480));
  if (!error.empty()) {
    fail("libcamera_busy", "open: " + error);
    return 1;
  }
  int child_exit = 0;
  std::string child = try_open_in_child(id, &child_exit);
  // libcamera 0.0.3 does not even list a camera another process streams from (its vimc handler cannot
  // reset the media links), so the refusal may read "no cameras found" rather than "busy".
  if (child_exit == 0 || child.empty() || child.rfind("OPENED", 0) == 0) {
    fail("libcamera_busy", "a second process opening the held camera said: '" + child + "'");
  } else {
    pass("libcamera_busy", "second process refused: " + child);
  }
  camera.close();
  child = try_open_in_child(id, &child_exit);
  if (child_exit != 0 || child.rfind("OPENED", 0) != 0) {
    fail("libcamera_release", "after close() a second process could not open the camera: '" + child + "'");
  } else {
    pass("libcamera_release", "after close() a second process opened it: " + child);
  }
  error = camera.open(config_for(id, PixelFormat::kRgb24, 636, 480));
  if (!error.empty()) {
    fail("libcamera_reopen", error);
  } else if (!grab_frames(camera, "libcamera_reopen", 636, 480).empty()) {
    camera.close();
  }
  return g_failures == 0 ? 0 : 1;
}
