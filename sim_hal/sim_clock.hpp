#pragma once
// Simulated monotonic time, advanced explicitly by the simulation loop.
#include <cstdint>

#include "hal/clock.hpp"

namespace vantage::sim {

class SimClock final : public hal::Clock {
 public:
  std::int64_t now_ns() const override { return now_ns_; }
  // Negative or non-finite dt is ignored (time never runs backward).
  void advance(double dt_s);
  double now_s() const { return static_cast<double>(now_ns_) * 1e-9; }

 private:
  std::int64_t now_ns_ = 0;
};

}  // namespace vantage::sim
