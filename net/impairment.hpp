#pragma once
// Seeded, reproducible network impairment for one directed link (this machine's kernel has no
// netem, so impairment is ours to emulate). The paper's model (Section V) is a preset: each
// packet's delay uniform in 50-150% of the link mean, independent loss, duplication where the
// duplicate draws its own delay; reordering follows from the random delays.
//
// Extensions (all off by default; when off they draw no random numbers, so the paper preset
// produces exactly the same sequence as before they existed):
//  - burst loss: a two-state Gilbert-Elliott chain (good/bad) stepped once per packet;
//  - reordering: with a probability, a packet is held back an extra delay so later ones pass it;
//  - blackout: every packet sent in [blackout_start_s, blackout_start_s + blackout_length_s)
//    is lost (needs the send time: next_packet_at());
//  - delay trace: one-way delays replayed cyclically from a recorded trace instead of the
//    uniform draw (load_delay_trace()).
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace haptic::net {

// splitmix64-seeded xoshiro256** generator: same numbers on every platform and compiler.
class Rng {
 public:
  explicit Rng(std::uint64_t seed = 1);
  std::uint64_t next();
  double uniform01();  // in [0, 1)
 private:
  std::uint64_t s_[4];
};

// The paper's impairment (Section V), the one definition the simulator's scenarios, the station's
// "paper" preset and haptic-topology use: each packet's delay uniform in 50-150 % of the mean
// (jitter fraction 0.5), 5 % loss, 1 % duplication (the duplicate draws its own delay).
inline constexpr double kPaperJitterFraction = 0.5;
inline constexpr double kPaperLossProbability = 0.05;
inline constexpr double kPaperDuplicateProbability = 0.01;

struct LinkImpairment {
  double mean_delay_s = 0.0;        // mean one-way delay
  double jitter_fraction = 0.5;     // delay uniform in mean*[1-j, 1+j]
  double loss_probability = 0.0;    // independent loss per packet (in the good state)
  double duplicate_probability = 0.0;  // a duplicate draws its own delay
  // Gilbert-Elliott burst loss (off when burst_enter_probability == 0).
  double burst_enter_probability = 0.0;  // P(good -> bad) per packet
  double burst_exit_probability = 1.0;   // P(bad -> good) per packet; mean burst = 1/exit
  double burst_loss_probability = 1.0;   // loss probability while in the bad state
  // Reordering (off when reorder_probability == 0): extra hold of a chosen packet.
  double reorder_probability = 0.0;
  double reorder_extra_delay_s = 0.0;
  // Blackout of a given length (off when blackout_length_s == 0), by send time.
  double blackout_start_s = 0.0;
  double blackout_length_s = 0.0;
  // Time-correlated delay (off when 0): the delay of each packet is driven by a
  // latent Gaussian AR(1) z_k = rho z_{k-1} + sqrt(1 - rho^2) n_k (one step per packet drawn) mapped
  // through the normal CDF onto the same support mean*[1-j, 1+j], so the marginal stays the
  // paper's uniform and only the correlation differs (about 1/(1 - rho) packets). A duplicate's
  // own delay stays i.i.d.
  double delay_correlation = 0.0;
  // Recorded one-way delays in seconds, replayed cyclically (replaces the uniform draw).
  std::shared_ptr<const std::vector<double>> delay_trace;

  // The paper's Section V model for a link of the given mean delay (kPaper* below).
  static LinkImpairment paper(double mean_delay_s);
  // A perfect link (zero delay, no loss).
  static LinkImpairment none() { return LinkImpairment{}; }
  // The paper's model plus bursts of loss (mean burst 5 packets, 1% entry) and 1% reordering.
  static LinkImpairment bursty(double mean_delay_s);
  // The paper's model plus a total blackout of the given length starting at start_s.
  static LinkImpairment blackout(double mean_delay_s, double start_s, double length_s);
  // Preset by name: "none", "paper", "bursty"; throws std::invalid_argument naming the
  // config key `key` and the allowed names.
  static LinkImpairment preset(std::string_view name, double mean_delay_s,
                               std::string_view key = "impairment.preset");

  // Largest one-way delay this model can produce.
  double max_delay_s() const;
};

// Reads a delay trace: one delay per line in milliseconds ('#' comments and blank lines
// skipped). Throws naming the file and line on a bad value (negative, not a number) or if empty.
std::shared_ptr<const std::vector<double>> load_delay_trace(const std::string& path);

// Fate of one packet: 0, 1 or 2 deliveries (the second is a duplicate).
struct PacketFate {
  int copies = 0;
  double delay_s[2] = {0.0, 0.0};
  bool lost = false;
  bool duplicated = false;
  bool burst_lost = false;     // lost in the Gilbert-Elliott bad state
  bool blackout_lost = false;  // lost in a blackout
  bool reordered = false;      // held back by reorder_extra_delay_s
};

// The seed of the impaired directed link sender -> receiver of a run:
//   run_seed * 1000003 + receiver * 64 + sender      (receiver, sender: 0-based user indices;
// a station's wire id is its user number, index + 1). The one rule for the simulator's channels
// and the station's send-side emulator, so both draw the same packet fates for one run seed.
std::uint64_t link_seed(std::uint64_t run_seed, int receiver_index, int sender_index);

class ImpairedLink {
 public:
  ImpairedLink() = default;
  ImpairedLink(const LinkImpairment& model, std::uint64_t seed);  // throws on a bad model
  // Draws the fate of the next packet sent on this link (blackout ignored: no send time).
  // RT-safe (no allocation).
  PacketFate next_packet();
  // Same, for a packet sent at send_time_s (seconds on the caller's clock; blackout applies).
  PacketFate next_packet_at(double send_time_s);
  // Fate of the packet with sequence number `seq`, counted from this link's first packet (0):
  // the fates of skipped sequence numbers are drawn and discarded first (at most
  // kMaxSkippedFates, beyond that the stream resynchronizes without drawing), so packet `seq`
  // meets the same fate whether or not its sender sent every earlier one. A `seq` already drawn
  // (a resend) takes the next fate in line. Blackout by send_time_s as next_packet_at().
  // RT-safe (no allocation; bounded loop).
  PacketFate fate_of(std::uint64_t seq, double send_time_s);
  static constexpr std::uint64_t kMaxSkippedFates = 1u << 16;
  const LinkImpairment& model() const { return model_; }
  bool in_burst() const { return bad_state_; }

 private:
  double draw_delay();
  PacketFate draw(bool blacked_out);
  LinkImpairment model_{};
  Rng rng_{1};
  bool bad_state_ = false;
  double latent_z_ = 0.0;       // AR(1) state of the correlated delay
  bool latent_started_ = false;
  std::size_t trace_index_ = 0;
  std::uint64_t next_seq_ = 0;  // fate_of(): sequence number the next draw belongs to
};

// The send-side emulator of one directed link as a station runs it (net::Endpoint) and as the
// simulator's channel runs it: packets before the run (seq < first_run_seq: probing) draw from a
// stream of their own; run packets draw fate_of(seq - first_run_seq) from the link seed's
// stream. So run packet k meets the same fate in a station and in the simulator (first_run_seq
// = 0) for the same link seed (tests/firmware/station/packet_fate_test.cpp).
class SendImpairment {
 public:
  SendImpairment() = default;
  SendImpairment(const LinkImpairment& model, std::uint64_t link_seed, std::uint64_t first_run_seq);  // throws on a bad model
  // send_time_s: seconds since the run start (blackouts). RT-safe (no allocation).
  PacketFate fate(std::uint64_t seq, double send_time_s);
  const LinkImpairment& model() const { return run_.model(); }

 private:
  ImpairedLink probe_, run_;
  std::uint64_t first_run_seq_ = 0;
};

}  // namespace haptic::net
