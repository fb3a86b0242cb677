#pragma once
// A one-way hand-off of state buffers between two threads: Buffers buffers of 2 x value_count
// doubles (x_hat then v_hat) plus a Meta record each, allocated in the constructor, and two SPSC
// rings of buffer indices (platform/spsc_ring.hpp): `ready` (producer -> consumer) and `free`
// (consumer -> producer). Exactly one thread produces and one consumes; the names say which side
// may call what. Every method is wait-free, lock-free and allocation-free (RT-safe) on both sides.
// The endpoint has two: RX (I/O thread -> RT tick) and TX (RT tick -> I/O thread).
#include <cstdint>
#include <vector>

#include "platform/spsc_ring.hpp"

namespace haptic::net {

template <class Meta, std::size_t Buffers>
class StateChannel {
 public:
  explicit StateChannel(std::uint32_t value_count)
      : value_count_(value_count), meta_(Buffers), store_(Buffers * 2 * std::size_t{value_count}) {
    for (std::uint32_t i = 0; i < Buffers; ++i) free_.writer_try_push(i);
  }
  StateChannel(const StateChannel&) = delete;
  StateChannel& operator=(const StateChannel&) = delete;

  // Producer: a free buffer's index; false when every buffer is queued or held by the consumer.
  bool producer_acquire(std::uint32_t& idx) { return free_.reader_try_pop(idx); }
  // Producer: hands a buffer filled through values()/meta() to the consumer (never fails: as many slots as buffers).
  void producer_publish(std::uint32_t idx) { ready_.writer_try_push(idx); }
  // Consumer: the oldest published buffer; false when none is waiting.
  bool consumer_pop(std::uint32_t& idx) { return ready_.reader_try_pop(idx); }
  // Consumer: gives a popped buffer back to the producer.
  void consumer_release(std::uint32_t idx) { free_.writer_try_push(idx); }

  // The buffer's x_hat (value_count doubles), then v_hat; its record. The side holding idx only.
  double* values(std::uint32_t idx) { return store_.data() + std::size_t{idx} * 2 * value_count_; }
  const double* values(std::uint32_t idx) const { return store_.data() + std::size_t{idx} * 2 * value_count_; }
  Meta& meta(std::uint32_t idx) { return meta_[idx]; }
  const Meta& meta(std::uint32_t idx) const { return meta_[idx]; }
  // Published buffers not yet popped (either side; exact when the other side is idle).
  std::size_t ready_size() const { return ready_.size(); }
  std::uint32_t value_count() const { return value_count_; }

 private:
  std::uint32_t value_count_;
  std::vector<Meta> meta_;
  std::vector<double> store_;
  platform::SpscRing<std::uint32_t, Buffers> ready_, free_;
};

}  // namespace haptic::net
