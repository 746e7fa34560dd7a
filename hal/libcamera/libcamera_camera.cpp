#include "hal/libcamera/libcamera_camera.hpp"

#include <sys/mman.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <libcamera/libcamera.h>

namespace vantage::hal {
namespace {

bool libcamera_format(PixelFormat format, libcamera::PixelFormat* out) {
  switch (format) {
    case PixelFormat::kGrey: *out = libcamera::formats::R8; return true;
    case PixelFormat::kYuyv: *out = libcamera::formats::YUYV; return true;
    case PixelFormat::kUyvy: *out = libcamera::formats::UYVY; return true;
    case PixelFormat::kNv12: *out = libcamera::formats::NV12; return true;
    case PixelFormat::kRgb24: *out = libcamera::formats::BGR888; return true;   // memory R G B
    case PixelFormat::kBgr24: *out = libcamera::formats::RGB888; return true;   // memory B G R
    case PixelFormat::kBgrx32: *out = libcamera::formats::XRGB8888; return true;  // memory B G R X
    case PixelFormat::kMjpeg: return false;
  }
  return false;
}

}  // namespace

LibcameraCamera::LibcameraCamera() = default;
LibcameraCamera::~LibcameraCamera() { close(); }

std::string LibcameraCamera::fail(const std::string& what) {
  const std::string message = std::string(name_) + ": " + what;
  close();
  return message;
}

std::vector<std::string> LibcameraCamera::camera_ids() {
  std::vector<std::string> ids;
  libcamera::CameraManager* manager = manager_.get();
  std::unique_ptr<libcamera::CameraManager> temporary;
  if (manager == nullptr) {
    temporary = std::make_unique<libcamera::CameraManager>();
    if (temporary->start() != 0) return ids;
    manager = temporary.get();
  }
  for (const auto& camera : manager->cameras()) ids.push_back(camera->id());
  if (temporary) temporary->stop();
  return ids;
}

std::string LibcameraCamera::open(const LibcameraConfig& config) {
  close();
  config_ = config;
  std::snprintf(name_, sizeof name_, "libcamera:%s", config_.camera_id.empty() ? "(first)" : config_.camera_id.c_str());
  libcamera::PixelFormat pixel_format;
  if (!libcamera_format(config_.format, &pixel_format)) {
    return fail(std::string("pixel format ") + to_string(config_.format) + " is not supported (no decoder in this build)");
  }
  if (config_.buffer_count < 2 || config_.buffer_count > kMaxBuffers) {
    return fail("buffer_count must be 2.." + std::to_string(kMaxBuffers));
  }
  if (config_.intrinsics.width_px != config_.width_px || config_.intrinsics.height_px != config_.height_px) {
    return fail("the calibration is for " + std::to_string(config_.intrinsics.width_px) + "x" +
                std::to_string(config_.intrinsics.height_px) + " but capture is set to " + std::to_string(config_.width_px) +
                "x" + std::to_string(config_.height_px));
  }

  manager_ = std::make_unique<libcamera::CameraManager>();
  if (manager_->start() != 0) return fail("the camera manager did not start");
  {
    // The list holds shared_ptrs to every camera: it must be gone before any failure path stops the
    // manager (a Camera outliving its CameraManager is a use after free).
    std::string missing;
    {
      const std::vector<std::shared_ptr<libcamera::Camera>> cameras = manager_->cameras();
      if (cameras.empty()) {
        missing = "no cameras found";
      } else if (config_.camera_id.empty()) {
        camera_ = cameras.front();
      } else {
        camera_ = manager_->get(config_.camera_id);
        if (!camera_) {
          std::string ids;
          for (const auto& c : cameras) ids += (ids.empty() ? "" : ", ") + c->id();
          missing = "no such camera (present: " + ids + ")";
        }
      }
    }
    if (!missing.empty()) return fail(missing);
  }
  std::snprintf(name_, sizeof name_, "libcamera:%s", camera_->id().c_str());
  manager_->cameraRemoved.connect(this, &LibcameraCamera::on_camera_removed);
  if (camera_->acquire() != 0) return fail("busy: the camera is in use by another process or object");
  acquired_ = true;

  configuration_ = camera_->generateConfiguration({libcamera::StreamRole::Viewfinder});
  if (!configuration_ || configuration_->size() != 1) return fail("the camera gave no stream configuration");
  libcamera::StreamConfiguration& stream_config = configuration_->at(0);
  stream_config.pixelFormat = pixel_format;
  stream_config.size.width = static_cast<unsigned int>(config_.width_px);
  stream_config.size.height = static_cast<unsigned int>(config_.height_px);
  stream_config.bufferCount = static_cast<unsigned int>(config_.buffer_count);
  const libcamera::CameraConfiguration::Status status = configuration_->validate();
  if (status == libcamera::CameraConfiguration::Invalid) return fail("the stream configuration is invalid");
  if (stream_config.pixelFormat != pixel_format) {
    std::string offered;
    for (const libcamera::PixelFormat& f : stream_config.formats().pixelformats()) offered += (offered.empty() ? "" : " ") + f.toString();
    return fail(std::string("pixel format ") + to_string(config_.format) + " not supported (stream offers " + offered + ")");
  }
  if (stream_config.size.width != static_cast<unsigned int>(config_.width_px) ||
      stream_config.size.height != static_cast<unsigned int>(config_.height_px)) {
    return fail("size " + std::to_string(config_.width_px) + "x" + std::to_string(config_.height_px) +
                " not supported (camera gave " + stream_config.size.toString() + ")");
  }
  if (stream_config.bufferCount > static_cast<unsigned int>(kMaxBuffers)) return fail("the camera needs more buffers than this driver holds");
  if (camera_->configure(configuration_.get()) != 0) return fail("configure failed");
  stream_ = stream_config.stream();
  stride_bytes_ = static_cast<std::int32_t>(stream_config.stride);
  if (stride_bytes_ < min_line_bytes(config_.format, config_.width_px)) return fail("stream stride shorter than a line");

  allocator_ = std::make_unique<libcamera::FrameBufferAllocator>(camera_);
  if (allocator_->allocate(stream_) < 0) return fail("buffer allocation failed");
  const auto& buffers = allocator_->buffers(stream_);
  if (buffers.empty() || buffers.size() > static_cast<std::size_t>(kMaxBuffers)) return fail("unexpected number of buffers");
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    libcamera::FrameBuffer* buffer = buffers[i].get();
    const libcamera::FrameBuffer::Plane& plane = buffer->planes()[0];
    // Plane 0 carries the luma (or the only plane); map its dmabuf once, from the start of the fd.
    const std::size_t map_length = static_cast<std::size_t>(plane.offset) + plane.length;
    void* base = ::mmap(nullptr, map_length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
    if (base == MAP_FAILED) return fail(std::string("mmap of a frame buffer failed: ") + std::strerror(errno));
    mappings_[i] = Mapping{base, map_length, plane.offset, plane.length};
    buffer_count_ = static_cast<int>(i + 1);
    std::unique_ptr<libcamera::Request> request = camera_->createRequest(i);
    if (!request) return fail("request creation failed");
    if (request->addBuffer(stream_, buffer) != 0) return fail("adding a buffer to a request failed");
    requests_.push_back(std::move(request));
  }

  camera_->requestCompleted.connect(this, &LibcameraCamera::on_request_completed);
  if (camera_->start() != 0) return fail("start failed");
  started_ = true;
  for (auto& request : requests_) {
    if (camera_->queueRequest(request.get()) != 0) return fail("queueing a request failed");
  }
  streaming_ = true;
  return {};
}

void LibcameraCamera::on_request_completed(libcamera::Request* request) {
  // libcamera's thread: no work here beyond handing the request to grab().
  if (request->status() == libcamera::Request::RequestCancelled) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (completed_count_ < kMaxBuffers) {
      completed_[(completed_head_ + completed_count_) % kMaxBuffers] = request;
      ++completed_count_;
    }
  }
  completed_cv_.notify_one();
}

