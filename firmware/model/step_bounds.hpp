#pragma once
// The bounds T^min <= T_k <= T^max of a station's measured step (eq. 18's D term and P term, eq. 26,
// the core's step levels), one rule for the simulator's clock model and for the real station's
// measurement while probing. T_k is the interval between two wakes of the station's loop (the
// simulator's clocks and the station measure it alike: this wake minus the previous one); a wake is
// late after its grid time by a delay in [0, J], and the grid interval is T r (1 +- F), so
//   T^min = min(T, T r_lo (1 - F) - J),   T^max = max(T, T r_hi (1 + F) + J).
// Start-up code (no allocation, but not on the tick).
namespace haptic::model {

struct StepBounds {
  double t_min_s = 0, t_max_s = 0;
  bool capped = false;  // the measured wake-delay bound was larger than the cap (steps beyond are clamped, counted)
};

// The clock model's bounds: grid interval T rate (1 +- jitter), wake delays in [0, wake_delay_s].
StepBounds step_bounds(double period_s, double rate, double jitter, double wake_delay_s);

// A real station's bounds from the largest wake-up latency measured while probing: the wake delay
// bound J = min(cap_s, kWakeHeadroom x measured + kWakeFloor_s) on its own clock (rate 1, no grid
// jitter: the loop's deadlines are exact multiples of T), then step_bounds. A longer wake later in the
// run gives a step outside the bounds, which the core clamps and counts (steps_clamped).
inline constexpr double kWakeHeadroom = 1.5;    // the probe's few hundred wakes under-sample the tail
inline constexpr double kWakeFloor_s = 20e-6;   // an idle PREEMPT_RT host measures a few µs
StepBounds measured_step_bounds(double period_s, double max_wake_latency_s, double cap_s);

// A neighbour's T^min from the T^max it announced (only T^max travels, in its fingerprints): measured
// bounds are T -+ J, so 2 T - T^max, at least T / 2 (station.step_margin_max <= 0.5). What the
// neighbour state check's step fit assumes (rt/edge_monitor.hpp StepBox); a station whose
// station.period_min_s is set below it has its shorter steps read as unexplained motion.
double announced_step_min(double period_s, double t_max_s);

}  // namespace haptic::model
