#pragma once
// Resilient consensus: the distance-trimmed W-MSR rule (rt/README.md, "Resilient consensus").
// With at most F neighbours that may lie, a station leaves out, each tick, the F neighbours whose
// received configuration x_hat_j is farthest from its own x_i(k) (Euclidean over all 3n
// coordinates, one scalar per edge); its own state is the reference and never a candidate. An
// excluded edge takes the over-bound action of rt/station.hpp (x_hat_j := x_i(k), delta_ij = 0:
// the damper D_ij + T/2 P_ij), so A stays the one prefactored matrix. Which graphs let the honest
// stations agree: (2F+1)-robust ones (firmware/model/graph.hpp is_r_robust).
// Pure functions, no allocation, no state: RT-safe.
namespace haptic::rt {

// |a - b|^2 over n values. RT-safe.
double squared_distance(const double* a, const double* b, int n);

// Marks in excluded[0..count) the f candidates (candidate[j] != 0) with the largest dist2[j]
// (ties: the later neighbour first); every candidate when there are at most f. Entries that are
// not candidates are left 0. Returns how many were marked. f <= 0: none. RT-safe.
int exclude_farthest(const double* dist2, const unsigned char* candidate, int count, int f, unsigned char* excluded);

}  // namespace haptic::rt
