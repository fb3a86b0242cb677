#pragma once
// Counts heap allocations made by the calling thread, by interposing malloc/calloc/realloc/
// memalign/posix_memalign/aligned_alloc in the test binary (forwarding to glibc's __libc_*).
// operator new, Eigen and the C++ library all allocate through these, so a zero count over a
// window proves the code in that window did not touch the heap.
#include <cstdint>

namespace haptic::test {

class AllocationCounter {
 public:
  AllocationCounter();   // starts counting on this thread
  ~AllocationCounter();  // stops
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  std::uint64_t allocations() const;  // malloc-family calls on this thread since construction
  std::uint64_t frees() const;
};

// Self-check that the interposer is live in this binary (a new must be counted).
bool allocation_counter_works();

}  // namespace haptic::test
