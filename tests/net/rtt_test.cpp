// Round-trip estimator: probing fixes a bound with margin; later samples above it are
// counted over-bound events that raise the bound and bump the generation.
#include <CppUTest/TestHarness.h>

#include <stdexcept>
#include <system_error>

#include <cmath>
#include <limits>

#include "firmware/model/passivity_budget.hpp"
#include "net/rtt.hpp"

using namespace haptic::net;

TEST_GROUP(Rtt){};

TEST(Rtt, ProbingSetsTheBoundFromTheMaximumWithMargin) {
  RttConfig c;
  c.bound_policy = &haptic::model::round_trip_bound_s;  // the station's (firmware/model)
  c.margin_fraction = 0.25;
  c.margin_s = 0.004;
  c.min_probe_samples = 5;
  RttEstimator e(c);
  e.begin_probing();
  for (double s : {0.010, 0.012, 0.011}) e.add_sample(s);
  CHECK_FALSE(e.finish_probing());  // too few samples: stays probing
  CHECK(e.probing());
  for (double s : {0.020, 0.009}) e.add_sample(s);
  CHECK(e.finish_probing());
  CHECK_FALSE(e.probing());
  DOUBLES_EQUAL(0.020 * 1.25 + 0.004, e.bound_s(), 1e-12);
  CHECK_EQUAL(15u, e.bound_ticks(0.002));  // 29 ms -> 14.5 -> 15 ticks
  DOUBLES_EQUAL(0.009, e.min_s(), 1e-12);
  DOUBLES_EQUAL(0.0124, e.mean_s(), 1e-12);
  CHECK_EQUAL(1u, e.generation());
}

TEST(Rtt, OverBoundSampleIsCountedAndRaisesTheBound) {
  RttConfig c;
  c.bound_policy = &haptic::model::round_trip_bound_s;
  c.min_probe_samples = 1;
  c.margin_fraction = 0.0;
  c.margin_s = 0.001;
  RttEstimator e(c);
  e.begin_probing();
  e.add_sample(0.010);
  CHECK(e.finish_probing());
  CHECK_FALSE(e.add_sample(0.011));  // within the 11 ms bound
  CHECK(e.add_sample(0.015));
  CHECK_EQUAL(1u, e.over_bound_events());
  DOUBLES_EQUAL(0.016, e.bound_s(), 1e-12);
  CHECK_EQUAL(2u, e.generation());
  CHECK_FALSE(e.add_sample(0.0155));
}

TEST(Rtt, WithoutAPolicyTheBoundIsTheMeasuredMaximum) {
  // net/ measures; the margin is the caller's policy (net/ knows no physics)
  RttConfig c;
  c.min_probe_samples = 1;
  RttEstimator e(c);
  e.begin_probing();
  for (double s : {0.010, 0.014}) e.add_sample(s);
  CHECK(e.finish_probing());
  DOUBLES_EQUAL(0.014, e.bound_s(), 0);
  CHECK(e.add_sample(0.015));
  DOUBLES_EQUAL(0.015, e.bound_s(), 0);
}

TEST(Rtt, NonsenseSamplesAreIgnored) {
  RttEstimator e;
  e.add_sample(-1.0);
  e.add_sample(std::numeric_limits<double>::quiet_NaN());
  e.add_sample(std::numeric_limits<double>::infinity());
  CHECK_EQUAL(0u, e.samples());
}

TEST(Rtt, BadConfigNamesTheKey) {
  RttConfig c;
  c.margin_fraction = -1;
  CHECK_THROWS(std::invalid_argument, RttEstimator(c));
}
