// Resilient consensus (rt/resilient.hpp, rt/README.md "Resilient consensus"): the distance-trimmed
// W-MSR rule leaves out exactly the F neighbours farthest from the station's own copy, an excluded
// edge is the over-bound damper, and on a 3-robust graph (K_5) one authenticated liar - reporting
// its copy with a constant offset, a wobble at the object's lowest mode or a slow ramp - no longer
// drags the four honest copies, which agree among themselves.
#include <CppUTest/TestHarness.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numeric>
#include <random>
#include <vector>

#include "rt/resilient.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(Resilient){};

TEST(Resilient, excludes_exactly_the_f_farthest_candidates_and_nothing_else) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 2000; ++trial) {
    const int count = 1 + static_cast<int>(rng() % 16), f = static_cast<int>(rng() % 4);
    double d2[16];
    unsigned char cand[16], out[16];
    int ncand = 0;
    for (int j = 0; j < count; ++j) {
      d2[j] = u(rng) < 0.2 ? 0.5 : u(rng);  // some ties
      cand[j] = u(rng) < 0.8 ? 1 : 0;
      ncand += cand[j];
      out[j] = 7;
    }
    const int marked = exclude_farthest(d2, cand, count, f, out);
    CHECK_EQUAL(std::min(f, ncand), marked);
    int n_out = 0;
    for (int j = 0; j < count; ++j) {
      CHECK_TRUE(out[j] == 0 || out[j] == 1);
      if (!cand[j]) CHECK_EQUAL(0, out[j]);
      n_out += out[j];
      // an excluded candidate is at least as far as every kept one
      for (int i = 0; i < count; ++i)
        if (out[j] && cand[i] && !out[i]) CHECK_TRUE(d2[j] >= d2[i]);
    }
    CHECK_EQUAL(marked, n_out);
  }
  // ties: the later neighbour first; f <= 0: none
  const double d2[] = {1, 3, 3, 2};
  const unsigned char all[] = {1, 1, 1, 1};
  unsigned char out[4];
  CHECK_EQUAL(1, exclude_farthest(d2, all, 4, 1, out));
  CHECK_TRUE(out[2] == 1 && out[0] + out[1] + out[3] == 0);
  CHECK_EQUAL(0, exclude_farthest(d2, all, 4, 0, out));
  CHECK_EQUAL(0, out[0] + out[1] + out[2] + out[3]);
  DOUBLES_EQUAL(1 + 4 + 0.25, squared_distance(std::vector<double>{1, 2, 3}.data(), std::vector<double>{0, 0, 3.5}.data(), 3), 1e-15);
}

namespace {
// A station with three neighbours at rest, whose packets hold x_d shifted by 1, 5 and 2 mm: the rule
// (F = 1) must leave out the second, and its edge then acts exactly as an edge with no packet in
// its delay bound (the damper x_hat_j := x(k), delta = 0): a core to which the second neighbour never
// sends gives the same bits.
struct Triple {
  Eigen::VectorXd x, v;
  std::uint32_t flags = 0;
  std::uint64_t excluded[3] = {};
};
Triple three_neighbours(int f, bool second_silent) {
  const auto& w = PaperWorld::get();
  auto c = w.station(0, 4, {1, 2, 3}, 20, test::tetra_dirs()[0], 0);  // bound 0: a silent link is out from tick 0
  for (auto& nb : c.neighbors) nb.energy_bound_J = 0.1, nb.energy_release_J = 0.05;
  c.resilient_f = f;
  StationCore s(c);
  const int dofs = w.scene.dofs;
  const double shift[] = {1e-3, 5e-3, 2e-3};
  Triple r;
  for (int k = 0; k < 200; ++k) {
    for (int n = 0; n < 3; ++n) {
      Eigen::VectorXd x = w.scene.x_d, v = Eigen::VectorXd::Zero(dofs);
      for (int p = 0; p < w.scene.nodes; ++p) x[3 * p + n] += shift[n];
      if (!(n == 1 && second_silent)) s.rx(n).offer(k, 0, x.data(), v.data(), dofs);
    }
    r.flags |= s.tick(k, w.face_center(test::tetra_dirs()[0])).flags;
  }
  r.x = s.x();
  r.v = s.v();
  for (int n = 0; n < 3; ++n) r.excluded[n] = s.resilient_excluded_ticks(n);
  return r;
}
}  // namespace

