#include "tools/devices/device_check.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "drivers/falcon_device.hpp"
#include "drivers/hd_library.hpp"
#include "drivers/phantom_device.hpp"
#include "drivers/spacemouse.hpp"

namespace haptic::tools {

namespace {
enum class Verdict { kPass, kFail, kSkip };
const char* verdict_word(Verdict v) { return v == Verdict::kPass ? "PASS" : v == Verdict::kFail ? "FAIL" : "SKIP"; }

struct Item {
  std::string id;
  Verdict verdict = Verdict::kSkip;
  std::string reason;
};

std::string fmt(const char* f, double a) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, a);
  return buf;
}

// The checklist run: the tick, the results so far, the prompts.
class Check {
 public:
  Check(drivers::HapticDevice& dev, const CheckOptions& o, std::ostream& out) : dev_(dev), o_(o), out_(out) {}

  void record(const std::string& id, Verdict v, const std::string& reason) {
    items_.push_back({id, v, reason});
    out_ << verdict_word(v) << " " << id << ": " << reason << "\n";
    out_.flush();
  }
  bool skipped(const std::string& id) {
    if (o_.skip.count(id) == 0) return false;
    record(id, Verdict::kSkip, "not run (--skip " + id + ")");
    return true;
  }
  // The device entered its safe state during item `id`: it FAILs naming the fault; nothing else runs.
  void fault_in(const std::string& id) {
    faulted_ = true;
    record(id, Verdict::kFail, std::string("the device entered its safe state: ") + drivers::fault_name(dev_.fault()));
    report_fault(dev_, out_);
  }
  bool faulted() const { return faulted_; }

  // One zero-force tick; false when the device faulted.
  bool idle_tick(drivers::DeviceSample& s, bool& fresh) {
    fresh = dev_.read_newest(s);
    if (!fresh && dev_.fault() != drivers::DeviceFault::kNone) return false;
    dev_.command_force(zero_);
    pacer_.wait();
    return true;
  }

  // A prompt for the user; without --yes, zero-force ticks go on until Enter (or end of input).
  bool prompt(const std::string& text) {
    out_ << "\n>>> " << text << (o_.yes ? "\n" : "\n    press Enter to start this item\n");
    out_.flush();
    if (o_.yes) return true;
    drivers::DeviceSample s{};
    bool fresh = false;
    for (;;) {
      pollfd p{STDIN_FILENO, POLLIN, 0};
      if (poll(&p, 1, 0) > 0) {
        char buf[256];
        const ssize_t n = read(STDIN_FILENO, buf, sizeof buf);
        if (n <= 0 || std::find(buf, buf + n, '\n') != buf + n) return true;
      }
      if (!idle_tick(s, fresh)) return false;
    }
  }

  // Zero-force ticks until done(sample) says so or timeout_s passes. kPass = done, kFail = timed out,
  // kSkip = faulted (the caller reports the fault).
  Verdict watch(const std::function<bool(const drivers::DeviceSample&)>& done) {
    const double t0 = pacer_.elapsed_s();
    drivers::DeviceSample s{};
    bool fresh = false;
    while (pacer_.elapsed_s() - t0 < o_.timeout_s) {
      if (!idle_tick(s, fresh)) return Verdict::kSkip;
      if (fresh && done(s)) return Verdict::kPass;
    }
    return Verdict::kFail;
  }

  void open_and_servo_rate();
  void encoders();
  void workspace();
  void buttons();
  void force_and_damping();
  int finish();

 private:
  drivers::HapticDevice& dev_;
  const CheckOptions& o_;
  std::ostream& out_;
  TickPacer pacer_;
  double next_print_ = 0.0;
  std::vector<Item> items_;
  bool faulted_ = false;
  const double zero_[3] = {0, 0, 0};
};

