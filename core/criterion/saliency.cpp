#include "core/criterion/saliency.hpp"

#include <cmath>

#include "core/common/double_lanes.hpp"

namespace vantage {

namespace {

constexpr int kP = kPatchSize;
constexpr int kLags = 2 * kP - 1;

// The autocorrelation sums of the lags (dx, dy) from (0, 0) on in row-major order (dy = 0 .. kP - 1, dx
// from 0 in row 0 and from -(kP - 1) in the others, to kP - 1), as sums[dy][dx + kP - 1]: each the
// products centred[y][x] * centred[y + dy][x + dx] over y, then x, ascending, the pairs outside the patch
// skipped. The other entries (row 0, dx < 0: mirrors of computed lags) are not read.
using LagSums = double[kP][kLags];

void lag_sums_scalar(const double* centred, LagSums& sums) {
  for (int dy = 0; dy < kP; ++dy) {
    for (int dx = dy == 0 ? 0 : -(kP - 1); dx <= kP - 1; ++dx) {
      double sum = 0.0;
      for (int y = 0; y + dy < kP; ++y) {
        const int x_begin = dx < 0 ? -dx : 0;
        const int x_end = dx > 0 ? kP - dx : kP;
        for (int x = x_begin; x < x_end; ++x) sum += centred[y * kP + x] * centred[(y + dy) * kP + x + dx];
      }
      sums[dy][dx + kP - 1] = sum;
    }
  }
}

#if VANTAGE_DOUBLE_LANES
// The same with the 13 lags of a row dy in vector lanes (16, three unused; core/common/double_lanes.hpp):
// the second factor read from a copy padded with zeros, so every lane runs over all of x and adds +-0 where
// the scalar form skips a pair; adding a signed zero to a finite sum leaves it as it is, so each lane ends
// with the scalar sum's bits. On x86-64 nothing is fused; GCC for AArch64 fuses each product into its sum
// in both forms alike, and fma(c, +-0, s) = s, so there too (the core test checks both bit for bit).
VANTAGE_DOUBLE_LANES_TARGET void lag_sums_lanes(const double* centred, LagSums& sums) {
  using Double4 = double __attribute__((vector_size(32)));
  constexpr int kPadded = 24;  // columns -6 .. 17 of a row: lane j of centre x reads column x + j - 6
  double padded[kP][kPadded] = {};
  for (int y = 0; y < kP; ++y) {
    for (int x = 0; x < kP; ++x) padded[y][x + kP - 1] = centred[y * kP + x];
  }
  for (int dy = 0; dy < kP; ++dy) {
    Double4 acc0 = {0.0, 0.0, 0.0, 0.0};
    Double4 acc1 = acc0;
    Double4 acc2 = acc0;
    Double4 acc3 = acc0;
    for (int y = 0; y + dy < kP; ++y) {
      const double* row = padded[y + dy];
      for (int x = 0; x < kP; ++x) {
        const Double4 c = Double4{} + centred[y * kP + x];
        Double4 v0;
        Double4 v1;
        Double4 v2;
        Double4 v3;
        __builtin_memcpy(&v0, row + x, sizeof(v0));
        __builtin_memcpy(&v1, row + x + 4, sizeof(v1));
        __builtin_memcpy(&v2, row + x + 8, sizeof(v2));
        __builtin_memcpy(&v3, row + x + 12, sizeof(v3));
        acc0 += c * v0;
        acc1 += c * v1;
        acc2 += c * v2;
        acc3 += c * v3;
      }
    }
    double lanes[16];
    __builtin_memcpy(lanes, &acc0, sizeof(acc0));
    __builtin_memcpy(lanes + 4, &acc1, sizeof(acc1));
    __builtin_memcpy(lanes + 8, &acc2, sizeof(acc2));
    __builtin_memcpy(lanes + 12, &acc3, sizeof(acc3));
    for (int j = 0; j < kLags; ++j) sums[dy][j] = lanes[j];
  }
}
#endif

void lag_sums(const double* centred, LagSums& sums) {
#if VANTAGE_DOUBLE_LANES
  if (VANTAGE_DOUBLE_LANES_AVAILABLE()) {
    lag_sums_lanes(centred, sums);
    return;
  }
#endif
  lag_sums_scalar(centred, sums);
}

}  // namespace

float patch_autocorrelation_entropy(const Patch& patch, float min_stddev) {
  double mean = 0.0;
  for (std::uint8_t v : patch) mean += v;
  mean /= static_cast<double>(kP * kP);
  double centred[kP * kP];
  double energy = 0.0;
  for (int i = 0; i < kP * kP; ++i) {
    centred[i] = patch[i] - mean;
    energy += centred[i] * centred[i];
  }
  const double variance = energy / static_cast<double>(kP * kP);
  const double stddev_floor = min_stddev > 0.0f ? static_cast<double>(min_stddev) : 0.0;
  if (!(variance > stddev_floor * stddev_floor) || !(energy > 0.0)) return 1.0f;

  // Biased autocorrelation normalized by the zero-lag energy: a(0, 0) = 1 and |a| <= 1 (Cauchy-Schwarz).
  // Its squares, normalized to sum 1, are the distribution whose entropy measures flatness. Squares, not
  // magnitudes: with |a| the many small lags of white noise outweigh its peak and noise measures as flat
  // as a shading ramp (measured: 0.90 vs 0.94); with a^2 noise measures 0.41-0.67, ramps 0.78-0.82.
  // a(-d) = a(d), and bit for bit: lag -d's products are lag d's, commuted, met in the same order (rows,
  // then columns, ascending), so each sum is computed once, for the lags from (0, 0) on in row-major
  // order, and its mirror copied. The totals and the entropy still run over all lags in their order.
  constexpr int kCentre = (kP - 1) * kLags + (kP - 1);  // the index of lag (0, 0)
  double weight[kLags * kLags];
  LagSums sums;
  lag_sums(centred, sums);
  for (int dy = 0; dy <= kP - 1; ++dy) {
    for (int dx = dy == 0 ? 0 : -(kP - 1); dx <= kP - 1; ++dx) {
      const double r = sums[dy][dx + kP - 1] / energy;
      const int index = (dy + kP - 1) * kLags + (dx + kP - 1);
      weight[index] = r * r;
      weight[2 * kCentre - index] = r * r;  // lag (-dx, -dy)
    }
  }
  double total = 0.0;
  for (double a : weight) total += a;
  // -p log p of each lag, once per mirrored pair (log is the costly part).
  double term[kLags * kLags];
  for (int i = 0; i <= kCentre; ++i) {
    const double a = weight[i];
    if (a <= 0.0) {
      term[i] = 0.0;  // 0 log 0 = 0
    } else {
      const double q = a / total;
      term[i] = q * std::log(q);
    }
    term[2 * kCentre - i] = term[i];
  }
  double entropy = 0.0;
  for (double t : term) entropy -= t;  // a lag of weight 0 subtracts 0: the sum is unchanged
  return static_cast<float>(entropy / std::log(static_cast<double>(kLags * kLags)));
}

float saliency_step(float entropy, const SaliencyParams& params) {
  if (!std::isfinite(params.tau) || !std::isfinite(params.gamma) || !(params.gamma > 0.0f) ||
      !std::isfinite(entropy)) {
    return 0.0f;
  }
  return 0.5f * std::erfc((entropy - params.tau) / params.gamma);
}

float compute_saliency_h(const Patch& patch, const SaliencyParams& params) {
  return saliency_step(patch_autocorrelation_entropy(patch, params.min_stddev), params);
}

}  // namespace vantage
