#!/usr/bin/env bash
# Line coverage of fuzz_session's corpus over the receive path's key, greeting and fingerprint code:
# builds fuzz_session with clang's source-based coverage (HAPTIC_FUZZ_COVERAGE, no sanitizers), runs
# every corpus input once (-runs=0), merges the profile (llvm-profdata) and prints, per function of
# interest, its lines and the share run (llvm-cov report), then the files' totals.
# Usage: coverage.sh CORPUS_DIR [BUILD_DIR]      (needs clang, llvm-profdata, llvm-cov, llvm-cxxfilt)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
corpus="${1:?usage: coverage.sh CORPUS_DIR [BUILD_DIR]}"
build="${2:-/tmp/haptic-fuzz-cov}"
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=Debug -DHAPTIC_FUZZ_COVERAGE=ON >/dev/null
cmake --build "$build" --target fuzz_session >/dev/null
rm -f "$build"/*.profraw
LLVM_PROFILE_FILE="$build/corpus.profraw" "$build/fuzz_session" -runs=0 "$corpus" 2>&1 | grep -E "^#[0-9]+[[:space:]]+(INITED|DONE)" | tail -1 || true
llvm-profdata merge -sparse -o "$build/corpus.profdata" "$build/corpus.profraw"
files=("$repo/net/wire.cpp" "$repo/net/key_agreement.cpp" "$repo/net/keys.cpp" "$repo/net/endpoint.cpp")
llvm-cov report "$build/fuzz_session" -instr-profile="$build/corpus.profdata" -show-functions "${files[@]}" \
  | llvm-cxxfilt > "$build/functions.txt"
llvm-cov report "$build/fuzz_session" -instr-profile="$build/corpus.profdata" "${files[@]}" > "$build/files.txt"
python3 - "$build/functions.txt" <<'PY'
import re, sys
want = ["Decoder::authenticate", "Decoder::decode_hello", "Decoder::decode_fingerprint", "Decoder::decode_state",
        "Decoder::check_incarnation", "Decoder::note_current", "Decoder::control_replayed", "Decoder::set_peer_keys",
        "Decoder::reassembly_slot", "Decoder::conflicts_with_delivered", "Decoder::keep_digests",
        "Decoder::same_sequence_conflict",
        "PairAgreement::on_hello", "PairAgreement::forget", "PairAgreement::take_hello", "traffic_key(",
        "Endpoint::receive_one", "Endpoint::on_authentic", "Endpoint::on_hello", "Endpoint::on_fingerprint",
        "Endpoint::on_state", "Endpoint::deliver", "Endpoint::send_keepalive", "Endpoint::send_fingerprints",
        "Endpoint::send_hellos"]
print("%-34s %6s %6s %8s" % ("function", "lines", "missed", "covered"))
for line in open(sys.argv[1]):
    for w in want:
        if w in line:
            # Name (may hold spaces) then Regions Miss Cover Lines Miss Cover [Branches Miss Cover]
            m = re.search(r"\s(\d+)\s+(\d+)\s+([\d.]+%|-)\s+(\d+)\s+(\d+)\s+([\d.]+%|-)", line)
            if m:
                print("%-34s %6s %6s %8s" % (w.rstrip("("), m.group(4), m.group(5), m.group(6)))
PY
grep -E "^(TOTAL|.*\.cpp)" "$build/files.txt" | sed "s|$repo/||" | awk '{print $1, "lines", $8, "missed", $9, "covered", $10}'
