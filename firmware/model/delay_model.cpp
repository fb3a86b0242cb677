#include "firmware/model/delay_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace haptic::model {

namespace {
[[noreturn]] void bad(const std::string& msg) { throw std::invalid_argument(msg); }

void check_square(const Eigen::MatrixXd& m, const std::string& what) {
  if (m.rows() != m.cols() || m.rows() < 1) bad(what + ": must be a square N x N matrix");
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(item);
  return out;
}

double cell_value(const std::string& cell, const std::string& key) {
  const auto b = cell.find_first_not_of(" \t[]");
  const auto e = cell.find_last_not_of(" \t[]");
  const std::string t = b == std::string::npos ? "" : cell.substr(b, e - b + 1);
  if (t == "inf") return std::numeric_limits<double>::infinity();
  try {
    std::size_t used = 0;
    const double v = std::stod(t, &used);
    if (used != t.size() || std::isnan(v)) throw std::invalid_argument(t);
    return v;
  } catch (const std::exception&) {
    bad(key + ": '" + t + "' is not a number");
  }
}
}  // namespace

Eigen::MatrixXd paper_delay_matrix_ms() {
  Eigen::MatrixXd d(4, 4);
  d << 0, 4, 4, 4, 8, 0, 80, 200, 4, 100, 0, 200, 6, 240, 200, 0;
  return d;
}

Eigen::MatrixXd parse_delay_matrix(const std::string& text, const std::string& key, int users) {
  std::vector<std::string> rows;
  for (const auto& r : split(text, ';'))
    if (r.find_first_not_of(" \t[]") != std::string::npos) rows.push_back(r);
  const int n = users > 0 ? users : static_cast<int>(rows.size());
  if (users > 0 && static_cast<int>(rows.size()) != users)
    bad(key + " needs " + std::to_string(users) + " rows separated by ';' (got " + std::to_string(rows.size()) + ")");
  if (n < 2) bad(key + ": need an N x N matrix with N >= 2, rows separated by ';'");
  Eigen::MatrixXd m(n, n);
  for (int i = 0; i < n; ++i) {
    const auto cols = split(rows[static_cast<std::size_t>(i)], ',');
    if (static_cast<int>(cols.size()) != n)
      bad(key + " row " + std::to_string(i + 1) + " needs " + std::to_string(n) + " values (got " + std::to_string(cols.size()) + ")");
    for (int j = 0; j < n; ++j) m(i, j) = cell_value(cols[static_cast<std::size_t>(j)], key);
  }
  return m;
}

int index_delay_bound_ticks(double max_delay_ms, double period_s, int loss_allowance_ticks) {
  if (!(period_s > 0)) bad("period: T must be > 0 s");
  if (!(max_delay_ms >= 0) || !std::isfinite(max_delay_ms)) bad("delay: a link's maximum delay must be finite and >= 0 ms");
  // 1e-9: a delay of exactly m periods is m ticks, not m + 1 from rounding noise.
  return static_cast<int>(std::ceil(max_delay_ms * 1e-3 / period_s - 1e-9)) + loss_allowance_ticks;
}

int loss_allowance_from_loss(double p, double ticks, int directed_links, double per_run) {
  return loss_allowance_from_loss(LossModel{p}, ticks, directed_links, per_run);
}

double consecutive_loss_probability(const LossModel& m, int n) {
  if (!(m.p >= 0 && m.p < 1)) bad("loss probability must be in [0, 1)");
  if (!m.bursty()) return std::pow(m.p, n);
  if (!(m.burst_enter > 0 && m.burst_enter <= 1)) bad("burst entry probability must be in (0, 1]");
  if (!(m.burst_exit > 0 && m.burst_exit <= 1)) bad("burst exit probability must be in (0, 1]");
  if (!(m.burst_loss >= 0 && m.burst_loss <= 1)) bad("loss probability in a burst must be in [0, 1]");
  // a(s) = P(the packets so far all lost, chain now in s), from the stationary distribution; each
  // further packet steps the chain, then is lost with its state's probability.
  const double pi_bad = m.burst_enter / (m.burst_enter + m.burst_exit);
  double good = (1 - pi_bad) * m.p, bad_state = pi_bad * m.burst_loss;
  for (int k = 1; k < n; ++k) {
    const double g = (good * (1 - m.burst_enter) + bad_state * m.burst_exit) * m.p;
    const double b = (good * m.burst_enter + bad_state * (1 - m.burst_exit)) * m.burst_loss;
    good = g;
    bad_state = b;
  }
  return n <= 0 ? 1.0 : good + bad_state;
}

int loss_allowance_from_loss(const LossModel& m, double ticks, int directed_links, double per_run) {
  (void)consecutive_loss_probability(m, 1);  // the model's ranges first, then the target's
  if (!(per_run > 0 && per_run < 1)) bad("over-bound chance per run must be in (0, 1)");
  const double events = std::max(1.0, ticks) * std::max(1, directed_links);
  int L = 0;
  // P(L+1 lost in a row) events <= per_run; the cap keeps absurd inputs finite (p -> 1)
  while (L < 1000 && consecutive_loss_probability(m, L + 1) * events > per_run) ++L;
  return L;
}

