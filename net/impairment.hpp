#pragma once
// Seeded, reproducible network impairment for one directed link (this machine's kernel has no
// netem, so impairment is ours to emulate). The paper's model (Section V) is a preset: each
// packet's delay uniform in 50-150% of the link mean, independent loss, duplication where the
// duplicate draws its own delay; reordering follows from the random delays.
#include <cstdint>

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

struct LinkImpairment {
  double mean_delay_s = 0.0;        // mean one-way delay
  double jitter_fraction = 0.5;     // delay uniform in mean*[1-j, 1+j]
  double loss_probability = 0.0;    // independent loss per packet
  double duplicate_probability = 0.0;  // a duplicate draws its own delay
  // The paper's Section V model for a link of the given mean delay.
  static LinkImpairment paper(double mean_delay_s) {
    return LinkImpairment{mean_delay_s, 0.5, 0.05, 0.01};
  }
  // Largest one-way delay this model can produce.
  double max_delay_s() const { return mean_delay_s * (1.0 + jitter_fraction); }
};

// Fate of one packet: 0, 1 or 2 deliveries (the second is a duplicate).
struct PacketFate {
  int copies = 0;
  double delay_s[2] = {0.0, 0.0};
  bool lost = false;
  bool duplicated = false;
};

class ImpairedLink {
 public:
  ImpairedLink() = default;
  ImpairedLink(const LinkImpairment& model, std::uint64_t seed);  // throws on a bad model
  PacketFate next_packet();  // draws the fate of the next packet sent on this link
  const LinkImpairment& model() const { return model_; }

 private:
  double draw_delay();
  LinkImpairment model_{};
  Rng rng_{1};
};

}  // namespace haptic::net
