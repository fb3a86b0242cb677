#include "firmware/model/growth_detector.hpp"

#include <cmath>
#include <limits>

namespace haptic::firmware {

void GrowthDetector::add(double t_s, double value) {
  if (!std::isfinite(value)) value = std::numeric_limits<double>::max();
  if (!started_) {
    started_ = true;
    window_start_s_ = t_s;
  }
  while (t_s >= window_start_s_ + c_.window_s) close_window(window_start_s_ + c_.window_s);
  window_max_ = any_in_window_ ? std::max(window_max_, value) : value;
  any_in_window_ = true;
}

void GrowthDetector::close_window(double end_s) {
  window_start_s_ = end_s;
  if (!any_in_window_) {  // a window without samples (the caller skipped a stretch) breaks a run
    run_ = 0;
    have_prev_ = false;
    return;
  }
  any_in_window_ = false;
  const double m = window_max_;
  if (have_prev_ && m >= c_.factor * prev_max_ && prev_max_ > (run_ == 0 ? c_.base : 0.0)) {
    if (run_ == 0) run_first_max_ = prev_max_;
    ++run_;
  } else {
    run_ = 0;
  }
  prev_max_ = m;
  have_prev_ = true;
  if (!detected_at_ && run_ >= c_.windows && m > c_.floor) {
    detected_at_ = end_s;
    rate_ = std::log(m / run_first_max_) / (run_ * c_.window_s);
  }
}

}  // namespace haptic::firmware
