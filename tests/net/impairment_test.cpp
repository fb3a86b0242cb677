// Impairment emulator: the paper preset is unchanged and reproducible; statistics of every
// knob match the model within sampling error (fixed seeds, so these are deterministic).
#include <CppUTest/TestHarness.h>

#include <stdexcept>
#include <system_error>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "net/impairment.hpp"

using namespace haptic::net;

TEST_GROUP(Impairment){};

TEST(Impairment, PaperPresetMatchesTheModelStatistics) {
  ImpairedLink link(LinkImpairment::paper(0.080), 7);
  const int n = 200000;
  int lost = 0, dup = 0, delivered = 0;
  double sum = 0.0, lo = 1e9, hi = 0.0;
  for (int i = 0; i < n; ++i) {
    const PacketFate f = link.next_packet();
    if (f.lost) ++lost;
    if (f.duplicated) ++dup;
    for (int c = 0; c < f.copies; ++c) {
      ++delivered;
      sum += f.delay_s[c];
      lo = std::min(lo, f.delay_s[c]);
      hi = std::max(hi, f.delay_s[c]);
    }
  }
  DOUBLES_EQUAL(0.05, lost / double(n), 0.003);
  DOUBLES_EQUAL(0.01 * 0.95, dup / double(n), 0.001);
  DOUBLES_EQUAL(0.080, sum / delivered, 0.0005);
  CHECK(lo >= 0.040 && hi <= 0.120);
  CHECK(lo < 0.041 && hi > 0.119);
}

TEST(Impairment, SameSeedSameSequenceDifferentSeedDifferent) {
  LinkImpairment m = LinkImpairment::bursty(0.05);
  m.blackout_start_s = 1.0;
  m.blackout_length_s = 0.5;
  ImpairedLink a(m, 42), b(m, 42), c(m, 43);
  int differ = 0;
  for (int i = 0; i < 5000; ++i) {
    const double t = i * 0.002;
    const PacketFate fa = a.next_packet_at(t), fb = b.next_packet_at(t), fc = c.next_packet_at(t);
    CHECK_EQUAL(fa.copies, fb.copies);
    CHECK_EQUAL(fa.delay_s[0], fb.delay_s[0]);
    CHECK_EQUAL(fa.delay_s[1], fb.delay_s[1]);
    if (fa.copies != fc.copies || fa.delay_s[0] != fc.delay_s[0]) ++differ;
  }
  CHECK(differ > 1000);
}

TEST(Impairment, PaperPresetSequenceIsPinned) {
  // Golden values: the deterministic simulator's runs depend on this exact sequence; the
  // extensions (burst, reorder, blackout, trace) must not consume random numbers when off.
  ImpairedLink link(LinkImpairment::paper(0.1), 1);
  const PacketFate f = link.next_packet();
  Rng r(1);
  const double u_loss = r.uniform01(), u_dup = r.uniform01(), d0u = r.uniform01();
  CHECK_EQUAL(u_loss < 0.05, f.lost);
  if (!f.lost) DOUBLES_EQUAL(0.1 * (0.5 + d0u), f.delay_s[0], 1e-15);
  CHECK_EQUAL(u_dup < 0.01 && !f.lost, f.duplicated);
}

TEST(Impairment, GilbertElliottBurstsHaveTheModelMeanLengthAndRate) {
  LinkImpairment m;
  m.burst_enter_probability = 0.01;
  m.burst_exit_probability = 0.2;  // mean burst length 5
  m.burst_loss_probability = 1.0;
  ImpairedLink link(m, 3);
  const int n = 400000;
  int lost = 0, bursts = 0;
  bool prev = false;
  for (int i = 0; i < n; ++i) {
    const bool l = link.next_packet().burst_lost;
    lost += l;
    if (l && !prev) ++bursts;
    prev = l;
  }
  // Stationary bad-state probability p/(p+r) = 0.01/0.21.
  DOUBLES_EQUAL(0.01 / 0.21, lost / double(n), 0.004);
  DOUBLES_EQUAL(5.0, lost / double(bursts), 0.3);
}

TEST(Impairment, ReorderingHoldsPacketsBackSoLaterOnesOvertake) {
  LinkImpairment m;
  m.mean_delay_s = 0.010;
  m.jitter_fraction = 0.0;
  m.reorder_probability = 0.1;
  m.reorder_extra_delay_s = 0.007;
  ImpairedLink link(m, 5);
  int reordered = 0;
  for (int i = 0; i < 100000; ++i) {
    const PacketFate f = link.next_packet();
    if (f.reordered) {
      ++reordered;
      DOUBLES_EQUAL(0.017, f.delay_s[0], 1e-12);
    } else {
      DOUBLES_EQUAL(0.010, f.delay_s[0], 1e-12);
    }
  }
  DOUBLES_EQUAL(0.1, reordered / 1e5, 0.005);
  DOUBLES_EQUAL(0.017, m.max_delay_s(), 1e-12);
}

