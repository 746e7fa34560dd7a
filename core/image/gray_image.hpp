#pragma once
// 8-bit grayscale images seen through views (pointer, size, stride), so camera buffers from V4L2,
// libcamera or the simulator are read in place, without copies. Owners with inline storage give
// fixed-size buffers to targets that hold them statically.
#include <array>
#include <cstddef>
#include <cstdint>

#include "core/common/status.hpp"

namespace vantage {

struct GrayImageView {
  const std::uint8_t* pixels = nullptr;
  std::int32_t width_px = 0;
  std::int32_t height_px = 0;
  std::int32_t stride_bytes = 0;  // bytes from one row's start to the next's

  std::uint8_t at(std::int32_t x, std::int32_t y) const { return pixels[y * stride_bytes + x]; }
  // kInvalidImage when null, zero-size, or the stride is shorter than a row.
  Status validate() const;
};

struct MutableGrayImageView {
  std::uint8_t* pixels = nullptr;
  std::int32_t width_px = 0;
  std::int32_t height_px = 0;
  std::int32_t stride_bytes = 0;

  std::uint8_t& at(std::int32_t x, std::int32_t y) const { return pixels[y * stride_bytes + x]; }
  GrayImageView as_const() const { return GrayImageView{pixels, width_px, height_px, stride_bytes}; }
  std::size_t size_bytes() const { return static_cast<std::size_t>(stride_bytes) * static_cast<std::size_t>(height_px); }
};

// A gray image of at most MaxWidth x MaxHeight pixels in inline storage; the used size is set at run time.
template <std::int32_t MaxWidth, std::int32_t MaxHeight>
class GrayImageBuffer {
 public:
  static_assert(MaxWidth > 0 && MaxHeight > 0, "image capacity must be positive");
  static constexpr std::int32_t kMaxWidth = MaxWidth;
  static constexpr std::int32_t kMaxHeight = MaxHeight;

  // kInvalidArgument when the size is non-positive or exceeds the capacity; the buffer is unchanged.
  Status resize(std::int32_t width_px, std::int32_t height_px) {
    if (width_px <= 0 || height_px <= 0 || width_px > MaxWidth || height_px > MaxHeight) {
      return Status::kInvalidArgument;
    }
    width_px_ = width_px;
    height_px_ = height_px;
    return Status::kOk;
  }
  MutableGrayImageView view() { return MutableGrayImageView{pixels_.data(), width_px_, height_px_, width_px_}; }
  GrayImageView view() const { return GrayImageView{pixels_.data(), width_px_, height_px_, width_px_}; }

 private:
  std::array<std::uint8_t, static_cast<std::size_t>(MaxWidth) * MaxHeight> pixels_{};
  std::int32_t width_px_ = MaxWidth;
  std::int32_t height_px_ = MaxHeight;
};

}  // namespace vantage