// The first number in a version string ("3.00.66" -> 3, "OpenHaptics 3.4" -> 3), -1 when it has none.
int major_of(const std::string& v) {
  const std::size_t i = v.find_first_of("0123456789");
  return i == std::string::npos ? -1 : std::atoi(v.c_str() + i);
}

void Check::open_and_servo_rate() {
  out_ << "check: " << dev_.capabilities().name << "; idle (zero force) for " << o_.idle_s << " s to measure the servo rate\n";
  const std::uint64_t frames0 = servo_frames_of(dev_), samples0 = dev_.counters().samples_read;
  const double t0 = pacer_.elapsed_s();
  if (run_push(dev_, o_.push, 0.0, o_.idle_s, false, pacer_, next_print_, out_).faulted) return fault_in("open");
  const ServoRate rate = measure_servo_rate(dev_, frames0, samples0, pacer_.elapsed_s() - t0);

  if (!skipped("open")) {
    if (const auto* p = dynamic_cast<const drivers::PhantomDevice*>(&dev_)) {
      const drivers::HdIdentity& id = p->identity();
      const std::string abi = std::string("the driver binds the ") + drivers::hd::kAbiDescription;
      const std::string cal = p->calibrated() ? "calibration OK" : "calibration not confirmed (no servo frame)";
      if (!id.reported)
        record("open", Verdict::kFail, "the HD library (" + p->library_path() + ") has no hdGetString: it reports no model or version; " + abi);
      else if (id.model.empty() || id.hd_version.empty())
        record("open", Verdict::kFail, "hdGetString(HD_DEVICE_MODEL_TYPE) = \"" + id.model + "\", hdGetString(HD_VERSION) = \"" +
                                           id.hd_version + "\": the device did not say what it is; " + abi);
      else if (major_of(id.hd_version) != drivers::hd::kAbiMajorVersion)
        record("open", Verdict::kFail, "HD library version \"" + id.hd_version + "\" is not OpenHaptics " +
                                           std::to_string(drivers::hd::kAbiMajorVersion) + ".x: " + abi + "; model \"" + id.model + "\"");
      else if (!p->calibrated())
        record("open", Verdict::kFail, "model \"" + id.model + "\": " + cal);
      else
        record("open", Verdict::kPass,
               "model \"" + id.model + "\", vendor \"" + id.vendor + "\", serial \"" + id.serial + "\", driver \"" + id.driver_version +
                   "\", firmware " + (id.firmware_version > 0.0 ? fmt("%g", id.firmware_version) : std::string("not reported")) +
                   ", HD library \"" + id.hd_version + "\" (" + p->library_path() + "); " + abi + "; " + cal);
    } else if (dynamic_cast<const drivers::FalconDevice*>(&dev_) != nullptr) {
      record("open", Verdict::kPass, std::string(dev_.capabilities().name) +
                                         ": firmware loaded (every byte echoed) and homed; the Novint protocol as libnifalcon "
                                         "describes it has no model/version query (the USB identity is what haptic-devices lists)");
    } else {
      record("open", Verdict::kPass, std::string(dev_.capabilities().name) + " (this backend has no model/version query)");
    }
  }
  if (!skipped("servo_rate")) {
    const std::string what = describe(rate) + "; threshold " + fmt("%g", o_.min_servo_hz) + " Hz (--min-servo-hz)";
    record("servo_rate", rate.hz >= o_.min_servo_hz ? Verdict::kPass : Verdict::kFail, what);
  }
}

