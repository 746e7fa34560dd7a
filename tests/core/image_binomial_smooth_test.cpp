#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cstdint>

#include "core/image/binomial_smooth.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

namespace {

// The filter written out per pixel with clamped coordinates: the reference the row-buffer version must equal.
std::uint8_t reference_pixel(const GrayImageView& in, std::int32_t x, std::int32_t y) {
  static constexpr int kWeights[3] = {1, 2, 1};
  int sum = 0;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const std::int32_t cx = std::min(std::max(x + dx, 0), in.width_px - 1);
      const std::int32_t cy = std::min(std::max(y + dy, 0), in.height_px - 1);
      sum += kWeights[dx + 1] * kWeights[dy + 1] * in.at(cx, cy);
    }
  }
  return static_cast<std::uint8_t>((sum + 8) / 16);
}

}  // namespace

TEST_CASE("the binomial low-pass equals the clamped 3x3 filter at every pixel, strided views included") {
  constexpr std::int32_t kW = 37, kH = 23, kStride = 41;
  std::array<std::uint8_t, kStride * kH> input{};
  std::uint32_t state = 12345u;
  for (std::uint8_t& v : input) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<std::uint8_t>(state >> 24);
  }
  const GrayImageView in{input.data(), kW, kH, kStride};
  std::array<std::uint8_t, kStride * kH> output{};
  output.fill(7);
  const MutableGrayImageView out{output.data(), kW, kH, kStride};
  REQUIRE_NO_ALLOCATION(REQUIRE(ok(binomial_smooth3(in, out))));
  int mismatches = 0;
  for (std::int32_t y = 0; y < kH; ++y) {
    for (std::int32_t x = 0; x < kW; ++x) mismatches += out.at(x, y) != reference_pixel(in, x, y) ? 1 : 0;
    // The stride's padding is not the image's: left as it was.
    for (std::int32_t x = kW; x < kStride; ++x) CHECK(output[static_cast<std::size_t>(y) * kStride + x] == 7);
  }
  CHECK(mismatches == 0);
}

TEST_CASE("the binomial low-pass keeps constant images and extreme values") {
  constexpr std::int32_t kW = 8, kH = 5;
  for (const std::uint8_t value : {std::uint8_t{0}, std::uint8_t{255}, std::uint8_t{131}}) {
    std::array<std::uint8_t, kW * kH> input;
    input.fill(value);
    std::array<std::uint8_t, kW * kH> output{};
    REQUIRE(ok(binomial_smooth3(GrayImageView{input.data(), kW, kH, kW}, MutableGrayImageView{output.data(), kW, kH, kW})));
    for (const std::uint8_t v : output) CHECK(v == value);
  }
}

TEST_CASE("the binomial low-pass refuses bad views and leaves the output unchanged") {
  std::array<std::uint8_t, 64> input{};
  std::array<std::uint8_t, 64> output;
  output.fill(9);
  const MutableGrayImageView out{output.data(), 8, 8, 8};
  CHECK(binomial_smooth3(GrayImageView{nullptr, 8, 8, 8}, out) == Status::kInvalidImage);
  CHECK(binomial_smooth3(GrayImageView{input.data(), 8, 8, 4}, out) == Status::kInvalidImage);
  CHECK(binomial_smooth3(GrayImageView{input.data(), 8, 4, 8}, out) == Status::kInvalidArgument);
  CHECK(binomial_smooth3(GrayImageView{input.data(), 8, 8, 8}, MutableGrayImageView{nullptr, 8, 8, 8}) ==
        Status::kInvalidImage);
  CHECK(binomial_smooth3(GrayImageView{input.data(), kBinomialSmoothMaxWidth + 1, 1, kBinomialSmoothMaxWidth + 1},
                         MutableGrayImageView{output.data(), kBinomialSmoothMaxWidth + 1, 1, kBinomialSmoothMaxWidth + 1}) ==
        Status::kInvalidArgument);
  for (const std::uint8_t v : output) CHECK(v == 9);
}
