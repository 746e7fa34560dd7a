// Deliberately does what the core must never do, so the guards are seen to reject it.
#include <string>

namespace vantage::guard_probe {

int* allocate_with_new() { return new int(42); }

const std::string& function_local_static() {
  static const std::string kName("needs a thread-safe static guard and the heap");
  return kName;
}

}  // namespace vantage::guard_probe