void LibcameraCamera::on_camera_removed(std::shared_ptr<libcamera::Camera> camera) {
  if (camera != camera_) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    lost_ = true;
  }
  completed_cv_.notify_one();
}

CaptureStatus LibcameraCamera::grab(MutableGrayImageView& out, FrameInfo& info, std::int32_t timeout_ms) {
  if (!streaming_) return CaptureStatus::kNotStarted;
  const std::size_t needed = static_cast<std::size_t>(config_.width_px) * static_cast<std::size_t>(config_.height_px);
  if (out.pixels == nullptr || out.size_bytes() < needed) return CaptureStatus::kBufferTooSmall;
  libcamera::Request* request = nullptr;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool ready = completed_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms < 0 ? 0 : timeout_ms),
                                              [this] { return completed_count_ > 0 || lost_; });
    if (lost_) {
      streaming_ = false;
      return CaptureStatus::kDeviceLost;
    }
    if (!ready) return CaptureStatus::kTimeout;
    request = completed_[completed_head_];
    completed_head_ = (completed_head_ + 1) % kMaxBuffers;
    --completed_count_;
  }
  CaptureStatus status = CaptureStatus::kOk;
  const std::uint64_t index = request->cookie();
  libcamera::FrameBuffer* buffer = request->findBuffer(stream_);
  if (index >= static_cast<std::uint64_t>(buffer_count_) || buffer == nullptr) {
    status = CaptureStatus::kCorruptFrame;
  } else {
    const libcamera::FrameMetadata& metadata = buffer->metadata();
    if (request->status() != libcamera::Request::RequestComplete || metadata.status != libcamera::FrameMetadata::FrameSuccess ||
        metadata.planes().size() == 0) {
      status = CaptureStatus::kCorruptFrame;
    } else {
      const Mapping& m = mappings_[index];
      const std::size_t used = metadata.planes()[0].bytesused;
      const std::uint8_t* data = static_cast<const std::uint8_t*>(m.base) + m.offset;
      MutableGrayImageView converted = out;
      if (!convert_to_gray(config_.format, data, used < m.length ? used : m.length, config_.width_px, config_.height_px,
                           stride_bytes_, &converted)) {
        status = CaptureStatus::kCorruptFrame;
      } else {
        out = converted;
        info.timestamp_ns = static_cast<std::int64_t>(metadata.timestamp);  // CLOCK_MONOTONIC (sensor timestamp)
        info.sequence = metadata.sequence;
      }
    }
  }
  request->reuse(libcamera::Request::ReuseBuffers);
  if (camera_->queueRequest(request) != 0) {
    streaming_ = false;
    return CaptureStatus::kDeviceLost;
  }
  return status;
}

void LibcameraCamera::close() {
  streaming_ = false;
  if (camera_ && started_) camera_->stop();
  started_ = false;
  if (camera_) camera_->requestCompleted.disconnect(this);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    completed_count_ = 0;
    completed_head_ = 0;
    lost_ = false;
  }
  for (int i = 0; i < buffer_count_; ++i) {
    if (mappings_[i].base != nullptr) ::munmap(mappings_[i].base, mappings_[i].map_length);
    mappings_[i] = Mapping{};
  }
  buffer_count_ = 0;
  requests_.clear();
  if (allocator_ && stream_ != nullptr) allocator_->free(stream_);
  allocator_.reset();
  stream_ = nullptr;
  configuration_.reset();
  if (camera_ && acquired_) camera_->release();
  acquired_ = false;
  camera_.reset();
  // The camera is released before the manager goes.
  if (manager_) {
    manager_->cameraRemoved.disconnect(this);
    manager_->stop();
  }
  manager_.reset();
}

}  // namespace vantage::hal
