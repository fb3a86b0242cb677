#!/usr/bin/env bash
# trace.csv's default rate scales with the users (firmware/sim/simulator.hpp default_trace_every):
# every tick up to 8 users, every ceil(N/8)-th tick above (16 users: every 2nd, 24: every 3rd);
# series.csv stays at every tick; --trace-every K sets both; summary.json says both rates.
set -euo pipefail
bin="$1"; out="$2"
rm -rf "$out"; mkdir -p "$out"
fail=0
check() {  # users, extra options, trace every, series every
  local users="$1" extra="$2" want_t="$3" want_s="$4" dir="$out/u$1$(echo "$2" | tr -d ' -')"
  # shellcheck disable=SC2086
  "$bin" sim --scenario paper-best --users "$users" --duration 0.24 $extra --out "$dir" --no-plots --quiet > "$dir.log" 2>&1 || { cat "$dir.log"; exit 1; }
  local ticks=120 rows_t rows_s got
  rows_t=$(($(wc -l < "$dir/trace.csv") - 1)); rows_s=$(($(wc -l < "$dir/series.csv") - 1))
  got=$(/usr/bin/python3 -c "import json; s = json.load(open('$dir/summary.json')); print(s['trace_every'], s['series_every'])")
  if [ "$rows_t" -ne $(( (ticks + want_t - 1) / want_t * users )) ] || [ "$rows_s" -ne $(( (ticks + want_s - 1) / want_s )) ] || [ "$got" != "$want_t $want_s" ]; then
    echo "FAILED: $users users $extra: trace.csv $rows_t rows, series.csv $rows_s rows, summary says every $got; want every $want_t and $want_s of $ticks ticks"
    fail=1
  else
    echo "$users users $extra: trace.csv every $want_t tick(s) ($rows_t rows), series.csv every $want_s ($rows_s rows)"
  fi
}
check 4 "" 1 1
check 8 "" 1 1
check 16 "" 2 1
check 24 "" 3 1
check 16 "--trace-every 1" 1 1
check 4 "--trace-every 5" 5 5
exit $fail
