#pragma once
// The one error type of the simulator: every bad outside input (mesh file, scene file, configuration)
// throws SimError with a single line naming the file and field. Constructors either finish or throw, so
// nothing is left half-initialized; targets catch it, print what() and exit non-zero.
#include <stdexcept>
#include <string>

namespace vantage::sim {

class SimError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace vantage::sim
