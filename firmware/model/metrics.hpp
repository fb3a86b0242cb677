#pragma once
// The model quantities the run metrics and the outputs are made of, one definition each, for the
// simulator, the multi-process merge, the live view and (through the files they write) every
// Python tool. Each name says which quantity it is; different quantities get different names:
//  - consensus error:            max over pairs of copies and nodes of |x_i,p - x_j,p| (all copies);
//  - received-copy distance:     max over neighbours and nodes of |x_p - x_hat_j,p| (one station's copy
//                                against the copies it last received; the live view);
//  - distance from the mean shape: per copy and node |x_i,p - xbar_p|, xbar the mean of all copies
//                                (the snapshot figure's colours);
//  - deformation:                rms over nodes of the mean copy's displacement from x_d, the mean
//                                displacement removed;
//  - force balance (eq. 20):     |sum_i u_i| and mean_i |u_i| at one instant; the hold balance ratio
//                                is their means over the hold window, divided (RunMetrics);
//  - totals over stations:       sums of the stations' port energy (13), controller energy (14) and forces.
// The copies are x vectors of 3 n values (node-major).
#include <span>
#include <vector>

#include <Eigen/Core>

namespace haptic::model {

// max over nodes of |x_p - y_p| (m). RT-safe (no allocation): the live view calls it in the tick.
double max_node_distance_m(const double* x, const double* y, int nodes);
// The consensus error (m): max over pairs and nodes; +inf when it is not finite. Not RT-safe.
double consensus_error_m(std::span<const double* const> copies, int nodes);
// The deformation (m) of the mean copy from the rest shape x_d. Not RT-safe.
double deformation_m(std::span<const double* const> copies, const Eigen::VectorXd& x_d);
// Node `node`'s position in the mean copy (m). Not RT-safe.
Eigen::Vector3d mean_node_position_m(std::span<const double* const> copies, int node);
// Per copy and node, the distance from the mean shape (m). Not RT-safe.
std::vector<std::vector<double>> distance_from_mean_shape_m(std::span<const double* const> copies, int nodes);

// Eq. (20)'s force balance at one instant.
struct ForceBalance {
  Eigen::Vector3d sum_N = Eigen::Vector3d::Zero();  // sum_i u_i
  double sum_norm_N = 0;                            // |sum_i u_i|
  double mean_norm_N = 0;                           // mean_i |u_i|
};
ForceBalance force_balance(std::span<const Eigen::Vector3d> forces);
// The balance ratio |sum_i u_i| / mean_i |u_i| (at one instant, or of the two means over a window);
// NaN when mean_i |u_i| is 0 (no force: no balance to speak of).
double force_balance_ratio(double sum_norm_N, double mean_norm_N);

// Totals over stations, added station by station in station order.
struct StationTotals {
  double port_J = 0, controller_J = 0;
  Eigen::Vector3d force_N = Eigen::Vector3d::Zero();
  void add_energies(double port, double controller) {
    port_J += port;
    controller_J += controller;
  }
  void add_force(const Eigen::Vector3d& f) { force_N += f; }
};

}  // namespace haptic::model
