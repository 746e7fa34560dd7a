#pragma once
// One log line on the image front end's tracked observations, for the targets' end-of-mission output.
#include <string>

#include "core/frontend/image_front_end.hpp"

namespace vantage::targets {

// "tracking: N observations predicted in view, x% matched; failed: template masked by the warp y%, ..."
// (no newline); every share is of the predicted count; with inverse-warp matches, "x% matched (z% by the
// inverse warp)". "tracking: no observation predicted in view" for 0.
std::string tracking_summary(std::uint64_t predicted, std::uint64_t matched, std::uint64_t inverse_warped,
                             const TrackFailureCounts& failures);

// "seeding: N seeds searched, x% matched, y% past the depth range" (no newline); a large last share says
// the configured depth range misses much of the scene. "seeding: no seed searched" for 0.
std::string seeding_summary(std::uint64_t tried, std::uint64_t matched, std::uint64_t beyond_depth_range);

}  // namespace vantage::targets
