#pragma once
// The speed-against-accuracy study: runs the reference integrators and
// reduced models of tools/study/integrators.hpp, tools/study/modal.hpp on the push problem of tools/study/model_selector.hpp
// and measures their error against the exact (modal closed-form) solution. Analysis code: it
// allocates freely; only the timed step loops are allocation-free.
#include <Eigen/Core>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "tools/study/integrators.hpp"
#include "tools/study/modal.hpp"
#include "tools/study/model_selector.hpp"

namespace haptic::study {

// One mesh of the family with its exact solution sampled on a common time grid.
struct ExactCase {
  PushProblem problem;
  ModalBasis basis;
  std::vector<double> times_s;            // sample times
  std::vector<double> force_N;            // exact felt force at each sample
  std::vector<Eigen::VectorXd> shape;     // exact displacement u at each sample (3n)
  double force_scale = 0, shape_scale = 0;  // max |F|, max ||u||
  double eig_seconds = 0;
};

// Builds the problem on make_ball_mesh(nodes), the modes and the exact samples every
// sample_dt_s over [0, duration_s]. keep_shape = false skips the O(n^2) shape samples.
ExactCase make_exact_case(int nodes, const PushProblemParams& params, double duration_s, double sample_dt_s,
                          bool keep_shape = true);

struct RunErrors {
  bool blew_up = false;           // non-finite or error > 1e3
  double force_error_self = 0;    // vs the same mesh's exact solution (integration error)
  double shape_error_self = 0;
  double force_error_ref = std::numeric_limits<double>::quiet_NaN();  // vs the reference mesh's exact force
};

// Runs a full-model integrator on `c` (sample_dt must be a multiple of step_s).
RunErrors run_full(const ExactCase& c, Integrator method, double step_s, const ExactCase* reference);
// Runs the r-mode reduced model of `c` with NPMI.
RunErrors run_modal(const ExactCase& c, int modes, bool static_correction, double step_s);

// Wall-clock seconds per step (median over `repeats` batches, each >= ~min_batch_s) of the
// allocation-free step loop. Not a Google Benchmark figure.
double time_full_step(const PushProblem& p, Integrator method, double step_s, int repeats = 5,
                      double min_batch_s = 0.02);
double time_modal_step(const ModalBasis& basis, const PushProblem& p, int modes, bool static_correction,
                       double step_s, int repeats = 5, double min_batch_s = 0.02);

// Free vibration (no input) from a deformed rest: u0 = static response to the push load.
struct EnergyTrace {
  std::vector<double> t_s, energy_ratio;  // E(t) / E(0)
  bool blew_up = false;
};
EnergyTrace energy_trace(const PushProblem& p, Integrator method, double step_s, double duration_s,
                         int record_every);

// Classification of a free-vibration run (stability map): "blows-up" (max E/E0 > 100 or
// non-finite), "grows" (max E/E0 > 1.01 and the second half's max > 1.1 x the first half's),
// "dissipative" (final E/E0 < 0.99), "bounded" (oscillates above 1.01 without a trend, e.g.
// symplectic Euler's modified energy), "stable" (|E/E0 - 1| <= 1% throughout).
std::string classify_energy(const EnergyTrace& t);

// Paths relative to the repository when run from there.
std::vector<int> parse_int_list(const std::string& text, const std::string& what);
std::vector<double> parse_double_list(const std::string& text, const std::string& what);

}  // namespace haptic::study
