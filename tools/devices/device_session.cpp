#include "tools/devices/device_session.hpp"

#include <Eigen/Core>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>
#include <thread>

#include "drivers/falcon_device.hpp"
#include "drivers/phantom_device.hpp"
#include "drivers/workspace_map.hpp"

namespace haptic::tools {

namespace {
using Clock = std::chrono::steady_clock;
constexpr auto kTick = std::chrono::milliseconds(2);  // the station's default period

// Calibration status (Touch: hdCheckCalibration in the servo loop; a Falcon is homed at start).
void report_calibration(const drivers::HapticDevice& dev, std::ostream& out) {
  if (const auto* p = dynamic_cast<const drivers::PhantomDevice*>(&dev))
    out << "calibration: " << (p->calibrated() ? "OK (hdCheckCalibration = HD_CALIBRATION_OK)" : "not confirmed yet (no servo frame)") << "\n";
  else if (dynamic_cast<const drivers::FalconDevice*>(&dev) != nullptr)
    out << "calibration: homed at start (all three axes reported homed)\n";
}

std::string mm3(const double p[3]) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.2f, %.2f, %.2f) mm", p[0] * 1e3, p[1] * 1e3, p[2] * 1e3);
  return buf;
}
}  // namespace

TickPacer::TickPacer() : t0_(Clock::now()), next_(t0_) {}
double TickPacer::elapsed_s() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }
void TickPacer::wait() {
  next_ += kTick;
  const auto now = Clock::now();
  if (next_ < now) next_ = now;
  std::this_thread::sleep_until(next_);
}

std::uint64_t servo_frames_of(const drivers::HapticDevice& dev) {
  if (const auto* p = dynamic_cast<const drivers::PhantomDevice*>(&dev)) return p->servo_frames();
  if (const auto* f = dynamic_cast<const drivers::FalconDevice*>(&dev)) return f->servo_frames();
  return 0;
}

int report_fault(const drivers::HapticDevice& dev, std::ostream& out) {
  out << "device fault: " << drivers::fault_name(dev.fault()) << " (detail " << dev.fault_detail()
      << "): the device is in its safe state (zero force)\n";
  if (dev.fault() == drivers::DeviceFault::kStaleSample)
    out << "the device's servo loop delivered no new sample for more than --max-stale-reads ticks of 2 ms (as device.max_stale_reads, "
           "default 5): a busy or non-RT machine can starve it; stop other load, or try a larger --max-stale-reads to see if it recovers\n";
  if (dev.fault() == drivers::DeviceFault::kCalibrationNeeded) {
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", static_cast<unsigned>(dev.fault_detail()));
    out << "calibration: NOT OK (hdCheckCalibration = " << code
        << (dev.fault_detail() == 0x5001   ? ", HD_CALIBRATION_NEEDS_UPDATE: put the stylus in its inkwell (or run the vendor's Touch_Diagnostic), then try again"
            : dev.fault_detail() == 0x5002 ? ", HD_CALIBRATION_NEEDS_MANUAL_INPUT: calibrate with the vendor's Touch_Diagnostic, then try again"
                                           : ": calibrate with the vendor's tools, then try again")
        << "); a station with this device stays in its safe state (exit 5, device_fault \"calibration needed\")\n";
  }
  return kExitDeviceFault;
}

