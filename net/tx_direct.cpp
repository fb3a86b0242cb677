#include "net/tx_direct.hpp"

namespace haptic::net {

DirectSender::DirectSender(const Encoder& encoder, Transport& transport, std::size_t peers, std::uint32_t value_count,
                           std::size_t max_datagram_bytes)
    : encoder_(encoder),
      transport_(transport),
      frags_(encoder.fragment_count(value_count)),
      cap_(max_datagram_bytes),
      enabled_(frags_ > 0 && peers * frags_ <= kDirectMaxDatagrams),
      store_(enabled_ ? kDirectMaxDatagrams * max_datagram_bytes : 0) {}

void DirectSender::send(OutgoingState s, const DirectTicket* tickets, std::size_t n, DirectPush& rec) {
  rec.attempted = true;
  std::size_t k = 0;
  for (std::size_t p = 0; p < n; ++p) {
    const DirectTicket& t = tickets[p];
    const EchoSlot* e = newest_echo_by(t.echo, t.previous, s.send_time_ns);
    s.dest = t.station_id;
    s.has_echo = e != nullptr;
    s.echo_seq = e ? e->seq : 0;
    s.echo_hold_ns = e ? s.send_time_ns - e->receive_time_ns : 0;
    rec.peer[p] = DirectPeerSend{s.has_echo, s.echo_seq, s.echo_hold_ns, 0, 0};
    for (std::size_t f = 0; f < frags_; ++f, ++k) {
      std::uint8_t* buf = store_.data() + k * cap_;
      batch_[k] = TxDatagram{t.station_id, buf, encoder_.encode_fragment(s, f, buf, cap_, &t.key)};
      owner_[k] = static_cast<std::uint8_t>(p);
    }
  }
  int error = 0;
  const std::size_t sent = transport_.send_batch(batch_, k, error);
  for (std::size_t i = 0; i < sent; ++i) {
    ++rec.peer[owner_[i]].datagrams_sent;
    rec.peer[owner_[i]].bytes_sent += static_cast<std::uint32_t>(batch_[i].len);
  }
  rec.complete = sent == k;
  rec.error = error;
}

}  // namespace haptic::net
