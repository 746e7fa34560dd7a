#pragma once
// REQUIRE_NO_ALLOCATION(expr): runs expr and fails the test when it allocated on this thread.
// Without the counting allocator (ASan builds) the check is reported as a warning, not a pass.
#include <catch2/catch.hpp>

#include "tests/support/allocation_counter.hpp"

#define REQUIRE_NO_ALLOCATION(...)                                              \
  do {                                                                          \
    ::vantage::test::AllocationScope vantage_alloc_scope_;                      \
    __VA_ARGS__;                                                                \
    if (::vantage::test::allocation_counter_active()) {                         \
      REQUIRE(vantage_alloc_scope_.count() == 0u);                              \
    } else {                                                                    \
      WARN("allocation counter not linked in this build: allocation unchecked"); \
    }                                                                           \
  } while (0)
