#include "net/impairment.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
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

LinkImpairment LinkImpairment::paper(double mean_delay_s) {
  LinkImpairment m;
  m.mean_delay_s = mean_delay_s;
  m.jitter_fraction = kPaperJitterFraction;
  m.loss_probability = kPaperLossProbability;
  m.duplicate_probability = kPaperDuplicateProbability;
  return m;
}

LinkImpairment LinkImpairment::bursty(double mean_delay_s) {
  LinkImpairment m = paper(mean_delay_s);
  m.burst_enter_probability = 0.01;
  m.burst_exit_probability = 0.2;
  m.burst_loss_probability = 1.0;
  m.reorder_probability = 0.01;
  m.reorder_extra_delay_s = mean_delay_s;
  return m;
}

LinkImpairment LinkImpairment::blackout(double mean_delay_s, double start_s, double length_s) {
  LinkImpairment m = paper(mean_delay_s);
  m.blackout_start_s = start_s;
  m.blackout_length_s = length_s;
  return m;
}

LinkImpairment LinkImpairment::preset(std::string_view name, double mean_delay_s, std::string_view key) {
  if (name == "none") return none();
  if (name == "paper") return paper(mean_delay_s);
  if (name == "bursty") return bursty(mean_delay_s);
  throw std::invalid_argument(std::string(key) + " = \"" + std::string(name) +
                              "\": allowed values are \"none\", \"paper\", \"bursty\"");
}

double LinkImpairment::max_delay_s() const {
  double base = mean_delay_s * (1.0 + jitter_fraction);
  if (delay_trace && !delay_trace->empty())
    base = *std::max_element(delay_trace->begin(), delay_trace->end());
  if (reorder_probability > 0.0) base += reorder_extra_delay_s;
  return base;
}

std::shared_ptr<const std::vector<double>> load_delay_trace(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("delay trace: cannot open " + path);
  auto v = std::make_shared<std::vector<double>>();
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    char* end = nullptr;
    const double ms = std::strtod(line.c_str(), &end);
    if (end == line.c_str() || !std::isfinite(ms) || ms < 0.0 ||
        line.find_first_not_of(" \t\r", static_cast<std::size_t>(end - line.c_str())) != std::string::npos)
      throw std::invalid_argument("delay trace " + path + ":" + std::to_string(lineno) +
                                  ": expected one delay in ms >= 0 per line");
    v->push_back(ms * 1e-3);
  }
  if (v->empty()) throw std::invalid_argument("delay trace " + path + ": no delays");
  return v;
}

ImpairedLink::ImpairedLink(const LinkImpairment& model, std::uint64_t seed)
    : model_(model), rng_(seed) {
  auto bad = [](const std::string& key, const std::string& range) {
    throw std::invalid_argument("impairment: " + key + " must be " + range);
  };
  auto prob = [](double p) { return p >= 0.0 && p <= 1.0; };
  if (!(model.mean_delay_s >= 0.0) || !std::isfinite(model.mean_delay_s)) bad("mean_delay_s", ">= 0");
  if (!(model.jitter_fraction >= 0.0 && model.jitter_fraction <= 1.0)) bad("jitter_fraction", "in [0, 1]");
  if (!(model.loss_probability >= 0.0 && model.loss_probability < 1.0)) bad("loss_probability", "in [0, 1)");
  if (!prob(model.duplicate_probability)) bad("duplicate_probability", "in [0, 1]");
  if (!prob(model.burst_enter_probability)) bad("burst_enter_probability", "in [0, 1]");
  if (!(model.burst_exit_probability > 0.0 && model.burst_exit_probability <= 1.0))
    bad("burst_exit_probability", "in (0, 1]");
  if (!prob(model.burst_loss_probability)) bad("burst_loss_probability", "in [0, 1]");
  if (!prob(model.reorder_probability)) bad("reorder_probability", "in [0, 1]");
  if (!(model.delay_correlation >= 0.0 && model.delay_correlation < 1.0)) bad("delay_correlation", "in [0, 1)");
  if (!(model.reorder_extra_delay_s >= 0.0) || !std::isfinite(model.reorder_extra_delay_s))
    bad("reorder_extra_delay_s", ">= 0");
  if (!(model.blackout_length_s >= 0.0) || !std::isfinite(model.blackout_length_s))
    bad("blackout_length_s", ">= 0");
  if (!std::isfinite(model.blackout_start_s)) bad("blackout_start_s", "finite");
  if (model.delay_trace) {
    if (model.delay_trace->empty()) bad("delay_trace", "non-empty");
    for (double d : *model.delay_trace)
      if (!(d >= 0.0) || !std::isfinite(d)) bad("delay_trace", "delays >= 0");
  }
}

