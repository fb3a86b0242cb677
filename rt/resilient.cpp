#include "rt/resilient.hpp"

namespace haptic::rt {

double squared_distance(const double* a, const double* b, int n) {
  double s = 0;
  for (int i = 0; i < n; ++i) {
    const double d = a[i] - b[i];
    s += d * d;
  }
  return s;
}

int exclude_farthest(const double* dist2, const unsigned char* candidate, int count, int f, unsigned char* excluded) {
  for (int j = 0; j < count; ++j) excluded[j] = 0;
  int marked = 0;
  for (; marked < f; ++marked) {
    int far = -1;
    for (int j = 0; j < count; ++j)
      if (candidate[j] && !excluded[j] && (far < 0 || !(dist2[j] < dist2[far]))) far = j;
    if (far < 0) break;
    excluded[far] = 1;
  }
  return marked;
}

}  // namespace haptic::rt
