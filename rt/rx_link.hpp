#pragma once
// Receive-side bookkeeping for one neighbour j of station i (Section III-B, Fig. 4, eq. 17).
// A pure object fed with (sequence, send time, payload) by whoever delivers packets (the
// deterministic simulator or the real network), so both feed the same code. Two receive rules:
//  - kNewestBySequence (default): keeps the newest packet by sequence number; older ones arriving
//    late (data swapping) and repeats of the newest (duplication) are counted and dropped;
//  - kMostRecentlyReceived (the paper's Fig. 4): keeps the packet that arrived last, even when it
//    is older than the one held (data swapping uses late data; N_ij^k = k - its sequence grows);
//    a repeat of the held packet changes nothing;
//  - at each tick k: if nothing newer arrived the previous packet is held (packet sustainment)
//    and the indexing delay N_ij^k = k - seq grows;
//  - delta_ij^k = 1 only the first tick a velocity sample is used (duplication avoidance, eq. 17);
//    under the paper's rule a window of the last kUsedWindow sequences remembers which samples
//    were used (older ones count as used: delta = 0, the passive choice).
//  - the index delay it reports is never negative (data stamped ahead of our tick count as
//    delay 0).
// Two ways in. take(): the tick rules only (the rules above), for a packet a real station's
// endpoint has already judged (authentic, in sequence range, finite, in the envelope, the scene's
// size: net/README.md "Receive-path sanity"); the link then holds the caller's buffer itself (no
// copy) until a newer packet replaces it. offer(): the payload size and its finiteness checked
// first, then the same rules, and the values copied into the link, for feeders without an endpoint
// (the simulator, replay, tests): the one check they share. A link is fed one way or the other.
// take(), offer() and begin_tick() never allocate: RT-safe.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace haptic::rt {

// Copies n values from `from` to `to` and returns nonzero if some value is inf or NaN (the check
// offer() makes). For a feeder that copies a payload anyway (the simulator's sender) and can then
// hand it in with take(). RT-safe.
std::uint64_t copy_non_finite(const double* from, double* to, int n);

enum class RxVerdict : std::uint8_t { kAccepted, kStale, kDuplicate, kBadSize, kNonFinite };
enum class RxRule : std::uint8_t { kNewestBySequence, kMostRecentlyReceived };
// "newest" / "paper" (throws std::invalid_argument naming `key`), and back.
RxRule parse_rx_rule(const std::string& text, const std::string& key);
const char* rx_rule_name(RxRule rule);

struct RxCounters {
  std::uint64_t accepted = 0;
  std::uint64_t stale = 0;       // older than the newest seen (swapped/late): dropped, or used under the paper's rule
  std::uint64_t duplicate = 0;   // same sequence as the newest held
  std::uint64_t bad_size = 0;    // offer(): a payload of another size (refused)
  std::uint64_t non_finite = 0;  // offer(): a NaN/inf value in the payload (refused)
  std::uint64_t ahead_ticks = 0; // ticks whose newest data had seq > k (reported as delay 0)
  std::uint64_t sustained_ticks = 0;  // ticks that held the previous packet
  std::int64_t max_index_delay = 0;   // max N_ij^k seen
};

class RxLink {
 public:
  struct TickView {
    std::int64_t index_delay = 0;  // N_ij^k
    bool fresh = false;            // delta_ij^k (eq. 17)
    const double* x_hat = nullptr; // x_hat_j(k - N_ij^k)
    const double* v_hat = nullptr; // v_hat_j(k - N_ij^k)
    double send_time_s = 0;
  };

  RxLink() = default;
  // Start-up: payload size and the state assumed before the first packet (all copies start
  // from the same configuration at rest, v_j(k) = 0 for k <= 0). Allocates.
  void init(int dofs, const double* x_hat0, const double* v_hat0, std::int64_t initial_sequence = -1,
            RxRule rule = RxRule::kNewestBySequence);
  // A judged packet (dofs values each, finite) in the caller's buffer number `slot`: the tick rules
  // only. kAccepted: the link now reads x_hat and v_hat where they are (the caller must leave that
  // buffer alone until the link gives it back) and `released` is the buffer it held before (kNoSlot:
  // none). Otherwise `released` = slot: not held, the caller may reuse it at once.
  static constexpr std::uint32_t kNoSlot = 0xFFFFFFFFu;
  RxVerdict take(std::int64_t sequence, double send_time_s, const double* x_hat, const double* v_hat, std::uint32_t slot,
                 std::uint32_t& released);
  // An unjudged one: kBadSize unless dofs matches, kNonFinite if a value is NaN/inf (the held packet
  // stays intact), else the tick rules as take(), the values copied into the link.
  RxVerdict offer(std::int64_t sequence, double send_time_s, const double* x_hat, const double* v_hat, int dofs);
  TickView begin_tick(std::int64_t k);
  std::int64_t newest_sequence() const { return newest_seq_; }  // sequence of the held packet (the one a tick uses)
  std::int64_t max_sequence_seen() const { return max_seen_; }
  RxRule rule() const { return rule_; }
  static constexpr int kUsedWindow = 4096;
  const double* newest_x_hat() const { return held_x(); }  // the held packet's x_hat (monitoring; RT-safe)
  const RxCounters& counters() const { return counters_; }
  int dofs() const { return dofs_; }

 private:
  int dofs_ = 0;
  std::vector<double> x_hat_, v_hat_;
  std::vector<double> x_in_, v_in_;  // offer() copies and checks into these, swapped in when finite
  // take(): the held packet is the caller's buffer `slot_` (x_ext_, v_ext_), not x_hat_/v_hat_.
  std::uint32_t slot_ = kNoSlot;
  const double* x_ext_ = nullptr;
  const double* v_ext_ = nullptr;
  const double* held_x() const { return slot_ != kNoSlot ? x_ext_ : x_hat_.data(); }
  const double* held_v() const { return slot_ != kNoSlot ? v_ext_ : v_hat_.data(); }
  // The tick rules' verdict on a sequence (counts stale and duplicate); kAccepted: use it.
  RxVerdict judge(std::int64_t seq);
  void hold(std::int64_t seq, double send_time_s);  // the newly used packet's bookkeeping
  std::int64_t newest_seq_ = -1;
  std::int64_t max_seen_ = -1;
  RxRule rule_ = RxRule::kNewestBySequence;
  std::array<std::uint64_t, kUsedWindow / 64> used_{};  // paper's rule: sequences whose velocity was used
  std::int64_t max_used_ = -1;
  bool was_used(std::int64_t seq) const;
  void mark_used(std::int64_t seq);
  double newest_send_time_ = 0;
  bool unused_ = false;  // newest velocity sample not yet used by a tick
  std::int64_t last_tick_ = INT64_MIN;
  RxCounters counters_{};
};

}  // namespace haptic::rt
