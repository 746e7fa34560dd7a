#pragma once
// The normalized innovation squared (NIS) of the image measurements, nu^T S^-1 nu, as a fixed histogram:
// a consistency check that needs no ground truth, so a robot can run it on real frames. When the filter's
// innovation covariance S is honest, the NIS of a 2-D measurement is chi-square with 2 degrees of freedom
// (Bar-Shalom, Li and Kirubarajan, "Estimation with Applications to Tracking and Navigation", 5.4), so its
// probability transform 1 - exp(-NIS / 2) is uniform: each of the kNisBins bins, of equal probability
// under that law, then holds 1 / kNisBins of the innovations. More in the upper bins means S understates
// the innovations (over-confidence); more in the lower ones, that it overstates them. Every innovation the
// gate tests is recorded, the ones it rejects too: the top bin starts at the 95 % point, the default gate.
#include <array>
#include <cstddef>
#include <cstdint>

namespace vantage {

inline constexpr int kNisBins = 20;

// Lower edges of the bins: -2 ln(1 - k / kNisBins), the chi-square(2) quantiles at k / 20 (core test checks
// them against the formula; written out because the core has no thread-safe statics to compute them once).
// clang-format off
inline constexpr std::array<double, kNisBins> kNisBinLowerEdges = {
    0.0, 0.10258658877510107, 0.21072103131565262, 0.3250378589955498, 0.44628710262841953,
    0.5753641449035618, 0.7133498878774647, 0.8615658321849085, 1.0216512475319814, 1.1956740015112408,
    1.3862943611198906, 1.5970153924355435, 1.83258146374831, 2.0996442489973557, 2.407945608651872,
    2.772588722239781, 3.218875824868201, 3.794239969771762, 4.605170185988092, 5.99146454710798};
// clang-format on

// The median of chi-square(2), 2 ln 2: the median NIS of honest innovations.
inline constexpr double kChiSquare2DofMedian = 1.3862943611198906;

struct NisHistogram {
  std::array<std::uint64_t, kNisBins> counts{};

  // NaN and negative values are not innovations' NIS: not recorded. Branch-free over the edges (the hot
  // path records every tracked match).
  void record(double nis) {
    if (!(nis >= 0.0)) return;
    int bin = 0;
    for (int k = 1; k < kNisBins; ++k) bin += nis >= kNisBinLowerEdges[static_cast<std::size_t>(k)] ? 1 : 0;
    ++counts[static_cast<std::size_t>(bin)];
  }
  void add(const NisHistogram& other) {
    for (int k = 0; k < kNisBins; ++k) counts[static_cast<std::size_t>(k)] += other.counts[static_cast<std::size_t>(k)];
  }
  std::uint64_t total() const {
    std::uint64_t n = 0;
    for (std::uint64_t c : counts) n += c;
    return n;
  }
};

struct NisSummary {
  std::uint64_t count = 0;
  // The median NIS over chi-square(2)'s median: 1 when S is honest, k when the innovations are k times
  // larger than S says (in variance). Read between the bins' edges linearly in probability. 0 when count is 0.
  double median_scale = 0.0;
  // The median lies in the top bin (beyond the 95 % point): median_scale is a lower bound.
  bool median_in_top_bin = false;
  // The share beyond the 95 % point (the top bin): 0.05 when S is honest.
  double fraction_beyond_95 = 0.0;
};

NisSummary summarize(const NisHistogram& histogram);

}  // namespace vantage
