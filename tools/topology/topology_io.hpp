#pragma once
// Input/output of the topology optimizer (haptic-topology): delay matrices, gain files, the
// simulator's run/summary.json link statistics, and the ranked-table JSON. Offline tool code.
#include <Eigen/Core>
#include <string>

#include "tools/topology/topology.hpp"

namespace haptic::tools::topology {

// Delay matrix from a JSON file: either a bare N x N array or {"mean_delay_ms": [[...]]}.
Eigen::MatrixXd read_delay_file(const std::string& path);

// Measured link statistics of a run: the simulator's summary.json key "link_stats", a list of
// {"to": i, "from": j, "mean_delay_ms": x, "max_delay_ms": y, "loss_rate": z} (users from 1; row i
// receives from j). Pairs without statistics (absent, or "delivered": 0) are +inf (no measured
// link) in mean/max, 0 in loss.
struct MeasuredLinks {
  Eigen::MatrixXd mean_delay_ms;
  Eigen::MatrixXd max_delay_ms;
  Eigen::MatrixXd loss_rate;
  int entries = 0;
};
MeasuredLinks read_summary(const std::string& path, int users_hint);

// Mean information age used for N_ij from measured statistics: with packet sustainment a lost
// packet ages the held sample by one more period, so the expected age grows by T p/(1-p).
Eigen::MatrixXd effective_mean_delay_ms(const MeasuredLinks& m, double period_s);

// Gain file (JSON):
//   {"a": [[..]], "b": [[..]], "mode_values": [..]}          -> polynomial gains (may be scalars
//                                                               for a and b: uniform)
//   {"n": n, "blocks": {"1-2": [[..]], "2-1": [[..]], ...}}   -> explicit dense P_ij (row i from j)
struct GainFile {
  bool dense = false;
  ::haptic::topology::PolynomialGains poly;
  ::haptic::topology::DenseGains blocks;
};
GainFile read_gain_file(const std::string& path, int users);

}  // namespace haptic::tools::topology