TEST(Resilient, the_farthest_neighbour_is_left_out_and_its_edge_is_the_over_bound_damper) {
  const Triple excluded = three_neighbours(1, false);
  CHECK_EQUAL(0u, excluded.excluded[0]);
  CHECK_EQUAL(200u, excluded.excluded[1]);
  CHECK_EQUAL(0u, excluded.excluded[2]);
  CHECK_TRUE((excluded.flags & kResilientExcluded) != 0);
  const Triple silent = three_neighbours(0, true);
  const Triple all_in = three_neighbours(0, false);
  CHECK_TRUE((silent.flags & kResilientExcluded) == 0 && all_in.excluded[1] == 0);
  // the exclusion did something: the 5 mm neighbour moves the copy when it is in
  CHECK_TRUE((excluded.x - all_in.x).cwiseAbs().maxCoeff() > 1e-4);
  // and the excluded edge is exactly the damper of an edge without data
  CHECK_TRUE(excluded.x == silent.x);
  CHECK_TRUE(excluded.v == silent.v);
}

namespace {

enum class Lie { kNone, kOffset, kModeWobble, kRamp };
const char* lie_name(Lie l) {
  return l == Lie::kNone ? "none" : l == Lie::kOffset ? "offset 20 mm" : l == Lie::kModeWobble ? "lowest-mode wobble 10 mm" : "ramp 10 mm/s";
}

// The object's lowest elastic mode (node-level K_int: its first non-zero eigenvector, applied along
// one direction), scaled to 1 m at its largest node, and its angular frequency (rad/s).
struct Mode {
  Eigen::VectorXd shape;
  double omega = 0;
};
const Mode& lowest_mode() {
  static const Mode m = [] {
    const auto& w = PaperWorld::get();
    const Eigen::MatrixXd S = Eigen::MatrixXd(w.scene.K_int.S);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
    const Eigen::VectorXd u = es.eigenvectors().col(1);  // col 0: translation (eigenvalue 0)
    const Eigen::Vector3d e = Eigen::Vector3d(1, 0.5, -0.3).normalized();
    Mode r;
    r.shape = Eigen::VectorXd::Zero(w.scene.dofs);
    for (int p = 0; p < w.scene.nodes; ++p) r.shape.segment<3>(3 * p) = u[p] / u.cwiseAbs().maxCoeff() * e;
    r.omega = std::sqrt(es.eigenvalues()[1] / w.scene.params.node_mass_kg);
    return r;
  }();
  return m;
}

struct Outcome {
  double drag_m = 0;          // end: largest honest centroid displacement from where the lie-free run put it
  double disagreement_m = 0;  // last 0.5 s: largest node distance between two honest copies
  std::uint64_t liar_excluded = 0, honest_excluded = 0;  // edge-ticks the honest stations left out
  double honest_edge_peak_J = 0;  // largest account of an honest edge at an honest station
  std::uint64_t honest_trips = 0, liar_trips = 0;
  bool diverged = false;
  std::vector<Eigen::Vector3d> centroid;  // per station at the end
};

Eigen::Vector3d centroid(const Eigen::VectorXd& x) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int p = 0; p < x.size() / 3; ++p) c += x.segment<3>(3 * p);
  return c / static_cast<double>(x.size() / 3);
}

// K_5, station 4 lies. Directed delays 2-5 ticks, B_i from eq. (18) (+5 %), the energy bound
// bound_J on every edge (with the default leak); user 0 pushes its face in by 10 mm over the first second and holds, the
// others rest on theirs. The liar runs an honest core and tampers only with what it sends.
// The stations and their links (1-based, as a topology is written); the last station lies.
struct Net {
  const char* name;
  int users;
  const char* links;
};
const Net kK5{"K5", 5, "1-2,1-3,1-4,1-5,2-3,2-4,2-5,3-4,3-5,4-5"};

