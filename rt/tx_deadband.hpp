#pragma once
// Transmission deadband (kinesthetic deadband codecs, IEEE 1918.1.1): a station sends its
// state (x_hat, v_hat) to its neighbours only when its configuration changed perceptibly since
// the last state it sent -- some node's x_hat moved more than `position_deadband_m` (max norm
// over coordinates) -- and at least every `max_interval_ticks` ticks. The receiver's packet
// sustainment treats a skipped packet like a lost one (eq. 17: delta = 0 on the held sample);
// eq. (18) stays valid when the index-delay bound Nbar_ij includes added_index_delay_ticks(L) on
// top of the delay and the loss allowance L (the passivity budget adds it for the scenario and the
// station plan). A pure object, used by the simulator and the real station alike.
//
// Predictive (first-order, as in the IEEE 1918.1.1 kinesthetic codecs): the reference a state is
// compared with is not the last sent x_hat(s) but its extrapolation with the sent velocity,
// x_hat(s) + (k - s) T v_hat(s), which is what a receiver with `StationConfig::predict_held_state`
// uses while it holds that packet. Then a slow drift of the whole object (a hold) costs no packets
// and leaves no held-value bias (the plain band's held value lags the drift by up to the band on
// every node, coherently). The extrapolation is limited to kPredictionBands bands per coordinate
// (prediction_limit_m(), the same at both ends): it is there for slow drifts; a fast motion falls
// back to the plain band (unlimited, extrapolating each node's velocity over a hold under jittered
// long delays excited the copies: paper-worst's 10 % consensus took 14.6 s instead of 1.7 s). Only
// with the set-position modulation (rt/README.md): eq. (18)'s proof does not cover extrapolated
// neighbour data.
#include <algorithm>
#include <cstdint>
#include <vector>

namespace haptic::rt {

inline constexpr double kPredictionBands = 4.0;

// The predictive reference, one formula for both ends: a held coordinate x_hat extrapolated with
// its velocity v_hat over h_s seconds, the offset limited to +-limit_m (the sender compares with
// it, a receiver with StationConfig::predict_held_state couples to it). RT-safe.
inline double extrapolated_position(double x_hat, double v_hat, double h_s, double limit_m) {
  return x_hat + std::clamp(h_s * v_hat, -limit_m, limit_m);
}

struct TxDeadbandConfig {
  double position_deadband_m = 0;  // 0: send every tick (the policy is off)
  int max_interval_ticks = 1;      // a state at least every this many ticks, [1, 1000]
  bool predictive = false;         // compare with the last sent state extrapolated by its velocity
  // The largest extrapolation offset per coordinate, m (both ends use it).
  double prediction_limit_m() const { return kPredictionBands * position_deadband_m; }
  bool enabled() const { return position_deadband_m > 0 && max_interval_ticks > 1; }
  // Ticks the policy adds to a receiver's index delay bound Nbar_ij when up to `lost_in_a_row`
  // consecutive packets may be lost (the loss allowance L). A state goes out at least every
  // I = max_interval_ticks ticks, so the L + 1 sends after the newest one received leave within
  // (L + 1) I ticks and N_ij^k <= delay + (L + 1) I - 1, against delay + L at full rate: (L + 1)(I - 1)
  // more. Affine in L: a round trip's two directions add to added(L_ij + L_ji) + added(0).
  int added_index_delay_ticks(int lost_in_a_row) const { return enabled() ? (lost_in_a_row + 1) * (max_interval_ticks - 1) : 0; }
  void validate() const;  // throws std::invalid_argument naming the key (tx_deadband.*)
};

// At least `interval` ticks between two sends: due at the first tick once `interval` ticks have
// passed since the last send (always before the first). The deadband's interval rule, and the pace
// of probing (firmware/station/probe.hpp): a period a loaded host skipped delays the send to the
// next tick it runs instead of losing a whole interval. RT-safe.
class SendInterval {
 public:
  explicit SendInterval(std::int64_t interval = 1) : interval_(std::max<std::int64_t>(1, interval)) {}
  bool due(std::int64_t k) const { return !any_sent_ || k - last_k_ >= interval_; }
  void sent(std::int64_t k) {
    any_sent_ = true;
    last_k_ = k;
  }
  // due(k), and then sent(k) when it is.
  bool take(std::int64_t k) {
    if (!due(k)) return false;
    sent(k);
    return true;
  }
  std::int64_t last_sent() const { return last_k_; }

 private:
  std::int64_t interval_ = 1;
  std::int64_t last_k_ = 0;
  bool any_sent_ = false;
};

class TxDeadband {
 public:
  TxDeadband() = default;
  // Start-up: allocates the last-sent copy. The first call to should_send() always sends.
  // period_s: the nominal step T of the predictive reference (the receiver uses the same).
  TxDeadband(const TxDeadbandConfig& config, int dofs, double period_s = 0.002);
  // Tick k: true if the state (x_hat, v_hat: dofs values each) must be sent now; then it becomes
  // the last sent state. v_hat is read only when the policy is predictive (may be null otherwise).
  // RT-safe: no allocation, O(dofs).
  bool should_send(std::int64_t k, const double* x_hat, const double* v_hat = nullptr);
  std::uint64_t sent() const { return sent_; }
  std::uint64_t skipped() const { return skipped_; }

 private:
  TxDeadbandConfig cfg_{};
  double period_s_ = 0.002;
  std::vector<double> last_x_, last_v_;
  SendInterval every_;  // the "at least every max_interval_ticks" part
  std::uint64_t sent_ = 0, skipped_ = 0;
};

}  // namespace haptic::rt
