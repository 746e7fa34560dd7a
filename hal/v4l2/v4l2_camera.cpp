#include "hal/v4l2/v4l2_camera.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>

namespace vantage::hal {
namespace {

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

std::uint32_t fourcc(PixelFormat format) {
  switch (format) {
    case PixelFormat::kGrey: return V4L2_PIX_FMT_GREY;
    case PixelFormat::kYuyv: return V4L2_PIX_FMT_YUYV;
    case PixelFormat::kUyvy: return V4L2_PIX_FMT_UYVY;
    case PixelFormat::kNv12: return V4L2_PIX_FMT_NV12;
    case PixelFormat::kRgb24: return V4L2_PIX_FMT_RGB24;
    case PixelFormat::kBgr24: return V4L2_PIX_FMT_BGR24;
    case PixelFormat::kBgrx32: return V4L2_PIX_FMT_XBGR32;
    case PixelFormat::kMjpeg: return V4L2_PIX_FMT_MJPEG;
  }
  return 0;
}

std::string fourcc_text(std::uint32_t code) {
  char text[5] = {static_cast<char>(code & 0xFF), static_cast<char>((code >> 8) & 0xFF),
                  static_cast<char>((code >> 16) & 0xFF), static_cast<char>((code >> 24) & 0xFF), 0};
  return text;
}

std::string errno_text(const char* call) { return std::string(call) + ": " + std::strerror(errno); }

}  // namespace

V4l2Camera::~V4l2Camera() { close(); }

std::string V4l2Camera::fail(const std::string& what) {
  const std::string message = "v4l2:" + config_.device + ": " + what;
  close();
  return message;
}

void V4l2Camera::close() {
  if (fd_ >= 0 && streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(fd_, VIDIOC_STREAMOFF, &type);
  }
  streaming_ = false;
  for (int i = 0; i < buffer_count_; ++i) {
    if (buffers_[i].start != nullptr) ::munmap(buffers_[i].start, buffers_[i].length);
    buffers_[i] = Mapping{};
  }
  buffer_count_ = 0;
  if (fd_ >= 0) {
    // Give the buffers back so another process (or our reopen) can stream.
    v4l2_requestbuffers release{};
    release.count = 0;
    release.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    release.memory = V4L2_MEMORY_MMAP;
    xioctl(fd_, VIDIOC_REQBUFS, &release);
    ::close(fd_);
  }
  fd_ = -1;
}

std::string V4l2Camera::reopen() { return open(config_); }

std::string V4l2Camera::open(const V4l2Config& config) {
  close();
  config_ = config;
  std::snprintf(name_, sizeof name_, "v4l2:%s", config_.device.c_str());
  if (config_.buffer_count < 2 || config_.buffer_count > kMaxBuffers) {
    return fail("buffer_count must be 2.." + std::to_string(kMaxBuffers));
  }
  if (config_.width_px <= 0 || config_.height_px <= 0 || !(config_.frame_rate_hz > 0.0)) {
    return fail("width, height and frame rate must be positive");
  }
  if (config_.intrinsics.width_px != config_.width_px || config_.intrinsics.height_px != config_.height_px) {
    return fail("the calibration is for " + std::to_string(config_.intrinsics.width_px) + "x" +
                std::to_string(config_.intrinsics.height_px) + " but capture is set to " + std::to_string(config_.width_px) +
                "x" + std::to_string(config_.height_px));
  }
  if (config_.format == PixelFormat::kMjpeg) {
    return fail("MJPEG needs a JPEG decoder this build does not include; use GREY, YUYV, UYVY, NV12, RGB3, BGR3 or XR24");
  }

  fd_ = ::open(config_.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) return fail(std::string("cannot open: ") + std::strerror(errno));
  struct stat st{};
  if (::fstat(fd_, &st) != 0 || !S_ISCHR(st.st_mode)) return fail("not a character device, so not a V4L2 device");

  v4l2_capability cap{};
  if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0) return fail("not a V4L2 device (" + errno_text("VIDIOC_QUERYCAP") + ")");
  std::snprintf(driver_, sizeof driver_, "%s", reinterpret_cast<const char*>(cap.driver));
  std::snprintf(card_, sizeof card_, "%s", reinterpret_cast<const char*>(cap.card));
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) return fail("only multi-planar capture, which this driver does not support");
    return fail(std::string("'") + card_ + "' has no video capture");
  }
  if (!(caps & V4L2_CAP_STREAMING)) return fail("no streaming I/O (mmap)");

  std::string error = negotiate_format();
  if (!error.empty()) return fail(error);
  error = set_frame_rate();
  if (!error.empty()) return fail(error);
  error = map_buffers();
  if (!error.empty()) return fail(error);

  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_STREAMON, &type) != 0) {
    if (errno == EBUSY) return fail("busy: another process is streaming from it");
    return fail(errno_text("VIDIOC_STREAMON"));
  }
  streaming_ = true;
  return {};
}

