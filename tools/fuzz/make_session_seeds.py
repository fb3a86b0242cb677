#!/usr/bin/env python3
"""Writes the seed corpus of fuzz_session (tools/fuzz/fuzz_session.cpp) into DIR: operation lists
(the harness seals every message itself, so a seed is a script, not captured datagrams) that run the
pairwise handshake with both neighbours, then messages of every kind under the agreed keys (hello,
fingerprint, single- and multi-fragment states, float32 and float64, safe state), a replay of each,
a restart after the quiet time, a restart announced while the current incarnation talks (two live
incarnations), two authentic datagrams with one sequence (a second key holder), stale keys, junk values, and the same under the shared key.
Usage: make_session_seeds.py DIR"""
import os
import struct
import sys

RAW, HELLO, FP, STATE, REPLAY, PUSH, TIME, DRAIN, TICK, PROBE, MUTATE, STEP = range(12)


def push(c=0): return bytes([PUSH, c])
def drain(): return bytes([DRAIN])
def step(): return bytes([STEP])
def time_ms(ms): return bytes([TIME]) + struct.pack('<H', int(ms * 10))  # units of 100 us
def tick(d=0): return bytes([TICK, d & 0xFF])
def probe(begin): return bytes([PROBE, 1 if begin else 0])
def replay(i): return bytes([REPLAY]) + struct.pack('<H', i)
def mutate(at, x, key=0): return bytes([MUTATE]) + struct.pack('<H', at) + bytes([x, key])


def hello(nb, nonce=0, echo=0, agreed=True, inc=0, src=0):
    """nonce: 0 current, 1 new, 3 zeros; echo: 0 the endpoint's, 1 zeros, 3 its previous; inc: 0 current, 1 newer, 2 older."""
    c = (nonce & 3) | ((echo & 3) << 2) | (0x10 if agreed else 0) | ((inc & 3) << 5)
    return bytes([HELLO, nb, c, src])


def fingerprint(nb, key=0, inc=0, allowance=5, bound=None, src=0):
    """key: 0 this run's traffic key, 1 stale nonces, 2 the static pair key, 3 the shared key."""
    c = (key & 3) | ((inc & 3) << 2) | (0x40 if bound is not None else 0)
    out = bytes([FP, nb, c, src])
    if bound is not None:
        out += struct.pack('<Q', bound)
    return out + bytes([allowance & 0xFF])


def state(nb, delta=1, key=0, inc=0, f32=False, echo=True, safe=False, frags=0, src=0, value=None):
    """frags: bits 0-2 which fragments (0: all), bit 3 reversed. value: (index, u64 bits, in v?)."""
    c = (key & 3) | ((inc & 3) << 2) | (0x10 if f32 else 0) | (0x20 if echo else 0) | (0x40 if safe else 0)
    c |= 0x80 if value is not None else 0
    out = bytes([STATE, nb, c, (frags & 0x0F) | ((src & 3) << 4), delta & 0xFF, 0])
    if value is not None:
        out += bytes([value[0]]) + struct.pack('<Q', value[1]) + bytes([1 if value[2] else 0])
    return out


def handshake():
    # The endpoint's first push sends its hellos (its nonce); each neighbour answers echoing it.
    return push() + hello(0) + hello(1) + push() + step()


SEEDS = {}
# Every kind once under the agreed keys, then each replayed (history indices 0..).
body = handshake() + fingerprint(0) + fingerprint(1, bound=3_000_000) + state(0) + state(1, f32=True) + drain()
# history: 0 hello0, 1 hello1, 2 fp0, 3 fp1, 4-6 state0 (3 fragments), 7-8 state1 (2 fragments)
SEEDS['every_kind_replayed'] = b'\x01' + body + b''.join(replay(i) for i in range(9)) + drain()
SEEDS['fragments_reordered'] = b'\x01' + handshake() + state(0, frags=0x08) + state(0, delta=2, frags=0x05) + \
    state(0, delta=2, frags=0x02) + state(0, delta=3, safe=True) + replay(3) + drain()
SEEDS['probing_round_trips'] = b'\x01' + probe(True) + handshake() + b''.join(
    push() + state(0, delta=0) + state(1, delta=0) + time_ms(2) for _ in range(6)) + probe(False) + tick(0) + \
    state(0, delta=60) + drain()
# A restart after the quiet time (0.25 s): new incarnation, new nonce, agreed again.
SEEDS['restart_after_quiet'] = b'\x01' + handshake() + state(0) + time_ms(400) + hello(0, nonce=1, inc=1, agreed=False) + \
    push() + hello(0, nonce=0, agreed=True) + step() + fingerprint(0) + state(0, delta=2) + drain()
# A newer incarnation while the current one talks (refused), then the current one again: two live.
SEEDS['two_live_incarnations'] = b'\x01' + handshake() + state(0) + time_ms(10) + hello(0, nonce=1, inc=1) + \
    time_ms(10) + state(0, delta=2) + state(0, delta=3) + fingerprint(0) + drain()
# Keep-alive while pushes pause, stale keys and older incarnations, junk values.
SEEDS['pause_stale_junk'] = b'\x01' + handshake() + fingerprint(0) + time_ms(100) + step() + time_ms(100) + step() + \
    fingerprint(0, key=1) + fingerprint(0, key=2) + state(0, key=1) + state(0, inc=2) + hello(0, echo=3) + \
    state(0, delta=4, value=(2, 0x7FF8000000000000, False)) + state(0, delta=5, value=(3, struct.unpack('<Q', struct.pack('<d', 1.0))[0], True)) + \
    hello(1, nonce=3, echo=1) + mutate(20, 0x40) + mutate(5, 0x01) + drain()
SEEDS['wrong_sources'] = b'\x01' + handshake() + state(0, src=1) + state(0, delta=2, src=2) + state(1, src=3) + fingerprint(1, src=2) + drain()
# A second holder of a neighbour's key in its own incarnation: two authentic datagrams with one sequence
# and fragment but other content, after the first was delivered, and while the first waits in reassembly.
other_x = (2, struct.unpack('<Q', struct.pack('<d', 0.05))[0], False)
SEEDS['same_sequence_conflict'] = b'\x01' + handshake() + state(0) + state(0, value=other_x) + replay(2) + \
    state(1, delta=2, frags=0x01) + state(1, delta=2, frags=0x01, value=other_x) + replay(6) + state(1, delta=3) + drain()
# Shared key (first byte 0): no hellos, states and fingerprints under the one key.
SEEDS['shared_key'] = b'\x00' + push() + fingerprint(0) + state(0) + state(1, f32=True) + replay(0) + replay(3) + \
    fingerprint(0, key=3) + drain()


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    os.makedirs(sys.argv[1], exist_ok=True)
    for name, data in SEEDS.items():
        with open(os.path.join(sys.argv[1], 'seed_' + name), 'wb') as f:
            f.write(data)


if __name__ == '__main__':
    main()
