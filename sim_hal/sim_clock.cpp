#include "sim_hal/sim_clock.hpp"

#include <cmath>

namespace vantage::sim {

void SimClock::advance(double dt_s) {
  if (!std::isfinite(dt_s) || dt_s <= 0.0) return;
  now_ns_ += static_cast<std::int64_t>(std::llround(dt_s * 1e9));
}

}  // namespace vantage::sim