void Check::encoders() {
  if (skipped("encoders")) return;
  const auto& caps = dev_.capabilities();
  if (!prompt("encoders: hold the stylus and move it back and forth along each axis (x, y and z), at least " +
              fmt("%g", o_.move_mm) + " mm each, within " + fmt("%g", o_.timeout_s) + " s"))
    return fault_in("encoders");
  double origin[3] = {0, 0, 0}, moved[3] = {0, 0, 0};
  bool have = false;
  const Verdict v = watch([&](const drivers::DeviceSample& s) {
    if (!have) {
      for (int i = 0; i < 3; ++i) origin[i] = s.position_m[i];
      have = true;
    }
    bool all = true;
    for (int i = 0; i < 3; ++i) {
      moved[i] = std::max(moved[i], std::abs(s.position_m[i] - origin[i]) * 1e3);
      if (caps.sensed_axes[i] && moved[i] < o_.move_mm) all = false;
    }
    return all;
  });
  if (v == Verdict::kSkip) return fault_in("encoders");
  std::string figs;
  for (int i = 0; i < 3; ++i)
    if (caps.sensed_axes[i]) figs += std::string(figs.empty() ? "" : ", ") + "xyz"[i] + " " + fmt("%.1f", moved[i]) + " mm";
  record("encoders", v, "largest move from the start " + figs + (v == Verdict::kPass ? "" : " in " + fmt("%g", o_.timeout_s) + " s") +
                            " (need " + fmt("%g", o_.move_mm) + " mm on every sensed axis, --move-mm)");
}

void Check::workspace() {
  if (skipped("workspace")) return;
  double box[6];
  std::string source;
  if (const auto* p = dynamic_cast<const drivers::PhantomDevice*>(&dev_)) {
    for (int i = 0; i < 6; ++i) box[i] = p->identity().workspace_box_mm[i];
    source = p->identity().has_workspace_box ? "HD_USABLE_WORKSPACE_DIMENSIONS" : "the Touch spec sheet (the library did not answer)";
  } else if (dynamic_cast<const drivers::FalconDevice*>(&dev_) != nullptr) {
    const double b[6] = {-50, -50, -50, 50, 50, 50};
    std::copy(b, b + 6, box);
    source = "the Falcon's 10 cm cube (spec sheet)";
  } else {
    record("workspace", Verdict::kSkip, std::string(dev_.capabilities().name) + " has no nominal workspace to compare with");
    return;
  }
  if (!prompt("workspace: sweep the stylus to both ends of its travel along each axis (nominal " + source + ": " +
              fmt("%.0f", box[3] - box[0]) + " x " + fmt("%.0f", box[4] - box[1]) + " x " + fmt("%.0f", box[5] - box[2]) +
              " mm), within " + fmt("%g", o_.timeout_s) + " s"))
    return fault_in("workspace");
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  auto fraction = [&](int i) { return hi[i] >= lo[i] ? (hi[i] - lo[i]) / (box[i + 3] - box[i]) : 0.0; };
  const Verdict v = watch([&](const drivers::DeviceSample& s) {
    bool all = true;
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], s.position_m[i] * 1e3);
      hi[i] = std::max(hi[i], s.position_m[i] * 1e3);
      if (fraction(i) < o_.workspace_fraction) all = false;
    }
    return all;
  });
  if (v == Verdict::kSkip) return fault_in("workspace");
  std::string figs;
  for (int i = 0; i < 3; ++i) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "%s%c %.0f of %.0f mm (%.0f%%)", i ? ", " : "", "xyz"[i], hi[i] >= lo[i] ? hi[i] - lo[i] : 0.0,
                  box[i + 3] - box[i], 100.0 * fraction(i));
    figs += buf;
  }
  record("workspace", v, "extent reached " + figs + " (need " + fmt("%g", 100.0 * o_.workspace_fraction) +
                             "% of the nominal " + source + " on each axis, --workspace-fraction)");
}

