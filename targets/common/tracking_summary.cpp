#include "targets/common/tracking_summary.hpp"

#include <cstdio>

namespace vantage::targets {

std::string tracking_summary(std::uint64_t predicted, std::uint64_t matched, std::uint64_t inverse_warped,
                             const TrackFailureCounts& failures) {
  if (predicted == 0) return "tracking: no observation predicted in view";
  const double share = 100.0 / static_cast<double>(predicted);
  char inverse[64] = "";
  if (inverse_warped > 0) std::snprintf(inverse, sizeof inverse, " (%.1f%% by the inverse warp)", share * inverse_warped);
  char line[512];
  std::snprintf(line, sizeof line,
                "tracking: %llu observations predicted in view, %.1f%% matched%s; failed: template masked by the "
                "warp %.1f%%, below the NCC threshold %.1f%%, ambiguous %.1f%%, no subpixel fit %.1f%%, no room "
                "%.1f%%, edge-on %.1f%%, too uncertain %.1f%%",
                static_cast<unsigned long long>(predicted), share * matched, inverse, share * failures.template_masked,
                share * failures.below_threshold, share * failures.ambiguous, share * failures.no_subpixel,
                share * failures.no_room, share * failures.edge_on, share * failures.too_uncertain);
  return line;
}

std::string seeding_summary(std::uint64_t tried, std::uint64_t matched, std::uint64_t beyond_depth_range,
                            std::uint64_t rejected_back_match, std::uint64_t rejected_no_plane_fit) {
  if (tried == 0) return "seeding: no seed searched";
  const double share = 100.0 / static_cast<double>(tried);
  char line[200];
  const int n =
      std::snprintf(line, sizeof line, "seeding: %llu seeds searched, %.1f%% matched, %.1f%% past the depth range",
                    static_cast<unsigned long long>(tried), share * matched, share * beyond_depth_range);
  // Each refusal reason that refused any seed, as a share of the seeds searched.
  std::size_t used = n > 0 ? static_cast<std::size_t>(n) : sizeof line;
  auto append_share = [&](std::uint64_t count, const char* what) {
    if (count == 0 || used >= sizeof line) return;
    const int more = std::snprintf(line + used, sizeof line - used, ", %.1f%% %s", share * count, what);
    used = more > 0 ? used + static_cast<std::size_t>(more) : sizeof line;
  };
  append_share(rejected_back_match, "refused by the left-right check");
  append_share(rejected_no_plane_fit, "erased without a plane fit");
  return line;
}

std::string innovation_summary(const NisHistogram& innovations) {
  const NisSummary s = summarize(innovations);
  if (s.count == 0) return "innovations: none tested";
  char line[256];
  std::snprintf(line, sizeof line,
                "innovations: %llu tested by the gate, median NIS %s%.2f times chi-square(2)'s, %.1f%% beyond its 95%% "
                "point (honest covariances: 1 and 5%%)",
                static_cast<unsigned long long>(s.count), s.median_in_top_bin ? "above " : "", s.median_scale,
                100.0 * s.fraction_beyond_95);
  return line;
}

}  // namespace vantage::targets