Outcome run_net(const Net& net, Lie lie, int f, double bound_J, double seconds, const Outcome* reference, bool pspm = false) {
  const auto& w = PaperWorld::get();
  const int N = net.users, kLiar = N - 1;
  constexpr int D = 8;
  const std::vector<Eigen::Vector3d> dirs = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}, {0, 0, 1}, {0, 0, -1}, {1, 0, 0}};
  std::vector<std::vector<int>> adj(static_cast<std::size_t>(N));
  for (const char* c = net.links; *c;) {
    char* end = nullptr;
    const int a = static_cast<int>(std::strtol(c, &end, 10)) - 1;
    const int b = static_cast<int>(std::strtol(end + 1, &end, 10)) - 1;
    adj[static_cast<std::size_t>(a)].push_back(b), adj[static_cast<std::size_t>(b)].push_back(a);
    c = *end ? end + 1 : end;
  }
  auto delay = [](int to, int from) { return 2 + (3 * to + from) % 4; };
  const double T = 0.002;
  std::vector<std::unique_ptr<StationCore>> st;
  for (int i = 0; i < N; ++i) {
    std::vector<int> peers;
    std::vector<Eq18Neighbor> eq18;
    for (int j : adj[static_cast<std::size_t>(i)]) peers.push_back(j), eq18.push_back({static_cast<double>(delay(i, j) + delay(j, i)), T, &w.gains});
    auto c = w.station(i, N, peers, 1.05 * damping_min_eq18(T, eq18), dirs[static_cast<std::size_t>(i)]);
    for (std::size_t n = 0; n < peers.size(); ++n) {
      c.neighbors[n].index_delay_bound_ticks = delay(i, peers[n]);
      c.neighbors[n].energy_bound_J = bound_J;
      c.neighbors[n].energy_release_J = 0.5 * bound_J;
      c.neighbors[n].energy_leak_W = kDefaultEdgeEnergyLeakW;
    }
    c.resilient_f = i == kLiar ? 0 : f;
    if (pspm) {  // passive set-position modulation: B_i = 0, E0 = 1 mJ per edge end (the station's default)
      c.consensus_passivity = ConsensusPassivity::kSetPositionModulation;
      c.damping_Ns_per_m = 0;
      c.pspm_reservoir0_J = 1e-3;
    }
    st.push_back(std::make_unique<StationCore>(c));
  }
  const int dofs = w.scene.dofs;
  std::vector<Eigen::VectorXd> sx(N * D, w.scene.x_d), sv(N * D, Eigen::VectorXd::Zero(dofs));  // sent states by tick
  const Mode& mode = lowest_mode();
  const Eigen::Vector3d e = Eigen::Vector3d(0.3, -1, 0.4).normalized();
  Outcome r;
  const int ticks = static_cast<int>(seconds / T);
  for (int k = 0; k < ticks; ++k) {
    const double t = k * T;
    for (int i = 0; i < N; ++i) {
      auto& s = *st[static_cast<std::size_t>(i)];
      for (int n = 0; n < s.neighbor_count(); ++n) {
        const int j = s.neighbor(n).peer_id;
        const int seq = k - delay(i, j);
        if (seq >= 0) s.rx(n).offer(seq, 0, sx[j * D + seq % D].data(), sv[j * D + seq % D].data(), dofs);
      }
      const auto& dir = dirs[static_cast<std::size_t>(i)];
      const double depth = i == 0 ? 0.01 * std::min(1.0, t) : 0.0;
      r.diverged = r.diverged || (s.tick(k, w.face_center(dir) + depth * w.face_inward(dir)).flags & kDiverged) != 0;
      Eigen::VectorXd& x = sx[i * D + k % D];
      Eigen::VectorXd& v = sv[i * D + k % D];
      x = Eigen::Map<const Eigen::VectorXd>(s.x_hat(), dofs);
      v = Eigen::Map<const Eigen::VectorXd>(s.v_hat(), dofs);
      if (i != kLiar || lie == Lie::kNone) continue;
      for (int p = 0; p < w.scene.nodes; ++p) {
        if (lie == Lie::kOffset) x.segment<3>(3 * p) += 0.02 * e;
        if (lie == Lie::kRamp) x.segment<3>(3 * p) += 0.01 * t * e, v.segment<3>(3 * p) += 0.01 * e;
      }
      if (lie == Lie::kModeWobble) {
        x += 0.01 * std::sin(mode.omega * t) * mode.shape;
        v += 0.01 * mode.omega * std::cos(mode.omega * t) * mode.shape;
      }
    }
    if (t < seconds - 0.5) continue;
    for (int i = 0; i < kLiar; ++i)
      for (int j = i + 1; j < kLiar; ++j) {
        const Eigen::VectorXd d = st[static_cast<std::size_t>(i)]->x() - st[static_cast<std::size_t>(j)]->x();
        for (int p = 0; p < w.scene.nodes; ++p) r.disagreement_m = std::max(r.disagreement_m, d.segment<3>(3 * p).norm());
      }
  }
  for (int i = 0; i < N; ++i) {
    const auto& s = *st[static_cast<std::size_t>(i)];
    r.centroid.push_back(centroid(s.x()));
    if (reference && i != kLiar) r.drag_m = std::max(r.drag_m, (r.centroid.back() - reference->centroid[static_cast<std::size_t>(i)]).norm());
    if (i == kLiar) continue;
    for (int n = 0; n < s.neighbor_count(); ++n) {
      const bool liar = s.neighbor(n).peer_id == kLiar;
      (liar ? r.liar_excluded : r.honest_excluded) += s.resilient_excluded_ticks(n);
      (liar ? r.liar_trips : r.honest_trips) += s.edge_gate().trips(n);
      if (!liar) r.honest_edge_peak_J = std::max(r.honest_edge_peak_J, s.edge_energy().edge_J(n));
    }
  }
  std::printf("\n  %s, %s, bound %5.2f J, %-24s F = %d: drag %7.2f mm, honest disagreement %.4f mm, edge-ticks left out: liar %llu honest %llu, "
              "gate trips: liar %llu honest %llu, honest edge account at the end %.2e J%s",
              net.name, pspm ? "pspm" : "eq18", bound_J, lie_name(lie), f, 1e3 * r.drag_m, 1e3 * r.disagreement_m, static_cast<unsigned long long>(r.liar_excluded),
              static_cast<unsigned long long>(r.honest_excluded), static_cast<unsigned long long>(r.liar_trips),
              static_cast<unsigned long long>(r.honest_trips), r.honest_edge_peak_J, r.diverged ? " DIVERGED" : "");
  return r;
}

