// The transmission deadband (rt/tx_deadband): off sends every tick; on, a state within the band
// is held back, one outside it is sent at once, and the gap between sent states never exceeds
// max_interval_ticks (what the index-delay bound Nbar_ij adds for it).
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include "rt/tx_deadband.hpp"

using haptic::rt::TxDeadband;
using haptic::rt::TxDeadbandConfig;

TEST_GROUP(TxDeadband){};

TEST(TxDeadband, off_sends_every_tick) {
  TxDeadband d(TxDeadbandConfig{}, 6);
  std::vector<double> x(6, 0.0);
  for (int k = 0; k < 50; ++k) CHECK_TRUE(d.should_send(k, x.data()));
  CHECK_EQUAL(0, TxDeadbandConfig{}.added_index_delay_ticks(0));
  CHECK_EQUAL(0, TxDeadbandConfig{}.added_index_delay_ticks(5));
}

TEST(TxDeadband, a_still_state_is_sent_exactly_every_max_interval_ticks) {
  TxDeadbandConfig c;
  c.position_deadband_m = 1e-5;
  c.max_interval_ticks = 7;
  CHECK_EQUAL(6, c.added_index_delay_ticks(0));
  TxDeadband d(c, 6);
  std::vector<double> x(6, 0.01);
  std::int64_t last = -1;
  int sent = 0;
  for (int k = 0; k < 700; ++k) {
    x[3] = 0.01 + 0.9e-5 * std::sin(0.1 * k);  // wobbles inside the band
    if (d.should_send(k, x.data())) {
      if (last >= 0) CHECK_EQUAL(7, k - last);
      last = k;
      ++sent;
    }
  }
  CHECK_EQUAL(100, sent);
}

// Nbar's deadband allowance: with at most L packets lost in a row a receiver's newest state is at
// most L + added_index_delay_ticks(L) ticks old (above the network delay, 0 here), whatever the band
// triggers; the worst case (the object still, the L sends after a received one all lost) reaches it.
TEST(TxDeadband, with_L_packets_lost_in_a_row_the_held_state_stays_within_the_loss_and_deadband_allowances) {
  for (int interval : {2, 5, 20})
    for (int L : {0, 1, 3, 8}) {
      TxDeadbandConfig c;
      c.position_deadband_m = 1e-5;
      c.max_interval_ticks = interval;
      const std::int64_t bound = L + c.added_index_delay_ticks(L);
      for (int worst_case = 0; worst_case < 2; ++worst_case) {
        TxDeadband d(c, 6);
        std::vector<double> x(6, 0.01);
        std::mt19937 rng(static_cast<unsigned>(17 * interval + L));
        int lost_in_a_row = 0;
        std::int64_t newest = 0, oldest_held = 0;
        for (std::int64_t k = 0; k < 5000; ++k) {
          if (!worst_case) x[3] = 0.01 + 1.5e-5 * std::sin(0.05 * static_cast<double>(k));  // crosses the band now and then
          if (!d.should_send(k, x.data())) {
            oldest_held = std::max(oldest_held, k - newest);
            continue;
          }
          const bool lose = k > 0 && lost_in_a_row < L && (worst_case || rng() % 2 == 0);
          lost_in_a_row = lose ? lost_in_a_row + 1 : 0;
          if (!lose) newest = k;
          oldest_held = std::max(oldest_held, k - newest);
        }
        CHECK_TRUE(oldest_held <= bound);
        if (worst_case) CHECK_EQUAL(bound, oldest_held);
      }
    }
}

