#pragma once
// Counts heap allocations made by this thread while a NoAllocationScope is open. The counting
// operator new/delete and malloc family live in allocation_counter.cpp, linked into test binaries
// when VANTAGE_ALLOC_GUARD is on (not under ASan, which owns the allocator).
#include <cstdint>

namespace vantage::test {

// True when the counting allocator is linked in; tests that need it SKIP-fail loudly otherwise.
bool allocation_counter_active();

// Allocations (new, new[], malloc, calloc, realloc, aligned forms) seen on this thread since start.
std::uint64_t allocations_on_this_thread();

// Counts the allocations made on this thread between construction and count().
class AllocationScope {
 public:
  AllocationScope() : start_(allocations_on_this_thread()) {}
  std::uint64_t count() const { return allocations_on_this_thread() - start_; }

 private:
  std::uint64_t start_;
};

}  // namespace vantage::test
