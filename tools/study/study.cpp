#include "tools/study/study.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace haptic::study {

ExactCase make_exact_case(int nodes, const PushProblemParams& params, double duration_s, double sample_dt_s,
                          bool keep_shape) {
  ExactCase c;
  c.problem = make_push_problem(make_ball_mesh(nodes, params.radius_m), params);
  const auto t0 = std::chrono::steady_clock::now();
  c.basis = compute_modes(c.problem.model);
  c.eig_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(3 * c.problem.model.nodes);
  ExactResponse ex(c.basis, c.problem.model, zero, zero);
  ex.set_output(c.problem.felt_w);
  const int samples = static_cast<int>(std::lround(duration_s / sample_dt_s));
  for (int j = 0; j <= samples; ++j) {
    const double t = j * sample_dt_s;
    c.times_s.push_back(t);
    c.force_N.push_back(c.problem.felt_force(t, ex.output(t)));
    c.force_scale = std::max(c.force_scale, std::abs(c.force_N.back()));
    if (keep_shape) {
      Eigen::VectorXd u;
      ex.displacement(t, u);
      c.shape_scale = std::max(c.shape_scale, u.norm());
      c.shape.push_back(std::move(u));
    }
  }
  return c;
}

namespace {
int steps_per_sample(const ExactCase& c, double step_s) {
  const double dt = c.times_s.size() > 1 ? c.times_s[1] - c.times_s[0] : step_s;
  const int k = static_cast<int>(std::lround(dt / step_s));
  if (k < 1 || std::abs(k * step_s - dt) > 1e-9 * dt) throw std::invalid_argument("sample interval must be a multiple of the step");
  return k;
}

void accumulate(const ExactCase& c, std::size_t j, double F, const Eigen::VectorXd* u, RunErrors& e,
                const ExactCase* ref) {
  e.force_error_self = std::max(e.force_error_self, std::abs(F - c.force_N[j]) / c.force_scale);
  if (u && !c.shape.empty()) e.shape_error_self = std::max(e.shape_error_self, (*u - c.shape[j]).norm() / c.shape_scale);
  if (ref) {
    const double er = std::abs(F - ref->force_N[j]) / ref->force_scale;
    e.force_error_ref = std::isnan(e.force_error_ref) ? er : std::max(e.force_error_ref, er);
  }
  if (!std::isfinite(F) || e.force_error_self > 1e3) e.blew_up = true;
}
}  // namespace

RunErrors run_full(const ExactCase& c, Integrator method, double step_s, const ExactCase* reference) {
  RunErrors e;
  LinearIntegrator integ(c.problem.model, method, step_s);
  const int k = steps_per_sample(c, step_s);
  if (reference && reference->times_s.size() != c.times_s.size()) throw std::invalid_argument("reference grid differs");
  accumulate(c, 0, c.problem.felt_force(0, integ.output(c.problem.felt_w)), &integ.u(), e, reference);
  for (std::size_t j = 1; j < c.times_s.size() && !e.blew_up; ++j) {
    for (int s = 0; s < k; ++s) integ.step();
    accumulate(c, j, c.problem.felt_force(c.times_s[j], integ.output(c.problem.felt_w)), &integ.u(), e, reference);
  }
  if (e.blew_up) e.force_error_self = e.shape_error_self = e.force_error_ref = std::numeric_limits<double>::infinity();
  return e;
}

RunErrors run_modal(const ExactCase& c, int modes, bool static_correction, double step_s) {
  RunErrors e;
  ModalReducedModel red(c.basis, c.problem.model, modes, step_s, static_correction, c.problem.felt_w);
  const int k = steps_per_sample(c, step_s);
  Eigen::VectorXd u;
  for (std::size_t j = 0; j < c.times_s.size() && !e.blew_up; ++j) {
    if (j > 0)
      for (int s = 0; s < k; ++s) red.step();
    const bool shape = !c.shape.empty();
    if (shape) red.displacement(u);
    accumulate(c, j, c.problem.felt_force(c.times_s[j], red.output()), shape ? &u : nullptr, e, nullptr);
  }
  e.force_error_ref = e.force_error_self;  // the modes come from the reference mesh itself
  return e;
}

