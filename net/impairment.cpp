#include "net/impairment.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace haptic::net {

namespace {
std::uint64_t splitmix64(std::uint64_t& x) {
  std::uint64_t z = (x += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
}  // namespace

Rng::Rng(std::uint64_t seed) {
  for (auto& s : s_) s = splitmix64(seed);
}

std::uint64_t Rng::next() {
  const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
  const std::uint64_t t = s_[1] << 17;
  s_[2] ^= s_[0];
  s_[3] ^= s_[1];
  s_[1] ^= s_[2];
  s_[0] ^= s_[3];
  s_[2] ^= t;
  s_[3] = rotl(s_[3], 45);
  return result;
}

double Rng::uniform01() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

ImpairedLink::ImpairedLink(const LinkImpairment& model, std::uint64_t seed)
    : model_(model), rng_(seed) {
  auto bad = [](const std::string& key, const std::string& range) {
    throw std::invalid_argument("impairment: " + key + " must be " + range);
  };
  if (!(model.mean_delay_s >= 0.0) || !std::isfinite(model.mean_delay_s)) bad("mean_delay_s", ">= 0");
  if (!(model.jitter_fraction >= 0.0 && model.jitter_fraction <= 1.0)) bad("jitter_fraction", "in [0, 1]");
  if (!(model.loss_probability >= 0.0 && model.loss_probability < 1.0)) bad("loss_probability", "in [0, 1)");
  if (!(model.duplicate_probability >= 0.0 && model.duplicate_probability <= 1.0))
    bad("duplicate_probability", "in [0, 1]");
}

double ImpairedLink::draw_delay() {
  const double j = model_.jitter_fraction;
  return model_.mean_delay_s * (1.0 - j + 2.0 * j * rng_.uniform01());
}

PacketFate ImpairedLink::next_packet() {
  PacketFate f;
  // Draw every random number every time, so one link's sequence does not depend on outcomes.
  const double u_loss = rng_.uniform01();
  const double u_dup = rng_.uniform01();
  const double d0 = draw_delay();
  const double d1 = draw_delay();
  if (u_loss < model_.loss_probability) {
    f.lost = true;
    return f;
  }
  f.copies = 1;
  f.delay_s[0] = d0;
  if (u_dup < model_.duplicate_probability) {
    f.duplicated = true;
    f.copies = 2;
    f.delay_s[1] = d1;
  }
  return f;
}

}  // namespace haptic::net
