// Device-read-to-force-out latency (Google Benchmark). One iteration is what a station tick
// does with its device: read_newest() -> a force from the sample (a spring, standing in for the
// rt/ solve, which is benchmarked elsewhere) -> command_force() -> the device side takes the
// force and writes it out. Backends:
//   Interface:       the mailboxes + limits alone (test subclass, no plant, no library)
//   SimulatedDevice: owner-stepped simulated device + hand (rt/user_model, 20 substeps)
//   FakeHdServo:     PhantomDevice through dlopen'ed fake libHD.so; the device side is one HD
//                    servo frame (begin, get position/velocity/buttons, set force, end, error)
//   FakeHdThreaded:  the fake library's own 1 kHz scheduler thread and a 2 ms station loop on
//                    another thread; reports the time from the servo frame that read the
//                    position to the servo frame that wrote the force computed from it.
//   FalconMath:      the Falcon driver's own per-exchange computation (our open servo path): force
//                    -> motor commands at the current position (Jacobian by IK), encode, decode a
//                    status packet, encoders -> angles -> forward kinematics
//   FalconUmockdev:  FalconDevice through libusb against the umockdev stand-in (tests/drivers/
//                    falcon_standin.hpp), owner-stepped: one service() = one USB exchange (two bulk
//                    transfers). Dominated by umockdev's socket round trips to the emulation: it is
//                    the cost of the real libusb code path here, NOT a Falcon's USB latency.
//                    Needs LD_PRELOAD=libumockdev-preload.so.0, else it reports an error and skips.
#include "drivers/device.hpp"
#include "drivers/falcon_device.hpp"
#include "drivers/falcon_protocol.hpp"
#include "drivers/phantom_device.hpp"
#include "drivers/simulated_device.hpp"
#ifdef HAPTIC_BENCH_UMOCKDEV
#include "tests/drivers/falcon_standin.hpp"
#endif

#include <benchmark/benchmark.h>
#include <dlfcn.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

using namespace haptic::drivers;