void Check::buttons() {
  if (skipped("buttons")) return;
  int n = o_.buttons;
  if (n < 0) {
    if (dynamic_cast<const drivers::PhantomDevice*>(&dev_) != nullptr) n = 2;       // HD_DEVICE_BUTTON_1, _2 on a Touch stylus
    else if (dynamic_cast<const drivers::FalconDevice*>(&dev_) != nullptr) n = 4;   // status bits 0-3 (libnifalcon)
    else n = 2;
  }
  if (n == 0) {
    record("buttons", Verdict::kSkip, "--buttons 0");
    return;
  }
  if (!prompt("buttons: press and release each of the " + std::to_string(n) + " buttons in turn, within " + fmt("%g", o_.timeout_s) + " s"))
    return fault_in("buttons");
  const std::uint32_t want = (n >= 32 ? 0xFFFFFFFFu : (1u << n) - 1u);
  std::uint32_t pressed = 0, released = 0;
  const Verdict v = watch([&](const drivers::DeviceSample& s) {
    pressed |= s.buttons & want;
    released |= pressed & ~s.buttons;  // seen pressed, now clear
    return released == want;
  });
  if (v == Verdict::kSkip) return fault_in("buttons");
  std::string figs;
  for (int b = 0; b < n; ++b)
    figs += std::string(b ? ", " : "") + "button " + std::to_string(b + 1) +
            ((released >> b) & 1u ? " pressed and released" : (pressed >> b) & 1u ? " pressed, never released" : " never pressed");
  record("buttons", v, figs);
}

void Check::force_and_damping() {
  const bool skip_force = o_.skip.count("force") != 0, skip_bd = o_.skip.count("b_d") != 0;
  const char axis = "xyz"[o_.push.axis];
  if (!dev_.capabilities().actuated_axes[o_.push.axis]) {
    const std::string why = std::string("axis ") + axis + " is not actuated on this device (no force feedback)";
    if (!skipped("force")) record("force", Verdict::kSkip, why);
    if (!skipped("b_d")) record("b_d", Verdict::kSkip, why);
    return;
  }
  if (skip_force && skip_bd) {
    skipped("force");
    skipped("b_d");
    return;
  }
  const double F1 = o_.push.forces_N[0];
  if (!prompt(std::string("force: LET GO of the stylus (do not hold it): it will be pushed gently, ") + fmt("%g", F1) + " N along +" +
              axis + ", then back" + (o_.push.forces_N.size() > 1 ? ", then " + fmt("%g", o_.push.forces_N[1]) + " N" : std::string())))
    return fault_in(skip_force ? "b_d" : "force");
  const drivers::DeviceCounters c0 = dev_.counters();
  const LevelResult L1 = run_level(dev_, o_.push, F1, pacer_, next_print_, out_);
  if (L1.faulted) return fault_in(skip_force ? "b_d" : "force");
  const drivers::DeviceCounters c1 = dev_.counters();
  if (!skipped("force")) {
    const double min_m = o_.min_push_mm * 1e-3;
    // How each push went: "" = with the force by min_push_mm; else against it (a force in the wrong
    // direction) or hardly at all.
    auto how = [&](const PushResult& r, double sign, const char* name) {
      const double along = sign * r.travel_m;
      if (along >= min_m && sign * r.mean_velocity > 0.0) return std::string();
      return std::string(name) + (along <= -min_m ? " moved the stylus AGAINST the force (wrong direction)"
                                                  : " moved the stylus less than " + fmt("%g", o_.min_push_mm) + " mm its way (held, blocked, no force?)");
    };
    const std::string p = how(L1.plus, 1.0, "+F"), m = how(L1.minus, -1.0, "-F");
    const bool plus_ok = p.empty(), minus_ok = m.empty();
    const std::uint64_t clamps = c1.force_clamps - c0.force_clamps, power = c1.power_limits - c0.power_limits;
    const double ratio = L1.minus.mean_speed > 0.0 ? L1.plus.mean_speed / L1.minus.mean_speed : std::nan("");
    const bool symmetric = std::isfinite(ratio) && ratio <= o_.max_asymmetry && ratio >= 1.0 / o_.max_asymmetry;
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "+%g N along %c: travel %+.1f mm, mean velocity %+.1f mm/s; -%g N: travel %+.1f mm, mean velocity %+.1f mm/s; "
                  "|v+|/|v-| = %.2f (allowed %.2g..%.2g, --max-asymmetry); force sent unreduced: %s",
                  F1, axis, L1.plus.travel_m * 1e3, L1.plus.mean_velocity * 1e3, F1, L1.minus.travel_m * 1e3, L1.minus.mean_velocity * 1e3,
                  ratio, 1.0 / o_.max_asymmetry, o_.max_asymmetry,
                  clamps + power == 0 ? "yes" : ("NO (" + std::to_string(clamps) + " force clamps, " + std::to_string(power) +
                                                 " power limits: lower --force-N)").c_str());
    std::string why = buf;
    if (!plus_ok || !minus_ok) why = p + (p.empty() || m.empty() ? "" : "; ") + m + " (--min-push-mm): " + why;
    else if (!symmetric) why = "the response is asymmetric: " + why;
    else if (clamps + power != 0) why = "the driver's limits reduced the test force: " + why;
    record("force", plus_ok && minus_ok && symmetric && clamps + power == 0 ? Verdict::kPass : Verdict::kFail, why);
  }
  if (skipped("b_d")) return;
  if (o_.push.forces_N.size() < 2) {
    record("b_d", Verdict::kSkip, "one --force-N level given; b_d = (F2 - F1) / (v2 - v1) needs two");
    return;
  }
  const double F2 = o_.push.forces_N[1];
  const LevelResult L2 = run_level(dev_, o_.push, F2, pacer_, next_print_, out_);
  if (L2.faulted) return fault_in("b_d");
  char buf[300];
  if (const auto b = damping_from_levels(F1, L1.mean_speed, F2, L2.mean_speed)) {
    std::snprintf(buf, sizeof buf, "b_d = (%g - %g) N / (%.2f - %.2f) mm/s = %.4g N s/m (device.damping_Ns_per_m = %.4g)", F2, F1,
                  L2.mean_speed * 1e3, L1.mean_speed * 1e3, *b, *b);
    record("b_d", Verdict::kPass, buf);
  } else {
    std::snprintf(buf, sizeof buf, "not determined: mean |speed| %.2f mm/s at %g N, %.2f mm/s at %g N (the speed did not grow with the force)",
                  L1.mean_speed * 1e3, F1, L2.mean_speed * 1e3, F2);
    record("b_d", Verdict::kFail, buf);
  }
}