double ImpairedLink::draw_delay() {
  const double j = model_.jitter_fraction;
  return model_.mean_delay_s * (1.0 - j + 2.0 * j * rng_.uniform01());
}

PacketFate ImpairedLink::next_packet() { return draw(false); }

std::uint64_t link_seed(std::uint64_t run_seed, int receiver_index, int sender_index) {
  return run_seed * 1000003ULL + static_cast<std::uint64_t>(static_cast<std::int64_t>(receiver_index) * 64 + sender_index);
}

PacketFate ImpairedLink::fate_of(std::uint64_t seq, double send_time_s) {
  if (seq > next_seq_ && seq - next_seq_ <= kMaxSkippedFates) {
    while (next_seq_ < seq) {
      (void)draw(false);
      ++next_seq_;
    }
  }
  next_seq_ = std::max(next_seq_, seq) + 1;
  return next_packet_at(send_time_s);
}

SendImpairment::SendImpairment(const LinkImpairment& model, std::uint64_t link_seed_value, std::uint64_t first_run_seq)
    : probe_(model, link_seed_value ^ 0x9E3779B97F4A7C15ULL), run_(model, link_seed_value), first_run_seq_(first_run_seq) {}

PacketFate SendImpairment::fate(std::uint64_t seq, double send_time_s) {
  if (seq < first_run_seq_) return probe_.next_packet_at(send_time_s);
  return run_.fate_of(seq - first_run_seq_, send_time_s);
}

PacketFate ImpairedLink::next_packet_at(double send_time_s) {
  const bool blacked = model_.blackout_length_s > 0.0 && send_time_s >= model_.blackout_start_s &&
                       send_time_s < model_.blackout_start_s + model_.blackout_length_s;
  return draw(blacked);
}

PacketFate ImpairedLink::draw(bool blacked_out) {
  PacketFate f;
  // Draw every random number every time, so one link's sequence does not depend on outcomes.
  // (Extensions draw theirs only when enabled: the paper preset's sequence is unchanged.)
  const double u_loss = rng_.uniform01();
  const double u_dup = rng_.uniform01();
  double d0 = draw_delay();
  double d1 = draw_delay();
  bool burst_lost = false;
  if (model_.burst_enter_probability > 0.0) {
    const double u_state = rng_.uniform01();
    const double u_bad = rng_.uniform01();
    if (bad_state_) {
      if (u_state < model_.burst_exit_probability) bad_state_ = false;
    } else if (u_state < model_.burst_enter_probability) {
      bad_state_ = true;
    }
    burst_lost = bad_state_ && u_bad < model_.burst_loss_probability;
  }
  if (model_.delay_correlation > 0.0) {
    // Box-Muller normal, then the AR(1) step and the normal CDF onto the uniform's support
    const double u1 = 1.0 - rng_.uniform01(), u2 = rng_.uniform01();
    const double n = std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
    const double rho = model_.delay_correlation;
    latent_z_ = latent_started_ ? rho * latent_z_ + std::sqrt(1.0 - rho * rho) * n : n;
    latent_started_ = true;
    const double phi = 0.5 * std::erfc(-latent_z_ / std::sqrt(2.0));
    const double j = model_.jitter_fraction;
    d0 = model_.mean_delay_s * (1.0 - j + 2.0 * j * phi);
  }
  bool reordered = false;
  if (model_.reorder_probability > 0.0) reordered = rng_.uniform01() < model_.reorder_probability;
  if (model_.delay_trace) {
    const auto& tr = *model_.delay_trace;
    d0 = tr[trace_index_ % tr.size()];
    d1 = tr[(trace_index_ + 1) % tr.size()];
    ++trace_index_;
  }
  if (reordered) d0 += model_.reorder_extra_delay_s;
  if (blacked_out) {
    f.lost = f.blackout_lost = true;
    return f;
  }
  if (burst_lost) {
    f.lost = f.burst_lost = true;
    return f;
  }
  if (u_loss < model_.loss_probability) {
    f.lost = true;
    return f;
  }
  f.copies = 1;
  f.delay_s[0] = d0;
  f.reordered = reordered;
  if (u_dup < model_.duplicate_probability) {
    f.duplicated = true;
    f.copies = 2;
    f.delay_s[1] = d1;
  }
  return f;
}

}  // namespace haptic::net