namespace {
constexpr double kT = 0.002;
constexpr double kStiffness = 200.0;  // N/m, the virtual coupling's K_vc of the reference scene

class LoopbackDevice final : public HapticDevice {
 public:
  LoopbackDevice() : HapticDevice(caps(), SafetyLimits{}) {}
  static DeviceCapabilities caps() {
    DeviceCapabilities c{};
    c.max_force_N = 3.3;
    c.max_stiffness_N_per_m = 1000.0;
    c.servo_rate_hz = 1000.0;
    c.workspace_radius_m = 0.1;
    for (int i = 0; i < 3; ++i) c.sensed_axes[i] = c.actuated_axes[i] = true;
    c.name = "loopback";
    return c;
  }
  void start() override { arm(); }
  void stop() override { disarm(); }
  void device_side(double t) {
    DeviceSample s{};
    s.position_m[0] = 0.01;
    s.time_s = t;
    s.sequence = ++seq_;
    publish_sample(s);
    take_force(out_);
  }
  double out_[3] = {0, 0, 0};
  std::uint64_t seq_ = 0;
};

inline void spring(const DeviceSample& s, double f[3]) {
  for (int i = 0; i < 3; ++i) f[i] = -kStiffness * s.position_m[i];
}

void BM_Interface_ReadToForceOut(benchmark::State& state) {
  LoopbackDevice d;
  d.start();
  DeviceSample s{};
  double f[3];
  double t = 0.0;
  d.device_side(t);
  for (auto _ : state) {
    d.read_newest(s);
    spring(s, f);
    d.command_force(f);
    d.device_side(t += kT);
    benchmark::DoNotOptimize(d.out_);
  }
  if (d.fault() != DeviceFault::kNone) state.SkipWithError("device faulted");
}
BENCHMARK(BM_Interface_ReadToForceOut);

void BM_SimulatedDevice_ReadToForceOut(benchmark::State& state) {
  SimulatedDeviceConfig c;
  c.script = haptic::rt::GoalScript(haptic::rt::Vec3(0.01, 0.0, 0.0));
  SimulatedDevice d(c);
  d.start();
  DeviceSample s{};
  double f[3];
  std::uint64_t k = 0;
  for (auto _ : state) {
    d.read_newest(s);
    spring(s, f);
    d.command_force(f);
    d.service(static_cast<double>(k++) * kT, kT);
  }
  if (d.fault() != DeviceFault::kNone) state.SkipWithError("device faulted");
}
BENCHMARK(BM_SimulatedDevice_ReadToForceOut);

struct FakeHd {
  void* h = nullptr;
  int (*run_frames)(int) = nullptr;
  void (*reset)() = nullptr;
  void (*set_manual)(int) = nullptr;
  void (*set_state)(const double*, const double*, int) = nullptr;
  FakeHd() {
    h = dlopen(HAPTIC_FAKE_HD_PATH, RTLD_NOW | RTLD_LOCAL);
    if (h == nullptr) return;
    reset = reinterpret_cast<void (*)()>(dlsym(h, "fakehd_reset"));
    run_frames = reinterpret_cast<int (*)(int)>(dlsym(h, "fakehd_run_frames"));
    set_manual = reinterpret_cast<void (*)(int)>(dlsym(h, "fakehd_set_manual"));
    set_state = reinterpret_cast<void (*)(const double*, const double*, int)>(dlsym(h, "fakehd_set_state"));
    reset();
  }
  ~FakeHd() {
    if (h != nullptr) {
      reset();
      dlclose(h);
    }
  }
};

void BM_FakeHdServo_ReadToForceOut(benchmark::State& state) {
  FakeHd fake;
  if (fake.h == nullptr) {
    state.SkipWithError("fake libHD.so not found");
    return;
  }
  const double p[3] = {10.0, 0.0, 0.0}, v[3] = {0.0, 0.0, 0.0};
  fake.set_state(p, v, 0);
  PhantomConfig pc;
  pc.hd_library_path = HAPTIC_FAKE_HD_PATH;
  PhantomDevice d(pc);
  d.start();
  fake.run_frames(1);
  DeviceSample s{};
  double f[3];
  for (auto _ : state) {
    d.read_newest(s);
    spring(s, f);
    d.command_force(f);
    fake.run_frames(1);
  }
  if (d.fault() != DeviceFault::kNone) state.SkipWithError("device faulted");
  d.stop();
}
BENCHMARK(BM_FakeHdServo_ReadToForceOut);

double now_s() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Threaded: the servo thread is the fake library's own 1 kHz scheduler, the station loop runs at
// 2 ms on this thread (absolute deadlines). Per tick: latency = (time the servo frame took the
// force computed from the newest sample) - (time that sample was read from the device), i.e.
// the age of the sample when the tick reads it plus the wait for the next servo frame. The
// wait is observed on the station side through counters().forces_out (spinning, benchmark only).
void BM_FakeHdThreaded_SampleToForceOut(benchmark::State& state) {
  FakeHd fake;
  if (fake.h == nullptr) {
    state.SkipWithError("fake libHD.so not found");
    return;
  }
  fake.set_manual(0);
  PhantomConfig pc;
  pc.hd_library_path = HAPTIC_FAKE_HD_PATH;
  SafetyLimits lenient;  // a loaded 2-core machine must not trip staleness during the benchmark
  lenient.max_stale_reads = 1000;
  PhantomDevice d(pc, lenient);
  d.start();
  std::vector<double> latency_us;
  latency_us.reserve(4096);
  DeviceSample s{};
  double f[3];
  auto next = std::chrono::steady_clock::now();
  for (auto _ : state) {
    next += std::chrono::microseconds(2000);
    std::this_thread::sleep_until(next);
    if (!d.read_newest(s)) continue;
    spring(s, f);
    const std::uint64_t out0 = d.counters().forces_out;
    d.command_force(f);
    while (d.counters().forces_out == out0) std::this_thread::yield();  // next servo frame took it
    latency_us.push_back((now_s() - s.time_s) * 1e6);
  }
  d.stop();
  if (latency_us.empty()) {
    state.SkipWithError("no samples");
    return;
  }
  std::sort(latency_us.begin(), latency_us.end());
  const auto pct = [&](double q) { return latency_us[static_cast<std::size_t>(q * (latency_us.size() - 1))]; };
  state.counters["p50_us"] = pct(0.5);
  state.counters["p99_us"] = pct(0.99);
  state.counters["max_us"] = latency_us.back();
}
BENCHMARK(BM_FakeHdThreaded_SampleToForceOut)->Iterations(2000)->UseRealTime()->Unit(benchmark::kMicrosecond);
void BM_FalconMath_ForceToMotorAndBack(benchmark::State& state) {
  namespace fa = haptic::drivers::falcon;
  Eigen::Vector3d p(0.01, -0.02, 0.12), q;
  const Eigen::Vector3d force(0.5, -0.2, 1.0);
  Eigen::Vector3d theta;
  fa::inverse_kinematics(p, theta);
  const std::int16_t enc[3] = {static_cast<std::int16_t>(std::lround((theta[0] - fa::encoder_to_theta(0)) / (fa::encoder_to_theta(1) - fa::encoder_to_theta(0)))),
                               static_cast<std::int16_t>(std::lround((theta[1] - fa::encoder_to_theta(0)) / (fa::encoder_to_theta(1) - fa::encoder_to_theta(0)))),
                               static_cast<std::int16_t>(std::lround((theta[2] - fa::encoder_to_theta(0)) / (fa::encoder_to_theta(1) - fa::encoder_to_theta(0))))};
  unsigned char status[fa::kPacketSize], cmd[fa::kPacketSize];
  fa::encode_command(enc, 0, status);  // same nibble layout as a status packet for the encoder part
  for (auto _ : state) {
    std::int16_t motor[3];
    fa::force_to_motor(p, force, motor);
    fa::encode_command(motor, fa::kLedBlue, cmd);
    fa::Status st{};
    fa::decode_status(status, st);
    const Eigen::Vector3d th(fa::encoder_to_theta(st.encoder[0]), fa::encoder_to_theta(st.encoder[1]), fa::encoder_to_theta(st.encoder[2]));
    fa::forward_kinematics(th, p, q);
    benchmark::DoNotOptimize(cmd);
    benchmark::DoNotOptimize(q);
  }
}
BENCHMARK(BM_FalconMath_ForceToMotorAndBack);

#ifdef HAPTIC_BENCH_UMOCKDEV
void BM_FalconUmockdev_ReadToForceOut(benchmark::State& state) {
  try {
    haptic::testing::FalconBed bed;
    FalconConfig c;
    c.firmware_path = bed.firmware_path;
    c.own_thread = false;
    SafetyLimits lenient;
    lenient.max_stale_reads = 100000;
    FalconDevice d(c, lenient);
    d.start();
    d.service();
    DeviceSample s{};
    double f[3];
    for (auto _ : state) {
      d.read_newest(s);
      spring(s, f);
      d.command_force(f);
      if (!d.service()) break;
    }
    if (d.fault() != DeviceFault::kNone) state.SkipWithError("device faulted");
    d.stop();
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}
BENCHMARK(BM_FalconUmockdev_ReadToForceOut)->Unit(benchmark::kMicrosecond);
#endif
}  // namespace

BENCHMARK_MAIN();