int Check::finish() {
  dev_.command_force(zero_);
  int pass = 0, fail = 0, skip = 0;
  std::string failed;
  for (const Item& i : items_) {
    if (i.verdict == Verdict::kPass) ++pass;
    if (i.verdict == Verdict::kSkip) ++skip;
    if (i.verdict == Verdict::kFail) {
      ++fail;
      failed += (failed.empty() ? "" : ", ") + i.id;
    }
  }
  const int not_run = static_cast<int>(std::size(kCheckItems)) - static_cast<int>(items_.size());
  const int rc = faulted_ ? kExitDeviceFault : fail > 0 ? kExitCheckFailed : skip > 0 || not_run > 0 ? kExitCheckSkipped : kExitOk;
  out_ << "\nsummary: " << pass << " PASS, " << fail << " FAIL" << (failed.empty() ? "" : " (" + failed + ")") << ", " << skip << " SKIP";
  if (not_run > 0) out_ << ", " << not_run << " not run (the device entered its safe state)";
  out_ << "; exit " << rc << "\n";
  return rc;
}
}  // namespace

int run_check(drivers::HapticDevice& dev, const CheckOptions& o, std::ostream& out) {
  Check c(dev, o, out);
  c.open_and_servo_rate();
  if (!c.faulted()) c.encoders();
  if (!c.faulted()) c.workspace();
  if (!c.faulted()) c.buttons();
  if (!c.faulted()) c.force_and_damping();
  return c.finish();
}

}  // namespace haptic::tools
