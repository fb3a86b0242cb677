#!/usr/bin/python3
"""Writes fuzzer seeds (tools/fuzz/seeds/): well-formed wire-v2 datagrams in the fuzz input
format (2-byte length + 1 flag byte, flag bit0 = re-sign with the fuzz key). The MAC is
computed here too (BLAKE2b-128 keyed = libsodium crypto_generichash), so seeds are valid."""
import hashlib, os, struct

KEY = bytes(range(32))
HERE = os.path.dirname(os.path.abspath(__file__))

def datagram(seq, sender, values, frag_index, frag_count, stride, payload, f32=False):
    flags = (1 if f32 else 0) | 2
    vb = 4 if f32 else 8
    total = 2 * values * vb
    off = frag_index * stride
    piece = payload[off:off + min(stride, total - off)]
    hdr = struct.pack('<IBBBBIHHQqQqIHHIHHQ', 0x4E504148, 2, 1, flags, 72, 0x5EED, sender, 0,
                      seq, 1000 + seq, seq - 1, 500, values, frag_index, frag_count, off, len(piece), stride,
                      1_700_000_000_000_000_000 + sender)
    body = hdr + piece
    return body + hashlib.blake2b(body, key=KEY, digest_size=16).digest()

def wrap(dgs):
    return b''.join(struct.pack('<H', len(d)) + b'\x01' + d for d in dgs)

os.makedirs(os.path.join(HERE, 'seeds'), exist_ok=True)
def write(name, dgs):
    with open(os.path.join(HERE, 'seeds', name), 'wb') as f:
        f.write(wrap(dgs))

vals = 99
p64 = b''.join(struct.pack('<d', i * 0.01) for i in range(2 * vals))
stride = 1320
write('single_f32', [datagram(1, 1, vals, 0, 1, 1320, b''.join(struct.pack('<f', i * 0.01) for i in range(2 * vals)), True)])
write('two_frag_f64', [datagram(2, 2, vals, 0, 2, stride, p64), datagram(2, 2, vals, 1, 2, stride, p64)])
write('reordered_dup', [datagram(3, 3, vals, 1, 2, stride, p64), datagram(3, 3, vals, 1, 2, stride, p64),
                        datagram(3, 3, vals, 0, 2, stride, p64), datagram(2, 3, vals, 0, 2, stride, p64)])
def fingerprint(seq, sender, nodes):
    hdr = struct.pack('<IBBBBIHHQqQqIHHIHHQ', 0x4E504148, 2, 2, 0, 72, 0x5EED, sender, 0,
                      seq, 1000 + seq, 0, 0, 0, 0, 1, 0, 32, 32, 1_700_000_000_000_000_000 + sender)
    body = hdr + struct.pack('<IIQQQ', 2, nodes, 0x1234, 2_000_000, 0x5678)
    return body + hashlib.blake2b(body, key=KEY, digest_size=16).digest()

write('fingerprint', [fingerprint(1, 1, 33)])
big = 600
pbig = bytes(2 * big * 8)
write('many_frags', [datagram(5, 1, big, i, 8, 1320, pbig) for i in range(8)])