std::string V4l2Camera::supported_formats() {
  std::string list;
  for (std::uint32_t index = 0; index < 64; ++index) {
    v4l2_fmtdesc desc{};
    desc.index = index;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_ENUM_FMT, &desc) != 0) break;
    if (!list.empty()) list += " ";
    list += fourcc_text(desc.pixelformat);
  }
  return list.empty() ? "none" : list;
}

std::string V4l2Camera::negotiate_format() {
  v4l2_format format{};
  format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  format.fmt.pix.width = static_cast<std::uint32_t>(config_.width_px);
  format.fmt.pix.height = static_cast<std::uint32_t>(config_.height_px);
  format.fmt.pix.pixelformat = fourcc(config_.format);
  format.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd_, VIDIOC_S_FMT, &format) != 0) {
    if (errno == EBUSY) return "busy: another process is using it";
    return errno_text("VIDIOC_S_FMT");
  }
  if (format.fmt.pix.pixelformat != fourcc(config_.format)) {
    return std::string("pixel format ") + to_string(config_.format) + " not supported (device offers " + supported_formats() + ")";
  }
  if (format.fmt.pix.width != static_cast<std::uint32_t>(config_.width_px) ||
      format.fmt.pix.height != static_cast<std::uint32_t>(config_.height_px)) {
    return "size " + std::to_string(config_.width_px) + "x" + std::to_string(config_.height_px) + " not supported (device gave " +
           std::to_string(format.fmt.pix.width) + "x" + std::to_string(format.fmt.pix.height) + ")";
  }
  if (format.fmt.pix.field != V4L2_FIELD_NONE && format.fmt.pix.field != V4L2_FIELD_ANY) {
    return "interlaced video is not supported";
  }
  const std::uint32_t min_stride =
      static_cast<std::uint32_t>(min_line_bytes(config_.format, static_cast<std::int32_t>(format.fmt.pix.width)));
  stride_bytes_ = static_cast<std::int32_t>(format.fmt.pix.bytesperline != 0 ? format.fmt.pix.bytesperline : min_stride);
  if (static_cast<std::uint32_t>(stride_bytes_) < min_stride) return "driver reports a line stride shorter than a line";
  image_bytes_ = format.fmt.pix.sizeimage;
  return {};
}

std::string V4l2Camera::set_frame_rate() {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_G_PARM, &parm) != 0 || !(parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
    actual_frame_rate_hz_ = 0.0;  // the device does not let us choose; 0 = unknown
    return {};
  }
  parm.parm.capture.timeperframe.numerator = 1000;
  parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(config_.frame_rate_hz * 1000.0));
  if (xioctl(fd_, VIDIOC_S_PARM, &parm) != 0) return errno_text("VIDIOC_S_PARM");
  const v4l2_fract& t = parm.parm.capture.timeperframe;
  actual_frame_rate_hz_ = t.numerator != 0 ? static_cast<double>(t.denominator) / t.numerator : 0.0;
  return {};
}

