// CppUTest entry point shared by every test binary. CppUTest's leak detector is off: tests build
// static fixtures (scenes, factorizations) once, which it would report as leaks. Heap use where
// it matters (the tick) is proven by tests/support/alloc_counter.hpp instead.
#include <CppUTest/CommandLineTestRunner.h>
#include <CppUTest/MemoryLeakWarningPlugin.h>

int main(int argc, char** argv) {
  MemoryLeakWarningPlugin::turnOffNewDeleteOverloads();
  return CommandLineTestRunner::RunAllTests(argc, argv);
}
