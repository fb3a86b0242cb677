#pragma once
// Whether the CPU runs AVX (256-bit lanes): the rt kernels with an AVX build choose it at run time
// (their AVX and baseline builds give the same bits). False off x86-64.
namespace haptic::rt {

inline bool cpu_has_avx() {
#if defined(__x86_64__)
  return __builtin_cpu_supports("avx");
#else
  return false;
#endif
}

}  // namespace haptic::rt