TEST(Impairment, BlackoutDropsEverythingInsideTheWindowOnly) {
  ImpairedLink link(LinkImpairment::blackout(0.004, 1.0, 0.25), 9);
  int in_lost = 0, in_n = 0, out_lost = 0, out_n = 0;
  for (int i = 0; i < 1000; ++i) {
    const double t = i * 0.002;
    const PacketFate f = link.next_packet_at(t);
    if (t >= 1.0 && t < 1.25) {
      ++in_n;
      in_lost += f.blackout_lost;
    } else {
      ++out_n;
      out_lost += f.blackout_lost;
    }
  }
  CHECK_EQUAL(125, in_n);
  CHECK_EQUAL(125, in_lost);
  CHECK_EQUAL(0, out_lost);
}

TEST(Impairment, DelayTraceIsReplayedCyclically) {
  const std::string path = "/tmp/haptic_net_trace_test.txt";
  {
    std::ofstream f(path);
    f << "# recorded one-way delays, ms\n10\n 20.5\n\n30 # last\n";
  }
  auto trace = load_delay_trace(path);
  CHECK_EQUAL(3u, trace->size());
  LinkImpairment m;
  m.delay_trace = trace;
  ImpairedLink link(m, 1);
  const double expect[] = {0.010, 0.0205, 0.030, 0.010, 0.0205};
  for (double e : expect) DOUBLES_EQUAL(e, link.next_packet().delay_s[0], 1e-12);
  DOUBLES_EQUAL(0.030, m.max_delay_s(), 1e-12);
  {
    std::ofstream f(path);
    f << "10\n-3\n";
  }
  CHECK_THROWS(std::invalid_argument, load_delay_trace(path));
  std::remove(path.c_str());
  CHECK_THROWS(std::invalid_argument, load_delay_trace("/nonexistent/trace.txt"));
}

TEST(Impairment, BadModelsAndPresetNamesAreRejectedWithTheKey) {
  LinkImpairment m;
  m.burst_exit_probability = 0.0;
  CHECK_THROWS(std::invalid_argument, ImpairedLink(m, 1));
  m = LinkImpairment{};
  m.reorder_probability = 1.5;
  CHECK_THROWS(std::invalid_argument, ImpairedLink(m, 1));
  try {
    LinkImpairment::preset("wobbly", 0.1);
    FAIL("no throw");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("impairment.preset") != std::string::npos);
  }
  CHECK_EQUAL(0.05, LinkImpairment::preset("paper", 0.1).loss_probability);
  CHECK_EQUAL(0.0, LinkImpairment::preset("none", 0.1).loss_probability);
}

// The time-correlated delay: the same uniform support and mean as the paper's
// i.i.d. delay, but consecutive packets' delays strongly correlated; rho = 0 is the i.i.d. model.
TEST(Impairment, CorrelatedDelayKeepsTheUniformSupportAndCorrelatesConsecutivePackets) {
  auto stats = [](double rho, double* lag1, double* mean, double* lo, double* hi, double* frac_low_quarter) {
    LinkImpairment m = LinkImpairment::paper(0.010);
    m.loss_probability = 0;
    m.duplicate_probability = 0;
    m.delay_correlation = rho;
    ImpairedLink link(m, 11);
    const int n = 200000;
    std::vector<double> d(n);
    for (int i = 0; i < n; ++i) d[static_cast<std::size_t>(i)] = link.next_packet().delay_s[0];
    double s = 0, lo_ = 1, hi_ = 0, low = 0;
    for (double x : d) {
      s += x;
      lo_ = std::min(lo_, x);
      hi_ = std::max(hi_, x);
      low += x < 0.0075 ? 1 : 0;
    }
    const double mu = s / n;
    double c0 = 0, c1 = 0;
    for (int i = 0; i < n; ++i) {
      c0 += (d[static_cast<std::size_t>(i)] - mu) * (d[static_cast<std::size_t>(i)] - mu);
      if (i > 0) c1 += (d[static_cast<std::size_t>(i)] - mu) * (d[static_cast<std::size_t>(i - 1)] - mu);
    }
    *lag1 = c1 / c0;
    *mean = mu;
    *lo = lo_;
    *hi = hi_;
    *frac_low_quarter = low / n;
  };
  double lag1, mean, lo, hi, q;
  stats(0.0, &lag1, &mean, &lo, &hi, &q);
  CHECK(std::abs(lag1) < 0.01);
  stats(0.99, &lag1, &mean, &lo, &hi, &q);
  CHECK(lag1 > 0.97);                       // consecutive delays nearly equal
  DOUBLES_EQUAL(0.010, mean, 0.0004);       // the same mean ...
  CHECK(lo >= 0.005 && hi <= 0.015);        // ... and support mean x [1 - j, 1 + j]
  DOUBLES_EQUAL(0.25, q, 0.03);             // ... and uniform marginal (a quarter below 7.5 ms)
  LinkImpairment bad = LinkImpairment::paper(0.01);
  bad.delay_correlation = 1.0;
  CHECK_THROWS(std::invalid_argument, ImpairedLink(bad, 1));
}
