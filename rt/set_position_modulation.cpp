#include "rt/set_position_modulation.hpp"

#include <cmath>
#include <stdexcept>

namespace haptic::rt {

ConsensusPassivity parse_consensus_passivity(const std::string& text, const std::string& key) {
  if (text == "eq18") return ConsensusPassivity::kEq18Damping;
  if (text == "pspm") return ConsensusPassivity::kSetPositionModulation;
  throw std::invalid_argument(key + " = \"" + text + "\" must be \"eq18\" (eq. 18 damping B_i, the paper) or \"pspm\" (passive set-position modulation)");
}

const char* consensus_passivity_name(ConsensusPassivity p) {
  return p == ConsensusPassivity::kSetPositionModulation ? "pspm" : "eq18";
}

void SetPositionModulator::init(int dofs, const double* x0, double reservoir0_J) {
  if (dofs <= 0 || x0 == nullptr) throw std::invalid_argument("set-position modulation: no state");
  if (!(reservoir0_J >= 0) || !std::isfinite(reservoir0_J))
    throw std::invalid_argument("set-position modulation: the initial reservoir must be finite and >= 0 J");
  ybar_.assign(x0, x0 + dofs);
  reservoir_J_ = reservoir0_J;
  limited_ticks_ = 0;
  injected_J_ = 0;
}

void SetPositionModulator::prepare(const double* y, const double* x, double* scratch) const {
  const int n = static_cast<int>(ybar_.size());
  // d = y - ybar, r = x - ybar; dV(alpha) = a alpha^2 + b alpha with a = d^T P d / 2, b = -d^T P r.
  double* d = scratch;
  double* r = scratch + n;
  const double* yb = ybar_.data();
  for (int i = 0; i < n; ++i) {
    d[i] = y[i] - yb[i];
    r[i] = x[i] - yb[i];
  }
}

double SetPositionModulator::update(const double* y, const double* x, const SpatialMatrix& P, double* scratch) {
  prepare(y, x, scratch);
  // one pass over P's rows; P symmetric: d^T P r = r^T P d
  return finish(P.pair_forms(scratch, scratch + ybar_.size()), scratch);
}

double SetPositionModulator::finish(const PairForms& f, const double* scratch) {
  const int n = static_cast<int>(ybar_.size());
  const double* d = scratch;
  double* yb = ybar_.data();
  const double a = 0.5 * f.dAd, b = -f.rAd;
  const double E = reservoir_J_ > 0 ? reservoir_J_ : 0.0;
  double alpha = 1.0;
  if (a + b > E) {  // the full jump costs more than the reservoir holds: the largest affordable alpha
    // a alpha^2 + b alpha = E has exactly one root in (0, 1] (dV(0) = 0 <= E < dV(1), a >= 0): the
    // larger root, written without cancellation for b >= 0 (then also a = 0 works: alpha = E / b);
    // for b < 0, a > -b > 0.
    const double disc = b * b + 4.0 * a * E;
    alpha = b >= 0 ? (2.0 * E) / (b + std::sqrt(disc)) : (-b + std::sqrt(disc)) / (2.0 * a);
    if (!(alpha >= 0.0)) alpha = 0.0;
    if (alpha > 1.0) alpha = 1.0;
    ++limited_ticks_;
  }
  if (!std::isfinite(alpha) || !std::isfinite(a) || !std::isfinite(b)) return 0.0;  // never jump on non-finite data
  const double dV = (a * alpha + b) * alpha;
  for (int i = 0; i < n; ++i) yb[i] += alpha * d[i];
  reservoir_J_ -= dV;
  if (reservoir_J_ < 0) reservoir_J_ = 0;  // rounding only: dV <= E by construction
  if (dV > 0) injected_J_ += dV;
  return alpha;
}

}  // namespace haptic::rt