Outcome run_k5(Lie lie, int f, double bound_J, double seconds, const Outcome* reference, bool pspm = false) {
  return run_net(kK5, lie, f, bound_J, seconds, reference, pspm);
}

// With the default energy bound (0.1 J) the gate already holds each lie's energy, so the drag is
// small either way; with a permissive bound (10 J) the lie drags the honest copies unless the rule
// leaves the liar out. Honest disagreement is compared with the lie-free run of the same rule.
void check_k5(double bound_J) {
  const double seconds = 6.0;
  const std::uint64_t honest_edge_ticks = 4ull * static_cast<std::uint64_t>(seconds / 0.002);
  const Outcome ref = run_k5(Lie::kNone, 0, bound_J, seconds, nullptr);
  const Outcome ref_f = run_k5(Lie::kNone, 1, bound_J, seconds, &ref);
  CHECK_FALSE(ref.diverged || ref_f.diverged);
  CHECK_TRUE(ref_f.drag_m < 1e-3 && ref_f.disagreement_m < 0.5e-3);  // the rule costs the honest run little
  for (Lie lie : {Lie::kOffset, Lie::kModeWobble, Lie::kRamp}) {
    const Outcome off = run_k5(lie, 0, bound_J, seconds, &ref);
    const Outcome on = run_k5(lie, 1, bound_J, seconds, &ref);
    CHECK_FALSE(on.diverged || off.diverged);
    // the honest copies stay where the lie-free run put them, within 1 mm, and agree within 0.5 mm
    CHECK_TRUE(on.drag_m < 1e-3);
    CHECK_TRUE(on.disagreement_m < 0.5e-3);
    // the liar is the one left out on nearly every tick, and no honest edge trips the energy gate
    CHECK_TRUE(on.liar_excluded > 98 * honest_edge_ticks / 100);
    CHECK_EQUAL(0u, on.honest_trips);
    // without the rule a constant offset or a ramp drags the honest copies until the gate trips:
    // with a permissive bound that is tens of mm
    if (bound_J >= 1.0 && lie != Lie::kModeWobble) CHECK_TRUE(off.drag_m > 20e-3);
  }
}
}  // namespace