double loss_upper_bound(long long lost, long long expected, double z) {
  if (expected <= 0) bad("measured loss: no packet expected (the probe was too short)");
  if (lost < 0 || lost > expected) bad("measured loss: lost must be in [0, expected]");
  const double n = static_cast<double>(expected), p = static_cast<double>(lost) / n, z2 = z * z;
  // Wilson score interval, upper end
  const double centre = p + z2 / (2 * n), half = z * std::sqrt(p * (1 - p) / n + z2 / (4 * n * n));
  return std::min(1.0, (centre + half) / (1 + z2 / n));
}

int loss_allowance_from_measured_loss(long long lost, long long expected, double ticks, int directed_links, double per_run) {
  // p -> 1 (everything lost) is not [0, 1): the capped search of loss_allowance_from_loss answers 1000
  const double p = std::min(loss_upper_bound(lost, expected), std::nextafter(1.0, 0.0));
  return loss_allowance_from_loss(p, ticks, directed_links, per_run);
}

int receive_rule_ticks(rt::RxRule rule, int spread_ticks) { return rule == rt::RxRule::kNewestBySequence ? 0 : spread_ticks + 1; }

int receive_rule_ticks(rt::RxRule rule, double min_delay_ms, double max_delay_ms, double period_s) {
  if (rule == rt::RxRule::kNewestBySequence) return 0;
  if (!(period_s > 0)) bad("period: T must be > 0 s");
  if (!(min_delay_ms >= 0 && min_delay_ms <= max_delay_ms) || !std::isfinite(max_delay_ms))
    bad("delay: a link's delays must satisfy 0 <= min <= max < inf");
  return receive_rule_ticks(rule, static_cast<int>(std::ceil((max_delay_ms - min_delay_ms) * 1e-3 / period_s - 1e-9)));
}

Eigen::MatrixXi index_delay_bounds_ticks(const Eigen::MatrixXd& mean_delay_ms, double jitter_fraction, double period_s,
                                         int loss_allowance_ticks, rt::RxRule rule) {
  check_square(mean_delay_ms, "delay matrix");
  const auto n = mean_delay_ms.rows();
  Eigen::MatrixXi nbar = Eigen::MatrixXi::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j)
      if (i != j && std::isfinite(mean_delay_ms(i, j)))
        nbar(i, j) = index_delay_bound_ticks((1.0 + jitter_fraction) * mean_delay_ms(i, j), period_s, loss_allowance_ticks) +
                     receive_rule_ticks(rule, (1.0 - jitter_fraction) * mean_delay_ms(i, j), (1.0 + jitter_fraction) * mean_delay_ms(i, j),
                                        period_s);
  return nbar;
}

Eigen::MatrixXi index_delay_bounds_ticks_from_range(const Eigen::MatrixXd& links, double min_delay_ms, double max_delay_ms, double period_s,
                                                    int loss_allowance_ticks, rt::RxRule rule) {
  check_square(links, "delay matrix");
  const int one = index_delay_bound_ticks(max_delay_ms, period_s, loss_allowance_ticks) + receive_rule_ticks(rule, min_delay_ms, max_delay_ms, period_s);
  Eigen::MatrixXi nbar = Eigen::MatrixXi::Zero(links.rows(), links.cols());
  for (Eigen::Index i = 0; i < links.rows(); ++i)
    for (Eigen::Index j = 0; j < links.cols(); ++j)
      if (i != j && std::isfinite(links(i, j))) nbar(i, j) = one;
  return nbar;
}

Eigen::VectorXd round_trip_half_sums_ms(const Graph& g, const Eigen::MatrixXi& nbar_ticks, double period_s) {
  Eigen::VectorXd s = Eigen::VectorXd::Zero(nbar_ticks.rows());
  for (const Link& l : g) {
    const double half_ms = (nbar_ticks(l.a, l.b) + nbar_ticks(l.b, l.a)) * period_s * 1e3 / 2.0;
    s(l.a) += half_ms;
    s(l.b) += half_ms;
  }
  return s;
}

int index_guard_from_round_trip(int round_trip_ticks) { return (round_trip_ticks + 1) / 2; }

int assumed_round_trip_sum_ticks(int round_trip_ticks, int agreement_ticks) {
  return 2 * index_guard_from_round_trip(round_trip_ticks) + agreement_ticks;
}

Eigen::MatrixXi mean_delay_steps(const Eigen::MatrixXd& mean_delay_ms, double period_s) {
  check_square(mean_delay_ms, "delay matrix");
  if (!(period_s > 0)) bad("period: T must be > 0 s");
  const double t_ms = period_s * 1e3;
  Eigen::MatrixXi s(mean_delay_ms.rows(), mean_delay_ms.cols());
  for (Eigen::Index i = 0; i < s.rows(); ++i)
    for (Eigen::Index j = 0; j < s.cols(); ++j) {
      const double d = mean_delay_ms(i, j);
      if (i != j && !(d >= 0))
        bad("delay matrix: entry (" + std::to_string(i + 1) + "," + std::to_string(j + 1) + ") must be >= 0 ms (+inf: no link)");
      s(i, j) = i == j ? 0 : (std::isfinite(d) ? static_cast<int>(std::lround(d / t_ms)) : -1);
    }
  return s;
}

}  // namespace haptic::model