PushResult run_push(drivers::HapticDevice& dev, const DiagOptions& opt, double force_N, double seconds, bool measure,
                    TickPacer& pacer, double& next_print, std::ostream& out) {
  PushResult r;
  const double start = pacer.elapsed_s();
  double speed_sum = 0.0, velocity_sum = 0.0, origin = 0.0, last = 0.0;
  bool have_origin = false, stopped = false;
  drivers::DeviceSample s{};
  for (double t = pacer.elapsed_s(); t - start < seconds; t = pacer.elapsed_s()) {
    const bool ok = dev.read_newest(s);
    if (!ok && dev.fault() != drivers::DeviceFault::kNone) {
      r.faulted = true;
      return r;
    }
    if (ok && !have_origin) {
      origin = s.position_m[opt.axis];
      have_origin = true;
    }
    if (ok) last = s.position_m[opt.axis];
    if (ok && std::abs(s.position_m[opt.axis] - origin) > opt.max_travel_mm * 1e-3) stopped = r.cut_short = true;
    double f[3] = {0, 0, 0};
    if (!stopped) f[opt.axis] = force_N;
    dev.command_force(f);
    if (ok && measure && !stopped && t - start >= 0.5 * seconds) {
      speed_sum += std::abs(s.velocity_m_per_s[opt.axis]);
      velocity_sum += s.velocity_m_per_s[opt.axis];
      ++r.samples;
    }
    if (ok && t >= next_print) {
      out << "  t " << t << " s  position " << mm3(s.position_m) << "  buttons " << s.buttons;
      if (f[opt.axis] != 0.0) out << "  force " << f[opt.axis] << " N along " << "xyz"[opt.axis];
      out << "\n";
      next_print = t + 1.0 / opt.print_hz;
    }
    pacer.wait();
  }
  r.mean_speed = r.samples > 0 ? speed_sum / r.samples : 0.0;
  r.mean_velocity = r.samples > 0 ? velocity_sum / r.samples : 0.0;
  r.travel_m = last - origin;
  return r;
}

LevelResult run_level(drivers::HapticDevice& dev, const DiagOptions& o, double F, TickPacer& pacer, double& next_print,
                      std::ostream& out) {
  LevelResult L;
  L.force_N = F;
  for (const double sign : {1.0, -1.0}) {
    PushResult& r = sign > 0 ? L.plus : L.minus;
    r = run_push(dev, o, sign * F, o.push_s, true, pacer, next_print, out);
    if (r.faulted) {
      L.faulted = true;
      return L;
    }
    if (r.cut_short) out << "  push " << sign * F << " N stopped: travel beyond " << o.max_travel_mm << " mm (--max-travel-mm)\n";
  }
  const int n = L.plus.samples + L.minus.samples;
  L.mean_speed = n > 0 ? (L.plus.mean_speed * L.plus.samples + L.minus.mean_speed * L.minus.samples) / n : std::nan("");
  const char axis = "xyz"[o.axis];
  char line[200];
  if (n > 0)
    std::snprintf(line, sizeof line, "test force %g N along %c: mean |speed| over the second half of each push %.2f mm/s (%d samples)\n",
                  F, axis, L.mean_speed * 1e3, n);
  else
    std::snprintf(line, sizeof line, "test force %g N along %c: mean |speed| n/a (no samples in the second half of a push)\n", F, axis);
  out << line;
  return L;
}

std::optional<double> damping_from_levels(double F1, double v1, double F2, double v2) {
  const double dv = v2 - v1;
  if (!(std::isfinite(dv) && dv > 0.0)) return std::nullopt;
  return (F2 - F1) / dv;
}

ServoRate measure_servo_rate(const drivers::HapticDevice& dev, std::uint64_t frames0, std::uint64_t samples0, double elapsed) {
  ServoRate r;
  r.seconds = elapsed;
  const std::uint64_t frames = servo_frames_of(dev) - frames0;
  r.own_frames = frames > 0;
  r.count = r.own_frames ? frames : dev.counters().samples_read - samples0;
  r.hz = elapsed > 0.0 ? static_cast<double>(r.count) / elapsed : 0.0;
  return r;
}

std::string describe(const ServoRate& r) {
  char buf[200];
  if (r.own_frames)
    std::snprintf(buf, sizeof buf, "%.0f Hz (%llu servo frames of the device's own loop in %.3f s)", r.hz,
                  static_cast<unsigned long long>(r.count), r.seconds);
  else
    std::snprintf(buf, sizeof buf, "%.0f Hz (%llu fresh samples read by the 500 Hz tick in %.3f s; the backend counts no frames)",
                  r.hz, static_cast<unsigned long long>(r.count), r.seconds);
  return buf;
}

