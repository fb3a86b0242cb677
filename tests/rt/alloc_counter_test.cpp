#include <CppUTest/TestHarness.h>

#include <vector>

#include "tests/support/alloc_counter.hpp"

TEST_GROUP(AllocationCounter){};

TEST(AllocationCounter, counts_a_vector_growth_and_nothing_when_idle) {
  CHECK_TRUE(haptic::test::allocation_counter_works());
  haptic::test::AllocationCounter idle;
  volatile double x = 0;
  for (int i = 0; i < 1000; ++i) x = x + i;
  CHECK_EQUAL(0u, idle.allocations());
  std::vector<int> v;
  haptic::test::AllocationCounter growing;
  for (int i = 0; i < 100; ++i) v.push_back(i);
  CHECK_TRUE(growing.allocations() >= 1);
}
