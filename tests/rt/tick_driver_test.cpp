// rt::drive_tick, the one way a StationCore is driven: each packet offered at seq - k0, the observer
// told every verdict and then that the step comes, the step taken with the T_k asked for; the same
// core state as a core driven by hand, and no heap in the tick.
#include <CppUTest/TestHarness.h>

#include <vector>

#include "rt/station.hpp"
#include "rt/tick_driver.hpp"
#include "tests/rt/fixtures.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(TickDriver){};

namespace {

struct Heard {
  std::int64_t index;
  RxVerdict verdict;
  int offered_before_step;  // -1: offered after stepping() (wrong)
};

// Records what drive_tick tells it (into preallocated storage).
struct LogObserver {
  std::vector<Heard>& heard;
  int count = 0;
  bool stepped = false;
  void offered(const ReceivedState&, std::int64_t index, RxVerdict v) {
    ++count;
    heard.push_back({index, v, stepped ? -1 : count});
  }
  void stepping() { stepped = true; }
};

StationConfig variable_step_config() {
  const auto& w = PaperWorld::get();
  const auto dir = test::tetra_dirs()[0];
  StationConfig c = w.station(0, 4, {1, 2}, 20.0, dir, 3);
  c.period_min_s = 0.0015;
  c.period_max_s = 0.0025;
  return c;
}

}  // namespace

TEST(TickDriver, offers_each_packet_at_its_sequence_minus_k0_then_steps_with_the_step_asked_for_like_a_core_driven_by_hand) {
  const auto& w = PaperWorld::get();
  const StationConfig cfg = variable_step_config();
  StationCore driven(cfg), by_hand(cfg);
  const int dofs = w.scene.dofs;
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-3);
  const Eigen::Vector3d p0 = w.face_center(test::tetra_dirs()[0]), in = w.face_inward(test::tetra_dirs()[0]);
  const std::int64_t k0 = 5000;  // the sequence number of index 0 (a station's run_k0)
  std::vector<Heard> heard;
  heard.reserve(16);
  for (std::int64_t k = 0; k < 400; ++k) {
    const Eigen::Vector3d q = p0 + 0.01 * (k < 200 ? static_cast<double>(k) / 200.0 : 1.0 - static_cast<double>(k - 200) / 200.0) * in;
    const double step_s = 0.0015 + 0.001 * static_cast<double>(k % 7) / 6.0;
    // link 0 every tick; link 1 every third tick, its packet two ticks old and then a duplicate (refused)
    const bool send1 = k % 3 == 0 && k >= 2;
    heard.clear();
    const auto out = drive_tick(driven, TickDrive{k, k0, q, step_s},
                                [&](auto&& offer) {
                                  offer(ReceivedState{0, k0 + k, 0.0, x.data(), v.data(), dofs});
                                  if (send1) {
                                    offer(ReceivedState{1, k0 + k - 2, 0.0, x.data(), v.data(), dofs});
                                    offer(ReceivedState{1, k0 + k - 2, 0.0, x.data(), v.data(), dofs});
                                  }
                                },
                                LogObserver{heard});
    std::vector<RxVerdict> want;
    want.push_back(by_hand.rx(0).offer(k, 0.0, x.data(), v.data(), dofs));
    if (send1) {
      want.push_back(by_hand.rx(1).offer(k - 2, 0.0, x.data(), v.data(), dofs));
      want.push_back(by_hand.rx(1).offer(k - 2, 0.0, x.data(), v.data(), dofs));
    }
    const auto ref = by_hand.tick(k, q, step_s);
    LONGS_EQUAL(want.size(), heard.size());
    for (std::size_t i = 0; i < heard.size(); ++i) {
      LONGS_EQUAL(i == 0 ? k : k - 2, heard[i].index);
      CHECK(want[i] == heard[i].verdict);
      LONGS_EQUAL(static_cast<long>(i) + 1, heard[i].offered_before_step);
    }
    if (send1) CHECK(heard[2].verdict == RxVerdict::kDuplicate);
    DOUBLES_EQUAL(by_hand.last_step_s(), driven.last_step_s(), 0.0);
    LONGS_EQUAL(ref.flags, out.flags);
    CHECK((driven.x() - by_hand.x()).cwiseAbs().maxCoeff() == 0.0);
    CHECK((out.device_force_N - ref.device_force_N).cwiseAbs().maxCoeff() == 0.0);
  }
  CHECK(driven.in_contact() || driven.energy().port_J != 0.0);
  LONGS_EQUAL(0, static_cast<long>(driven.step_clamped_ticks()));
}

TEST(TickDriver, allocates_nothing) {
  const auto& w = PaperWorld::get();
  StationCore core(variable_step_config());
  const int dofs = w.scene.dofs;
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 0.0);
  const Eigen::Vector3d q = w.face_center(test::tetra_dirs()[0]);
  auto one = [&](std::int64_t k) {
    return drive_tick(core, TickDrive{k, 0, q, 0.002}, [&](auto&& offer) {
      for (int n = 0; n < core.neighbor_count(); ++n) offer(ReceivedState{n, k, 0.0, x.data(), v.data(), dofs});
    });
  };
  for (std::int64_t k = 0; k < 10; ++k) one(k);
  test::AllocationCounter counter;
  for (std::int64_t k = 10; k < 200; ++k) one(k);
  LONGS_EQUAL(0, static_cast<long>(counter.allocations()));
}
