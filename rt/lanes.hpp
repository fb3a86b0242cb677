#pragma once
// Four double lanes (GCC vector extension) for the rt kernels that keep a node's three columns in
// one vector (lane 3 unused: it carries the next node's first column, or 0 at the last node, and
// is never stored or summed). A kernel's baseline build runs the lane operations as SSE2 pairs and
// its AVX build (target("avx"), chosen by cpu_has_avx()) in 256-bit registers: each lane does the
// same IEEE operations in the same order, so both builds give the same bits (replay on any CPU).
namespace haptic::rt {

typedef double Lanes4 __attribute__((vector_size(32)));

// sum_c l[c] over the first W lanes, in lane order ((l0 + l1) + l2 for a node): how a kernel's
// per-lane sums become one number, the same in every build.
template <int W>
[[gnu::always_inline]] inline double lane_sum(const Lanes4& l) {
  double s = l[0];
  for (int c = 1; c < W; ++c) s += l[c];
  return s;
}

}  // namespace haptic::rt

// Node `node`'s three columns of the interleaved array p (3 doubles per node) as Lanes4; `last`:
// the array's last node (lane 3 is then 0 instead of a read past the end). A macro, not a function:
// a Lanes4 argument or return value would change the ABI between the baseline and AVX builds.
#define HAPTIC_NODE_LANES(p, node, last)                                                 \
  __extension__({                                                                      \
    ::haptic::rt::Lanes4 r_;                                                           \
    if (!(last)) {                                                                     \
      __builtin_memcpy(&r_, (p) + 3L * (node), sizeof r_);                             \
    } else {                                                                           \
      r_ = ::haptic::rt::Lanes4{(p)[3L * (node)], (p)[3L * (node) + 1], (p)[3L * (node) + 2], 0.0}; \
    }                                                                                  \
    r_;                                                                                \
  })
// Stores lanes 0-2 of v as node `node`'s three columns of p.
#define HAPTIC_STORE_NODE(p, node, v) __builtin_memcpy((p) + 3L * (node), &(v), 3 * sizeof(double))
