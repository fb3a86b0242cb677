#pragma once
// The message of the std::invalid_argument that f() throws ("" when it throws none), so tests
// can check that an error names the key as the user wrote it.
#include <stdexcept>
#include <string>

namespace haptic::test {

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace haptic::test
