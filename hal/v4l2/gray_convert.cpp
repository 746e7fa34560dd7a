#include "hal/v4l2/gray_convert.hpp"

#include <cstring>

namespace vantage::hal {

const char* to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::kGrey: return "GREY";
    case PixelFormat::kYuyv: return "YUYV";
    case PixelFormat::kUyvy: return "UYVY";
    case PixelFormat::kNv12: return "NV12";
    case PixelFormat::kRgb24: return "RGB3";
    case PixelFormat::kBgr24: return "BGR3";
    case PixelFormat::kBgrx32: return "XR24";
    case PixelFormat::kMjpeg: return "MJPG";
  }
  return "????";
}

bool pixel_format_from_string(const char* text, PixelFormat* out) {
  const PixelFormat all[] = {PixelFormat::kGrey,  PixelFormat::kYuyv,  PixelFormat::kUyvy,   PixelFormat::kNv12,
                             PixelFormat::kRgb24, PixelFormat::kBgr24, PixelFormat::kBgrx32, PixelFormat::kMjpeg};
  for (PixelFormat f : all) {
    if (std::strcmp(text, to_string(f)) == 0) {
      *out = f;
      return true;
    }
  }
  return false;
}

namespace {
std::int32_t bytes_per_pixel(PixelFormat format) {
  switch (format) {
    case PixelFormat::kYuyv:
    case PixelFormat::kUyvy: return 2;
    case PixelFormat::kRgb24:
    case PixelFormat::kBgr24: return 3;
    case PixelFormat::kBgrx32: return 4;
    default: return 1;
  }
}
std::int32_t min_stride(PixelFormat format, std::int32_t width_px) { return bytes_per_pixel(format) * width_px; }

std::uint8_t luma(std::uint32_t r, std::uint32_t g, std::uint32_t b) {
  return static_cast<std::uint8_t>((77 * r + 150 * g + 29 * b + 128) >> 8);
}
}  // namespace

std::int32_t min_line_bytes(PixelFormat format, std::int32_t width_px) {
  return format == PixelFormat::kMjpeg ? 0 : min_stride(format, width_px);
}

std::size_t frame_bytes(PixelFormat format, std::int32_t width_px, std::int32_t height_px, std::int32_t stride_bytes) {
  if (format == PixelFormat::kMjpeg || width_px <= 0 || height_px <= 0) return 0;
  const std::size_t plane = static_cast<std::size_t>(stride_bytes) * static_cast<std::size_t>(height_px);
  // NV12: full-resolution Y plane, then the interleaved CbCr plane at half height.
  return format == PixelFormat::kNv12 ? plane + plane / 2 : plane;
}

bool convert_to_gray(PixelFormat format, const std::uint8_t* src, std::size_t src_bytes, std::int32_t width_px,
                     std::int32_t height_px, std::int32_t stride_bytes, MutableGrayImageView* out) {
  if (src == nullptr || out == nullptr || out->pixels == nullptr || width_px <= 0 || height_px <= 0) return false;
  if (format == PixelFormat::kMjpeg || stride_bytes < min_stride(format, width_px)) return false;
  // The luma plane is all gray needs, so a frame is complete once its luma plane is.
  const std::size_t luma_bytes =
      static_cast<std::size_t>(stride_bytes) * static_cast<std::size_t>(height_px - 1) + min_stride(format, width_px);
  if (src_bytes < luma_bytes) return false;
  std::uint8_t* dst = out->pixels;
  for (std::int32_t y = 0; y < height_px; ++y) {
    const std::uint8_t* row = src + static_cast<std::size_t>(y) * static_cast<std::size_t>(stride_bytes);
    std::uint8_t* dst_row = dst + static_cast<std::size_t>(y) * static_cast<std::size_t>(width_px);
    switch (format) {
      case PixelFormat::kGrey:
      case PixelFormat::kNv12:
        std::memcpy(dst_row, row, static_cast<std::size_t>(width_px));
        break;
      case PixelFormat::kYuyv:  // Y0 U Y1 V
        for (std::int32_t x = 0; x < width_px; ++x) dst_row[x] = row[2 * x];
        break;
      case PixelFormat::kUyvy:  // U Y0 V Y1
        for (std::int32_t x = 0; x < width_px; ++x) dst_row[x] = row[2 * x + 1];
        break;
      case PixelFormat::kRgb24:
        for (std::int32_t x = 0; x < width_px; ++x) dst_row[x] = luma(row[3 * x], row[3 * x + 1], row[3 * x + 2]);
        break;
      case PixelFormat::kBgr24:
        for (std::int32_t x = 0; x < width_px; ++x) dst_row[x] = luma(row[3 * x + 2], row[3 * x + 1], row[3 * x]);
        break;
      case PixelFormat::kBgrx32:
        for (std::int32_t x = 0; x < width_px; ++x) dst_row[x] = luma(row[4 * x + 2], row[4 * x + 1], row[4 * x]);
        break;
      case PixelFormat::kMjpeg:
        return false;
    }
  }
  out->width_px = width_px;
  out->height_px = height_px;
  out->stride_bytes = width_px;
  return true;
}

}  // namespace vantage::hal
