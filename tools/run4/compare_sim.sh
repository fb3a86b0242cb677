#!/usr/bin/env bash
# The issue's "Measure and report": the four-process run against the deterministic simulator on
# the same scenario and seed (shortened paper-best by default: 8 s, push end 2.5 s, release 5 s).
# Usage: compare_sim.sh [--transport udp|raw] [--seed N] [--duration S] [--push-end S] [--release S]
#                       [--bin PATH] [--out DIR]
# Writes OUT/sim/, OUT/run/ and OUT/compare.json (consensus time, hold-force balance, relative
# differences; the issue's target is within 20 %).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
transport=udp; seed=1; duration=8; push_end=2.5; release=5; bin="$repo/build/bin/haptic-station"; out=""
while [ $# -gt 0 ]; do
  case "$1" in
    --transport) transport="$2"; shift 2 ;; --seed) seed="$2"; shift 2 ;; --duration) duration="$2"; shift 2 ;;
    --push-end) push_end="$2"; shift 2 ;; --release) release="$2"; shift 2 ;; --bin) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;; *) echo "compare_sim.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
[ -n "$out" ] || out="$(mktemp -d /tmp/compare.XXXXXX)"
mkdir -p "$out"
"$bin" sim --scenario paper-best --seed "$seed" --duration "$duration" --push-end "$push_end" --release "$release" \
  --out "$out/sim" --quiet --no-plots
"$here/run4.sh" --transport "$transport" --bin "$bin" --seed "$seed" --duration "$duration" --push-end "$push_end" \
  --release "$release" --out "$out/run" --no-plots
/usr/bin/python3 - "$out" <<'PY'
import json, sys, os
out = sys.argv[1]
s = json.load(open(os.path.join(out, "sim", "summary.json")))
r = json.load(open(os.path.join(out, "run", "summary.json")))
def rel(a, b):
    return None if a is None or b is None or a == 0 else (b - a) / a
c = {"seed": s["seed"], "transport": r["mode"],
     "consensus_time_s": {"sim": s["consensus_time_s"], "run": r["consensus_time_s"], "rel_diff": rel(s["consensus_time_s"], r["consensus_time_s"]),
                          "run_resolution_s": r["consensus_time_resolution_s"]},
     "hold_force_mean_N": {"sim": s["hold_force_mean_N"], "run": r["hold_force_mean_N"], "rel_diff": rel(s["hold_force_mean_N"], r["hold_force_mean_N"])},
     "hold_force_sum_N": {"sim": s["hold_force_sum_N"], "run": r["hold_force_sum_N"], "rel_diff": rel(s["hold_force_sum_N"], r["hold_force_sum_N"])},
     "hold_force_balance_ratio": {"sim": s["hold_force_balance_ratio"], "run": r["hold_force_balance_ratio"]},
     "damping_Ns_per_m": {"sim_model": s["damping_Ns_per_m"], "run_measured": r["damping_Ns_per_m"]},
     "diverged": {"sim": s["diverged"], "run": r["diverged"]},
     "passivity_condition_met": {"sim": s["passivity_condition_met"], "run": r["passivity_condition_met"]},
     "bounds_consistent_all_links": r.get("bounds_consistent_all_links")}
json.dump(c, open(os.path.join(out, "compare.json"), "w"), indent=2)
print(json.dumps(c, indent=2))
PY