std::string V4l2Camera::map_buffers() {
  v4l2_requestbuffers request{};
  request.count = static_cast<std::uint32_t>(config_.buffer_count);
  request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  request.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_REQBUFS, &request) != 0) {
    if (errno == EBUSY) return "busy: another process holds its buffers";
    if (errno == EINVAL) return "no mmap streaming";
    return errno_text("VIDIOC_REQBUFS");
  }
  if (request.count < 2) return "the driver granted fewer than 2 buffers";
  if (request.count > static_cast<std::uint32_t>(kMaxBuffers)) return "the driver insists on more than " + std::to_string(kMaxBuffers) + " buffers";
  for (std::uint32_t i = 0; i < request.count; ++i) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    buffer.index = i;
    if (xioctl(fd_, VIDIOC_QUERYBUF, &buffer) != 0) return errno_text("VIDIOC_QUERYBUF");
    void* start = ::mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buffer.m.offset);
    if (start == MAP_FAILED) return errno_text("mmap");
    buffers_[i] = Mapping{start, buffer.length};
    buffer_count_ = static_cast<int>(i + 1);
    monotonic_timestamps_ = (buffer.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    if (xioctl(fd_, VIDIOC_QBUF, &buffer) != 0) return errno_text("VIDIOC_QBUF");
  }
  return {};
}

CaptureStatus V4l2Camera::grab(MutableGrayImageView& out, FrameInfo& info, std::int32_t timeout_ms) {
  if (!streaming_ || fd_ < 0) return CaptureStatus::kNotStarted;
  const std::size_t needed = static_cast<std::size_t>(config_.width_px) * static_cast<std::size_t>(config_.height_px);
  if (out.pixels == nullptr || out.size_bytes() < needed) return CaptureStatus::kBufferTooSmall;

  pollfd pfd{fd_, POLLIN, 0};
  int ready;
  do {
    ready = ::poll(&pfd, 1, timeout_ms);
  } while (ready < 0 && errno == EINTR);
  if (ready == 0) return CaptureStatus::kTimeout;
  if (ready < 0 || (pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
    // POLLERR also comes before the first QBUF; here all buffers are queued, so it means a dead device.
    streaming_ = false;
    return CaptureStatus::kDeviceLost;
  }

  v4l2_buffer buffer{};
  buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buffer.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_DQBUF, &buffer) != 0) {
    if (errno == EAGAIN) return CaptureStatus::kTimeout;
    streaming_ = false;  // ENODEV, EIO, EPIPE: the device is gone or broken
    return CaptureStatus::kDeviceLost;
  }
  CaptureStatus status = CaptureStatus::kOk;
  if (buffer.index >= static_cast<std::uint32_t>(buffer_count_)) {
    return CaptureStatus::kCorruptFrame;  // not ours to requeue
  }
  if (buffer.flags & V4L2_BUF_FLAG_ERROR) {
    status = CaptureStatus::kCorruptFrame;
  } else {
    const std::uint8_t* data = static_cast<const std::uint8_t*>(buffers_[buffer.index].start);
    const std::size_t used = buffer.bytesused != 0 ? buffer.bytesused : buffers_[buffer.index].length;
    const std::size_t bytes = used < buffers_[buffer.index].length ? used : buffers_[buffer.index].length;
    MutableGrayImageView converted = out;
    if (!convert_to_gray(config_.format, data, bytes, config_.width_px, config_.height_px, stride_bytes_, &converted)) {
      status = CaptureStatus::kCorruptFrame;
    } else {
      out = converted;
      if (monotonic_timestamps_) {
        info.timestamp_ns = static_cast<std::int64_t>(buffer.timestamp.tv_sec) * 1'000'000'000 +
                            static_cast<std::int64_t>(buffer.timestamp.tv_usec) * 1000;
      } else {
        timespec now{};
        clock_gettime(CLOCK_MONOTONIC, &now);
        info.timestamp_ns = static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
      }
      info.sequence = buffer.sequence;
    }
  }
  if (xioctl(fd_, VIDIOC_QBUF, &buffer) != 0) {
    streaming_ = false;
    return CaptureStatus::kDeviceLost;
  }
  return status;
}

}  // namespace vantage::hal
