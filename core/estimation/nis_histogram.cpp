#include "core/estimation/nis_histogram.hpp"

#include <cmath>

namespace vantage {

NisSummary summarize(const NisHistogram& histogram) {
  NisSummary out;
  out.count = histogram.total();
  if (out.count == 0) return out;
  const double n = static_cast<double>(out.count);
  out.fraction_beyond_95 = static_cast<double>(histogram.counts[kNisBins - 1]) / n;
  // The bin where the cumulative share reaches one half, and how far into it (in probability under
  // chi-square(2), where every bin is 1 / kNisBins wide).
  const double half = 0.5 * n;
  double below = 0.0;
  int bin = 0;
  while (bin < kNisBins - 1 && below + static_cast<double>(histogram.counts[static_cast<std::size_t>(bin)]) < half) {
    below += static_cast<double>(histogram.counts[static_cast<std::size_t>(bin)]);
    ++bin;
  }
  out.median_in_top_bin = bin == kNisBins - 1;
  const double in_bin = static_cast<double>(histogram.counts[static_cast<std::size_t>(bin)]);
  // The top bin is unbounded: its lower edge is the bound.
  const double fraction = out.median_in_top_bin || in_bin <= 0.0 ? 0.0 : (half - below) / in_bin;
  const double probability = (bin + fraction) / kNisBins;
  const double median_nis = -2.0 * std::log1p(-probability);
  out.median_scale = median_nis / kChiSquare2DofMedian;
  return out;
}

}  // namespace vantage
