// Stand-in for builds where the counting allocator cannot be linked (ASan owns malloc there).
#include "tests/support/allocation_counter.hpp"

namespace vantage::test {
bool allocation_counter_active() { return false; }
std::uint64_t allocations_on_this_thread() { return 0; }
}  // namespace vantage::test
