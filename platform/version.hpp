#pragma once
// What build a binary is: the project version, `git describe` of the source tree and a build id,
// all fixed when CMake configured the build tree (platform/build_info.cpp.in). Every binary we ship
// prints version_line() for --version (CLI11 programs through platform/command_line.hpp; haptic-lab
// prints haptic-station's). Start-up / non-RT only: allocates.
#include <string>

namespace haptic::platform {

struct BuildInfo {
  const char* version;       // project(VERSION), e.g. "0.1.0"
  const char* git_describe;  // `git describe --tags --always --dirty` at configure time ("unknown" outside git)
  const char* build_id;      // 12 hex digits: SHA-256 of the fields below and git_describe
  const char* configured_utc;  // when CMake configured the build tree, e.g. "2026-12-01T21:30:00Z"
  const char* build_type;      // CMAKE_BUILD_TYPE
  const char* compiler;        // e.g. "GNU 12.2.0"
};

const BuildInfo& build_info();

// "<program> <version> (git <describe>, build <id>; <build type>, <compiler>, configured <utc>)".
std::string version_line(const std::string& program);

}  // namespace haptic::platform
