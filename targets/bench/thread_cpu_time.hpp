#pragma once
// The calling thread's CPU time: benchmarks time themselves by it, since the machines are shared.
#include <time.h>

namespace vantage::bench {

inline double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace vantage::bench