TEST(Resilient, on_k5_one_liar_no_longer_drags_the_honest_copies_and_they_agree) {
  check_k5(kDefaultEdgeEnergyBoundJ);
  check_k5(10.0);
}

// Under pspm a left-out edge's set-position relaxes towards the copy's own state: the same lies, the
// same result, with eq. (14) kept by the reservoirs (E0 = 1 mJ) and no energy bound needed.
TEST(Resilient, under_set_position_modulation_one_liar_on_k5_no_longer_drags_the_honest_copies) {
  const double seconds = 6.0;
  const Outcome ref = run_k5(Lie::kNone, 0, kDefaultEdgeEnergyBoundJ, seconds, nullptr, true);
  for (Lie lie : {Lie::kOffset, Lie::kRamp}) {
    const Outcome off = run_k5(lie, 0, kDefaultEdgeEnergyBoundJ, seconds, &ref, true);
    const Outcome on = run_k5(lie, 1, kDefaultEdgeEnergyBoundJ, seconds, &ref, true);
    CHECK_FALSE(on.diverged || off.diverged);
    CHECK_TRUE(on.drag_m < 0.5e-3);  // 1.0 mm without the rule (the reservoirs bound the lie), 0.25 mm with it
    CHECK_TRUE(on.disagreement_m < 0.5e-3);
    CHECK_TRUE(on.liar_excluded > 98 * 4ull * static_cast<std::uint64_t>(seconds / 0.002) / 100);
  }
}

// A 3-robust graph that is not complete: the optimizer's best 3-robust graph on six users (11 links,
// tools/topology/README.md); user 6 lies and only users 1, 2 and 5 hear it. The honest five still
// agree and stay where the lie-free run put them; without the rule (permissive energy bound) the
// offset drags them, the users the liar does not reach included.
TEST(Resilient, on_a_3_robust_graph_that_is_not_complete_the_honest_copies_agree_without_the_liar) {
  const Net net{"6 users, 11 links", 6, "1-2,1-3,1-4,1-5,1-6,2-3,2-4,2-6,3-5,4-5,5-6"};
  const double seconds = 6.0;
  const Outcome ref = run_net(net, Lie::kNone, 0, 10.0, seconds, nullptr);
  for (Lie lie : {Lie::kOffset, Lie::kRamp}) {
    const Outcome off = run_net(net, lie, 0, 10.0, seconds, &ref);
    const Outcome on = run_net(net, lie, 1, 10.0, seconds, &ref);
    CHECK_FALSE(on.diverged || off.diverged);
    CHECK_TRUE(on.drag_m < 1e-3);
    CHECK_TRUE(on.disagreement_m < 0.5e-3);
    CHECK_TRUE(off.drag_m > 20e-3);
    CHECK_TRUE(on.liar_excluded > 98 * 3ull * static_cast<std::uint64_t>(seconds / 0.002) / 100);  // 3 honest ends
  }
}