namespace {
template <class Step>
double median_step_time(Step&& step, int repeats, double min_batch_s) {
  using clk = std::chrono::steady_clock;
  int batch = 16;
  for (;;) {  // calibrate the batch length
    const auto t0 = clk::now();
    for (int i = 0; i < batch; ++i) step();
    if (std::chrono::duration<double>(clk::now() - t0).count() >= min_batch_s || batch > (1 << 24)) break;
    batch *= 2;
  }
  std::vector<double> per;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = clk::now();
    for (int i = 0; i < batch; ++i) step();
    per.push_back(std::chrono::duration<double>(clk::now() - t0).count() / batch);
  }
  std::sort(per.begin(), per.end());
  return per[per.size() / 2];
}
}  // namespace

double time_full_step(const PushProblem& p, Integrator method, double step_s, int repeats, double min_batch_s) {
  LinearIntegrator integ(p.model, method, step_s);
  volatile double sink = 0;
  // A tick = one step + the felt force output (what the haptic loop needs).
  const double t = median_step_time(
      [&] {
        integ.step();
        sink = sink + integ.output(p.felt_w);
        if (integ.time_s() > 1.0) integ.reset();
      },
      repeats, min_batch_s);
  return t;
}

double time_modal_step(const ModalBasis& basis, const PushProblem& p, int modes, bool static_correction,
                       double step_s, int repeats, double min_batch_s) {
  ModalReducedModel red(basis, p.model, modes, step_s, static_correction, p.felt_w);
  volatile double sink = 0;
  return median_step_time(
      [&] {
        red.step();
        sink = sink + red.output();
      },
      repeats, min_batch_s);
}

EnergyTrace energy_trace(const PushProblem& p, Integrator method, double step_s, double duration_s,
                         int record_every) {
  LinearModel free_model = p.model;
  free_model.load.resize(0);
  free_model.damping_Ns_per_m = 0;
  // u0 = K^{-1} g: the static deformation under the full push.
  Eigen::SimplicialLDLT<rt::SparseColMajor> ldlt{rt::SparseColMajor(p.model.K)};
  const int n = p.model.nodes;
  Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> G(p.model.load.data(), n, 3);
  const Eigen::MatrixXd U = ldlt.solve(Eigen::MatrixXd(G));
  Eigen::VectorXd u0(3 * n);
  for (int i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) u0[3 * i + d] = U(i, d);
  LinearIntegrator integ(free_model, method, step_s);
  integ.set_state(u0, Eigen::VectorXd::Zero(3 * n));
  EnergyTrace tr;
  const double E0 = integ.energy();
  const long steps = std::lround(duration_s / step_s);
  tr.t_s.push_back(0);
  tr.energy_ratio.push_back(1.0);
  for (long s = 1; s <= steps; ++s) {
    integ.step();
    if (s % record_every == 0 || s == steps) {
      const double r = integ.energy() / E0;
      tr.t_s.push_back(integ.time_s());
      tr.energy_ratio.push_back(r);
      if (!std::isfinite(r) || r > 1e6) {
        tr.blew_up = true;
        break;
      }
    }
  }
  return tr;
}

std::string classify_energy(const EnergyTrace& t) {
  const std::size_t n = t.energy_ratio.size();
  double mx = 0, first = 0, second = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double r = std::isfinite(t.energy_ratio[k]) ? t.energy_ratio[k] : 1e300;
    mx = std::max(mx, r);
    (2 * k < n ? first : second) = std::max(2 * k < n ? first : second, r);
  }
  const double last = t.energy_ratio.back();
  if (t.blew_up || mx > 100 || !std::isfinite(last)) return "blows-up";
  if (mx > 1.01 && second > 1.1 * first) return "grows";
  if (last < 0.99) return "dissipative";
  if (mx > 1.01) return "bounded";
  return "stable";
}

std::vector<int> parse_int_list(const std::string& text, const std::string& what) {
  std::vector<int> v;
  for (double d : parse_double_list(text, what)) v.push_back(static_cast<int>(d));
  return v;
}

std::vector<double> parse_double_list(const std::string& text, const std::string& what) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      throw std::invalid_argument(what + ": '" + item + "' is not a number (expected a comma-separated list)");
    }
  }
  if (v.empty()) throw std::invalid_argument(what + ": empty list");
  return v;
}

}  // namespace haptic::study
