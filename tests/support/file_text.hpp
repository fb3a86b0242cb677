#pragma once
// The whole text of a file ("" when it cannot be read), for tests that check a tool's output file.
#include <fstream>
#include <sstream>
#include <string>

namespace haptic::test {

inline std::string file_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace haptic::test
