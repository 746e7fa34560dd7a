#include "core/image/binomial_smooth.hpp"

#include <array>
#include <cstdint>

namespace vantage {

Status binomial_smooth3(const GrayImageView& in, const MutableGrayImageView& out) {
  if (!ok(in.validate()) || !ok(out.as_const().validate())) return Status::kInvalidImage;
  if (in.width_px != out.width_px || in.height_px != out.height_px || in.width_px > kBinomialSmoothMaxWidth) {
    return Status::kInvalidArgument;
  }
  const std::int32_t w = in.width_px;
  const std::int32_t h = in.height_px;
  // The vertical [1 2 1] of one row (at most 4 x 255 = 1020), with the replicated border columns at 0 and w + 1.
  std::array<std::uint16_t, kBinomialSmoothMaxWidth + 2> column_sums;
  for (std::int32_t y = 0; y < h; ++y) {
    const std::uint8_t* above = in.pixels + static_cast<std::ptrdiff_t>(y > 0 ? y - 1 : 0) * in.stride_bytes;
    const std::uint8_t* row = in.pixels + static_cast<std::ptrdiff_t>(y) * in.stride_bytes;
    const std::uint8_t* below = in.pixels + static_cast<std::ptrdiff_t>(y + 1 < h ? y + 1 : h - 1) * in.stride_bytes;
    std::uint16_t* sums = column_sums.data() + 1;
    for (std::int32_t x = 0; x < w; ++x) {
      sums[x] = static_cast<std::uint16_t>(above[x] + 2 * row[x] + below[x]);
    }
    sums[-1] = sums[0];
    sums[w] = sums[w - 1];
    std::uint8_t* dst = out.pixels + static_cast<std::ptrdiff_t>(y) * out.stride_bytes;
    // (sum + 8) / 16 rounds to nearest; at most (4 x 1020 + 8) / 16 = 255.
    for (std::int32_t x = 0; x < w; ++x) {
      dst[x] = static_cast<std::uint8_t>((sums[x - 1] + 2 * sums[x] + sums[x + 1] + 8) >> 4);
    }
  }
  return Status::kOk;
}

}  // namespace vantage
