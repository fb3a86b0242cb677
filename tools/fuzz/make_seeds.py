#!/usr/bin/python3
"""Writes fuzzer seeds (tools/fuzz/seeds/): well-formed wire-v3 datagrams in the fuzz input
format (2-byte length + 1 flag byte, flag bit0 = re-sign with the fuzz key). The MAC is
computed here too (BLAKE2b-128 keyed = libsodium crypto_generichash), so seeds are valid."""
import hashlib, os, struct

KEY = bytes(range(32))
HERE = os.path.dirname(os.path.abspath(__file__))

PROXY = 3  # values after x_hat and v_hat: the sender's proxy position (flag 8 when meaningful)

def datagram(seq, sender, values, frag_index, frag_count, stride, payload, f32=False, proxy=False):
    flags = (1 if f32 else 0) | 2 | (8 if proxy else 0)
    vb = 4 if f32 else 8
    total = (2 * values + PROXY) * vb
    off = frag_index * stride
    piece = payload[off:off + min(stride, total - off)]
    hdr = struct.pack('<IBBBBIHHQqQqIHHIHHQ', 0x4E504148, 3, 1, flags, 72, 0x5EED, sender, 0,
                      seq, 1000 + seq, seq - 1, 500, values, frag_index, frag_count, off, len(piece), stride,
                      1_700_000_000_000_000_000 + sender)
    body = hdr + piece
    return body + hashlib.blake2b(body, key=KEY, digest_size=16).digest()

def wrap(dgs, ctl=1):
    # ctl: bit0 re-sign, bits1-3 source (0 unchecked, 1 unknown, 2..4 station 1..3), bits4-7 ticks passing first
    return b''.join(struct.pack('<H', len(d)) + bytes([ctl]) + d for d in dgs)

os.makedirs(os.path.join(HERE, 'seeds'), exist_ok=True)
def write(name, dgs, ctl=1):
    with open(os.path.join(HERE, 'seeds', name), 'wb') as f:
        f.write(wrap(dgs, ctl))

vals = 99
p64 = b''.join(struct.pack('<d', i * 0.01) for i in range(2 * vals + PROXY))
stride = 1312
write('single_f32', [datagram(1, 1, vals, 0, 1, 1312, b''.join(struct.pack('<f', i * 0.01) for i in range(2 * vals + PROXY)), True, True)])
write('two_frag_f64', [datagram(2, 2, vals, 0, 2, stride, p64, proxy=True), datagram(2, 2, vals, 1, 2, stride, p64, proxy=True)])
write('reordered_dup', [datagram(3, 3, vals, 1, 2, stride, p64), datagram(3, 3, vals, 1, 2, stride, p64),
                        datagram(3, 3, vals, 0, 2, stride, p64), datagram(2, 3, vals, 0, 2, stride, p64)])
def fingerprint(seq, sender, nodes):
    hdr = struct.pack('<IBBBBIHHQqQqIHHIHHQ', 0x4E504148, 3, 2, 0, 72, 0x5EED, sender, 0,
                      seq, 1000 + seq, 0, 0, 0, 0, 1, 0, 56, 56, 1_700_000_000_000_000_000 + sender)
    # the 56-byte fingerprint payload (net/wire.hpp): protocol, nodes, scene, period, gains, round-trip
    # bound, loss allowance + 1, law, predict, deadband hash, step bound T^max in ns
    body = hdr + struct.pack('<IIQQQQIBBHQ', 3, nodes, 0x1234, 2_000_000, 0x5678, 0, 0, 1, 0, 0, 2_000_000)
    return body + hashlib.blake2b(body, key=KEY, digest_size=16).digest()

write('fingerprint', [fingerprint(1, 1, 33)])
big = 600
pbig = bytes((2 * big + PROXY) * 8)
write('many_frags', [datagram(5, 1, big, i, 8, 1312, pbig) for i in range(8)])

# The whole receive path (fuzz_wire.cpp): 600 values in float32 inside the envelope, from station 1's
# address, 10 ticks after the previous datagram (so the echo's age bound passes the guard), then
# a far-future sequence, a NaN, and the same packet from an unknown address.
rest = (b''.join(struct.pack('<f', 0.001 * (i % 7)) for i in range(big)) + b''.join(struct.pack('<f', 0.01) for _ in range(big)) +
        b''.join(struct.pack('<f', 0.02) for _ in range(PROXY)))
def packet(seq, payload, f32=True):
    frags = (len(payload) + 1312 - 1) // 1312
    return [datagram(seq, 1, big, i, frags, 1312, payload, f32, proxy=True) for i in range(frags)]
station1 = 0x01 | (2 << 1)
nan = bytearray(rest); nan[40:44] = struct.pack('<f', float('nan'))
def timed(dgs, ctl, ticks):  # the ticks pass before the packet's first datagram only
    return wrap(dgs[:1], ctl | (ticks << 4)) + wrap(dgs[1:], ctl)
with open(os.path.join(HERE, 'seeds', 'receive_path'), 'wb') as f:
    f.write(timed(packet(10, rest), station1, 10) + timed(packet(12, rest), station1, 2) +
            wrap(packet(1_000_000, rest), station1) + timed(packet(13, bytes(nan)), station1, 1) +
            wrap(packet(14, rest), 0x01 | (1 << 1)))
