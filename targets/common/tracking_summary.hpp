#pragma once
// Log lines on the image front end's tracked observations and the EKF's innovations, for the targets'
// end-of-mission output.
#include <string>

#include "core/estimation/nis_histogram.hpp"
#include "core/frontend/image_front_end.hpp"

namespace vantage::targets {

// "tracking: N observations predicted in view, x% matched; failed: template masked by the warp y%, ..."
// (no newline); every share is of the predicted count; with inverse-warp matches, "x% matched (z% by the
// inverse warp)". "tracking: no observation predicted in view" for 0.
std::string tracking_summary(std::uint64_t predicted, std::uint64_t matched, std::uint64_t inverse_warped,
                             const TrackFailureCounts& failures);

// "seeding: N seeds searched, x% matched, y% past the depth range" (no newline), ", z% refused by the
// left-right check" when it refused any and ", w% erased without a plane fit" when it erased any (each a share
// of the seeds searched); a large past-the-range share says the configured depth range misses much of the
// scene. "seeding: no seed searched" for 0.
std::string seeding_summary(std::uint64_t tried, std::uint64_t matched, std::uint64_t beyond_depth_range,
                            std::uint64_t rejected_back_match, std::uint64_t rejected_no_plane_fit);

// "innovations: N tested by the gate, median NIS x times chi-square(2)'s, y% beyond its 95% point (honest
// covariances: 1 and 5%)" (no newline): the EKF's consistency without ground truth (NisHistogram). A median
// beyond the 95 % point reads "above x". "innovations: none tested" for an empty histogram.
std::string innovation_summary(const NisHistogram& innovations);

}  // namespace vantage::targets
