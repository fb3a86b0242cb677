#include "firmware/station/device_coupling.hpp"

#include "rt/station.hpp"
#include "platform/toml_config.hpp"

#include <cmath>
#include <stdexcept>

namespace haptic::firmware {

using platform::config::number_text;

DeviceCoupling device_coupling(const StationFile& f, const ScenarioSpec& spec, const drivers::DeviceCapabilities& caps) {
  const DeviceSection& d = f.device;
  DeviceCoupling c;
  c.gains = spec.vp.coupling;
  if (d.coupling_stiffness_N_per_m >= 0) c.gains.K_vc_N_per_m = d.coupling_stiffness_N_per_m;
  if (d.coupling_damping_Ns_per_m >= 0) c.gains.B_vc_Ns_per_m = d.coupling_damping_Ns_per_m;
  if (d.proxy_damping_Ns_per_m >= 0) c.gains.b_v_Ns_per_m = d.proxy_damping_Ns_per_m;
  c.force_feedback = caps.actuated_axes[0] || caps.actuated_axes[1] || caps.actuated_axes[2];
  c.force_limit_N = std::fmin(caps.max_force_N, d.max_force_N);
  c.map_scale = d.map_scale;
  if (d.damping_Ns_per_m >= 0) {
    c.b_d_Ns_per_m = d.damping_Ns_per_m;
    c.b_d_source = "device.damping_Ns_per_m";
  } else {
    c.b_d_Ns_per_m = caps.min_damping_Ns_per_m;
    c.b_d_source = std::string("published by ") + caps.name;
    if (c.force_feedback && !(c.b_d_Ns_per_m > 0))
      throw std::invalid_argument("device.damping_Ns_per_m: required for device.kind = \"" + d.kind + "\" (" + caps.name +
                                  "): the device publishes no damping b_d for eq. (26), and it is never assumed 0; measure it on "
                                  "the bench (firmware/deploy/README.md, \"Measuring b_d\") and state it in N s/m");
  }
  return c;
}

double eq26_largest_step_margin_s(const DeviceCoupling& c, double T, double max_margin_s) {
  const auto holds = [&](double m) {
    try {
      check_device_coupling(c, T - m, T + m);
      return true;
    } catch (const std::invalid_argument&) {
      return false;
    }
  };
  if (max_margin_s <= 0 || !holds(0.0)) return 0.0;
  if (holds(max_margin_s)) return max_margin_s;
  double lo = 0.0, hi = max_margin_s;  // holds(lo), !holds(hi): eq. (26) is monotone in the margin
  for (int i = 0; i < 40; ++i) (holds(0.5 * (lo + hi)) ? lo : hi) = 0.5 * (lo + hi);
  return lo;
}

void check_device_coupling(const DeviceCoupling& c, double t_min_s, double t_max_s) {
  if (!c.force_feedback) return;  // nothing goes out to the hand: eq. (26) concerns the device's port
  const double b_d = c.object_b_d_Ns_per_m();
  const double T = t_max_s, ratio = t_max_s / t_min_s;  // the worst step the core will take
  try {
    rt::check_eq26(c.gains, b_d, T, ratio);
  } catch (const std::invalid_argument&) {  // violated: say it with the keys as the station file writes them
    const double k_max = rt::max_K_vc_eq26(c.gains, b_d, T, ratio);
    const std::string steps = t_min_s == t_max_s ? "T = " + number_text(T) + " s"
                                                 : "T_k up to station.period_max_s = " + number_text(t_max_s) + " s, T_k/T_k-1 up to " +
                                                       number_text(ratio) + " with station.period_min_s = " + number_text(t_min_s) + " s";
    const std::string scaled = c.map_scale == 1.0 ? "" : ", i.e. " + number_text(b_d) + " N s/m in the object frame with device.map_scale = " + number_text(c.map_scale);
    std::string m = "eq. (26) violated: device damping b_d = " + number_text(c.b_d_Ns_per_m) + " N s/m (" + c.b_d_source + scaled +
                    ") with K_vc = device.coupling_stiffness_N_per_m = " + number_text(c.gains.K_vc_N_per_m) +
                    " N/m, B_vc = device.coupling_damping_Ns_per_m = " + number_text(c.gains.B_vc_Ns_per_m) +
                    " N s/m, b_v = device.proxy_damping_Ns_per_m = " + number_text(c.gains.b_v_Ns_per_m) + " N s/m, " + steps +
                    " (needs b_d >= B_vc (T_k/T_k-1 + 1) + K_vc T_k and b_v >= B_vc/2 (T_k/T_k-1 - 1) + K_vc T_k/2). ";
    if (k_max > 0)
      m += "The largest K_vc that satisfies eq. (26) with these is device.coupling_stiffness_N_per_m = " + number_text(std::floor(k_max * 1000) / 1000) + " N/m";
    else
      m += "No K_vc > 0 satisfies eq. (26) with this B_vc: lower device.coupling_damping_Ns_per_m";
    throw std::invalid_argument(m);
  }
}

drivers::WorkspaceMapConfig workspace_map_config(const StationFile& f, const drivers::DeviceCapabilities& caps) {
  drivers::WorkspaceMapConfig m;
  for (int i = 0; i < 3; ++i) {
    m.offset_m[i] = f.device.map_offset_m[i];
    m.rotation_deg[i] = f.device.map_rotation_deg[i];
  }
  m.scale = f.device.map_scale;
  m.workspace_radius_m = caps.workspace_radius_m;
  drivers::WorkspaceMap check(m);  // throws on a bad scale
  (void)check;
  return m;
}

std::int64_t ramp_in_ticks(const StationFile& f, double T) {
  const double s = f.device.ramp_in_s >= 0 ? f.device.ramp_in_s : (f.device.kind == "simulated" ? 0.0 : 1.0);
  return std::llround(s / T);
}

Eigen::Vector3d initial_proxy_position(const Eigen::Vector3d& q, const rt::Scene& scene, const std::vector<int>& nodes, bool* projected) {
  const rt::ContactFace face = rt::contact_face(scene.x_d, nodes);
  Eigen::Vector3d n = rt::outward_normal_sign(face, scene) * face.normal;
  n.normalize();
  const double depth = n.dot(q - face.centroid);  // < 0: inside the object
  if (projected != nullptr) *projected = depth < 0.0;
  return depth < 0.0 ? Eigen::Vector3d(q - depth * n) : q;
}

}  // namespace haptic::firmware