int run_diagnostics(drivers::HapticDevice& dev, const DiagOptions& o, std::ostream& out) {
  const char axis = "xyz"[o.axis];
  out << "diagnostics: " << dev.capabilities().name << "; keep the stylus free (do not hold it) during the pushes\n";
  if (!dev.capabilities().actuated_axes[o.axis])
    out << "NOTE: axis " << axis << " is not actuated on this device (no force feedback): the test force is clamped to zero\n";
  TickPacer pacer;
  double next_print = 0.0;
  const std::uint64_t frames0 = servo_frames_of(dev), samples0 = dev.counters().samples_read;
  if (run_push(dev, o, 0.0, o.settle_s, false, pacer, next_print, out).faulted) return report_fault(dev, out);
  report_calibration(dev, out);
  std::vector<double> speeds;
  for (const double F : o.forces_N) {
    const LevelResult L = run_level(dev, o, F, pacer, next_print, out);
    if (L.faulted) return report_fault(dev, out);
    speeds.push_back(L.mean_speed);
  }
  if (run_push(dev, o, 0.0, o.settle_s, false, pacer, next_print, out).faulted) return report_fault(dev, out);
  const double zero[3] = {0, 0, 0};
  dev.command_force(zero);
  out << "servo rate: " << describe(measure_servo_rate(dev, frames0, samples0, pacer.elapsed_s())) << "\n";
  if (speeds.size() == 2) {
    if (const auto b = damping_from_levels(o.forces_N[0], speeds[0], o.forces_N[1], speeds[1]))
      out << "b_d = (F2 - F1) / (v2 - v1) = " << *b << " N s/m (device.damping_Ns_per_m; "
          << "repeat a few times and keep the smallest)\n";
    else
      out << "b_d: not determined (the speed did not grow with the force; is the stylus held or blocked?)\n";
  }
  return dev.fault() == drivers::DeviceFault::kNone ? kExitOk : report_fault(dev, out);
}

namespace {
void print_map_keys(const MapOptions& o, const Eigen::Vector3d& held, std::ostream& out) {
  drivers::WorkspaceMapConfig c;
  for (int i = 0; i < 3; ++i) c.rotation_deg[i] = o.rotation_deg[i];
  c.scale = o.scale;
  const double p[3] = {held.x(), held.y(), held.z()};
  drivers::solve_offset(c, p, Eigen::Vector3d(o.object_centre_m[0], o.object_centre_m[1], o.object_centre_m[2]));
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "held still at %s (device frame); put these in the station file's [device] table:\n"
                "map_offset_m = [%.6f, %.6f, %.6f]\nmap_rotation_deg = [%g, %g, %g]\nmap_scale = %g\n",
                mm3(p).c_str(), c.offset_m[0], c.offset_m[1], c.offset_m[2], c.rotation_deg[0], c.rotation_deg[1],
                c.rotation_deg[2], c.scale);
  out << buf;
}
}  // namespace

int run_mapping(drivers::HapticDevice& dev, const MapOptions& o, std::ostream& out) {
  out << "hold the stylus at the object's centre and keep it still for " << o.still_s << " s (within " << o.still_mm
      << " mm)\n";
  TickPacer pacer;
  Eigen::Vector3d anchor = Eigen::Vector3d::Zero();
  double still_since = -1.0, next_print = 0.0;
  drivers::DeviceSample s{};
  const double zero[3] = {0, 0, 0};
  for (double t = 0.0; t < o.timeout_s; t = pacer.elapsed_s()) {
    const bool ok = dev.read_newest(s);
    if (!ok && dev.fault() != drivers::DeviceFault::kNone) return report_fault(dev, out);
    dev.command_force(zero);
    if (ok) {
      const Eigen::Vector3d p(s.position_m[0], s.position_m[1], s.position_m[2]);
      if (still_since < 0.0 || (p - anchor).norm() > o.still_mm * 1e-3) {
        anchor = p;
        still_since = t;
      } else if (t - still_since >= o.still_s) {
        print_map_keys(o, anchor, out);
        return kExitOk;
      }
      if (t >= next_print) {
        out << "  t " << t << " s  position " << mm3(s.position_m) << "\n";
        next_print = t + 1.0;
      }
    }
    pacer.wait();
  }
  out << "timed out after " << o.timeout_s << " s: the stylus was never still for " << o.still_s << " s within "
      << o.still_mm << " mm (--timeout-s, --still-s, --still-mm)\n";
  return kExitNotStill;
}

}  // namespace haptic::tools
