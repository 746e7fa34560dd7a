#pragma once
// Clock capability: monotonic time, real (hal/steady_clock.hpp) or simulated (sim_hal).
#include <cstdint>

namespace vantage::hal {

class Clock {
 public:
  virtual std::int64_t now_ns() const = 0;

 protected:
  ~Clock() = default;
};

}  // namespace vantage::hal
