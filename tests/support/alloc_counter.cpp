#include "tests/support/alloc_counter.hpp"

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <memory>

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {
thread_local bool t_counting = false;
thread_local std::uint64_t t_allocs = 0;
thread_local std::uint64_t t_frees = 0;
inline void count_alloc() {
  if (t_counting) ++t_allocs;
}
}  // namespace

extern "C" {
void* malloc(std::size_t n) {
  count_alloc();
  return __libc_malloc(n);
}
void* calloc(std::size_t a, std::size_t b) {
  count_alloc();
  return __libc_calloc(a, b);
}
void* realloc(void* p, std::size_t n) {
  count_alloc();
  return __libc_realloc(p, n);
}
void free(void* p) {
  if (t_counting && p) ++t_frees;
  __libc_free(p);
}
void* memalign(std::size_t a, std::size_t n) {
  count_alloc();
  return __libc_memalign(a, n);
}
void* aligned_alloc(std::size_t a, std::size_t n) {
  count_alloc();
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, std::size_t a, std::size_t n) {
  count_alloc();
  void* p = __libc_memalign(a, n);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
}

namespace haptic::test {

AllocationCounter::AllocationCounter() {
  t_allocs = 0;
  t_frees = 0;
  t_counting = true;
}
AllocationCounter::~AllocationCounter() { t_counting = false; }
std::uint64_t AllocationCounter::allocations() const { return t_allocs; }
std::uint64_t AllocationCounter::frees() const { return t_frees; }

bool allocation_counter_works() {
  AllocationCounter c;
  auto p = std::make_unique<volatile int>(3);
  (void)p;
  return c.allocations() >= 1;
}

}  // namespace haptic::test
