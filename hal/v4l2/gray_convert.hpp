#pragma once
// Camera pixel formats to 8-bit gray, written into the caller's buffer. Pure functions (no device), so
// they are tested on their own and shared by the V4L2 and libcamera drivers. Gray is the luma plane: Y of
// Y'CbCr formats, unchanged for GREY, and BT.601 luma (77 R + 150 G + 29 B) / 256 for RGB formats.
#include <cstddef>
#include <cstdint>

#include "core/image/gray_image.hpp"

namespace vantage::hal {

// Names are V4L2 fourccs; byte order in memory in the comments (libcamera's names in brackets).
enum class PixelFormat : std::uint8_t {
  kGrey,    // "GREY": Y (libcamera R8)
  kYuyv,    // "YUYV": Y0 U Y1 V
  kUyvy,    // "UYVY": U Y0 V Y1
  kNv12,    // "NV12": Y plane, then interleaved CbCr at half resolution
  kRgb24,   // "RGB3": R G B (libcamera BGR888)
  kBgr24,   // "BGR3": B G R (libcamera RGB888)
  kBgrx32,  // "XR24": B G R X (libcamera XRGB8888)
  kMjpeg,   // "MJPG": compressed; refused (no decoder in this build)
};

const char* to_string(PixelFormat format);
// "GREY", "YUYV", "UYVY", "NV12", "RGB3", "BGR3", "XR24", "MJPG" (case-sensitive); false otherwise.
bool pixel_format_from_string(const char* text, PixelFormat* out);

// Bytes of one line of luma-bearing pixels (width times bytes per pixel; 0 for MJPEG).
std::int32_t min_line_bytes(PixelFormat format, std::int32_t width_px);

// Bytes a frame of this format needs at this size and line stride (the luma plane and, for NV12, the
// chroma plane after it). 0 for MJPEG (compressed, variable).
std::size_t frame_bytes(PixelFormat format, std::int32_t width_px, std::int32_t height_px, std::int32_t stride_bytes);

// Converts one frame. src holds src_bytes bytes; stride_bytes is the source line stride (bytesperline).
// out.pixels must hold width_px * height_px bytes; out's size and stride are set on success.
// false (out untouched) when the frame is shorter than the format needs or the arguments are invalid.
bool convert_to_gray(PixelFormat format, const std::uint8_t* src, std::size_t src_bytes, std::int32_t width_px,
                     std::int32_t height_px, std::int32_t stride_bytes, MutableGrayImageView* out);

}  // namespace vantage::hal
