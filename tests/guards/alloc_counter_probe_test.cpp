// Registered WILL_FAIL: REQUIRE_NO_ALLOCATION must reject code that allocates.
#include <memory>

#include "tests/support/no_allocation.hpp"

namespace vantage::guard_probe {
int* allocate_with_new();
}

TEST_CASE("the allocation counter rejects an allocating call") {
  int* p = nullptr;
  REQUIRE_NO_ALLOCATION(p = vantage::guard_probe::allocate_with_new());
  std::unique_ptr<int> owner(p);
}