TEST(TxDeadband, a_move_beyond_the_band_is_sent_at_once_and_becomes_the_reference) {
  TxDeadbandConfig c;
  c.position_deadband_m = 1e-4;
  c.max_interval_ticks = 100;
  TxDeadband d(c, 3);
  std::vector<double> x = {0, 0, 0};
  CHECK_TRUE(d.should_send(0, x.data()));
  x[1] = 0.8e-4;
  CHECK_FALSE(d.should_send(1, x.data()));
  x[1] = 1.2e-4;  // beyond the band from the last SENT state
  CHECK_TRUE(d.should_send(2, x.data()));
  x[1] = 1.9e-4;  // within the band of the new reference
  CHECK_FALSE(d.should_send(3, x.data()));
  x[2] = NAN;  // a non-finite state is never held back
  CHECK_TRUE(d.should_send(4, x.data()));
  CHECK_EQUAL(3u, d.sent());
  CHECK_EQUAL(2u, d.skipped());
}

TEST(TxDeadband, a_predictive_band_holds_a_steady_drift_to_the_heartbeat_and_sends_at_once_when_the_velocity_changes) {
  // A steady drift of 1 um per tick (0.5 mm/s): the plain 10 um band must send every ~10 ticks, the
  // predictive one (reference: last sent x + (k - s) T v, at most 4 bands) only at its max interval
  // of 20 (19 um of drift, within the limit), exactly as long as the velocity holds; a change of
  // velocity shows up within the band's worth of ticks.
  const double T = 0.002, v = 5e-4, band = 1e-5;
  TxDeadbandConfig c;
  c.position_deadband_m = band;
  c.max_interval_ticks = 20;
  TxDeadbandConfig plain = c;
  c.predictive = true;
  DOUBLES_EQUAL(4e-5, c.prediction_limit_m(), 1e-18);
  TxDeadband pred(c, 3, T), held(plain, 3, T);
  std::vector<double> x(3, 0.02), vel = {0.0, v, 0.0};
  int sent_pred = 0, sent_plain = 0;
  std::int64_t last = -1;
  for (int k = 0; k < 462; ++k) {
    x[1] = 0.02 + k * T * v;
    if (pred.should_send(k, x.data(), vel.data())) {
      if (last >= 0) CHECK_EQUAL(20, k - last);  // the heartbeat only
      last = k;
      ++sent_pred;
    }
    sent_plain += held.should_send(k, x.data(), vel.data()) ? 1 : 0;
  }
  CHECK_EQUAL(24, sent_pred);  // k = 0, 20, ..., 460
  CHECK_TRUE(sent_plain >= 40);
  // the velocity stops at tick 462 (last sent at 460 with v): the prediction runs 1 um per tick ahead
  // of the still state, so the band is exceeded after 10 ticks, before the heartbeat at 480
  int first = -1;
  for (int k = 462; k < 480 && first < 0; ++k) {
    x[1] = 0.02 + 462 * T * v;
    vel[1] = 0.0;
    if (pred.should_send(k, x.data(), vel.data())) first = k;
  }
  CHECK_TRUE(first > 462 && first <= 462 + 11);
}

TEST(TxDeadband, the_prediction_is_limited_to_four_bands_so_a_fast_motion_falls_back_to_the_plain_band) {
  // 5 um per tick with a 1 um band: the extrapolation stops at 4 um, so a state that keeps moving is
  // sent within 5 ticks of the last one (4 um of prediction + 1 um of band), never held to the heartbeat.
  const double T = 0.002, v = 2.5e-3, band = 1e-6;
  TxDeadbandConfig c;
  c.position_deadband_m = band;
  c.max_interval_ticks = 100;
  c.predictive = true;
  TxDeadband d(c, 3, T);
  std::vector<double> x(3, 0.0), vel = {v, 0.0, 0.0};
  std::int64_t last = -1, longest = 0;
  for (int k = 0; k < 200; ++k) {
    x[0] = k * T * v;
    if (d.should_send(k, x.data(), vel.data())) {
      if (last >= 0) longest = std::max<std::int64_t>(longest, k - last);
      last = k;
    }
  }
  CHECK_TRUE(longest >= 1 && longest <= 5);
}

TEST(TxDeadband, bad_configuration_names_the_key) {
  TxDeadbandConfig c;
  c.max_interval_ticks = 0;
  try {
    c.validate();
    FAIL("expected a configuration error");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("max_interval_ticks", e.what());
  }
}
