#!/usr/bin/env bash
# Records an LTTng-UST session (provider 'haptic', plus vpid/vtid/procname contexts) around a
# command, e.g. a station run or haptic-jitter:
#   tools/trace/record.sh [-o OUTDIR] [-n SESSION] [-k] -- build/bin/haptic-jitter -D 5
# Prints the trace directory on the last line of stdout ("trace: DIR"); analyse it with
#   /usr/bin/python3 tools/trace/analyze.py DIR
# Needs lttng-tools; starts a root session daemon when none is running and we are root.
# -k also records kernel sched_switch/sched_wakeup when lttng-modules are loaded.
# Exit status: the command's, or 3 when tracing could not be set up (reason on stderr).
set -euo pipefail

out=""
session="haptic-$$-$(date +%Y%m%d-%H%M%S)"
kernel=0
usage() { sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    -o) out="$2"; shift 2 ;;
    -n) session="$2"; shift 2 ;;
    -k) kernel=1; shift ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    *) break ;;
  esac
done
[ $# -gt 0 ] || { usage >&2; exit 2; }
[ -n "$out" ] || out="$PWD/trace-${session}"

fail() { echo "record.sh: tracing impossible: $*" >&2; exit 3; }
command -v lttng >/dev/null || fail "lttng (lttng-tools) is not installed: apt install lttng-tools"
if ! lttng list >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ] && command -v lttng-sessiond >/dev/null; then
    lttng-sessiond --daemonize >/dev/null 2>&1 || fail "lttng-sessiond --daemonize failed"
    for _ in 1 2 3 4 5 6 7 8 9 10; do lttng list >/dev/null 2>&1 && break; sleep 0.2; done
    lttng list >/dev/null 2>&1 || fail "lttng-sessiond started but does not answer"
  else
    fail "no lttng session daemon is running and we are not root (start one: lttng-sessiond --daemonize)"
  fi
fi

lttng create "$session" --output="$out" >/dev/null || fail "lttng create $session failed"
cleanup() { lttng destroy "$session" >/dev/null 2>&1 || true; }
trap cleanup EXIT
# 8 x 1 MiB per-CPU sub-buffers: a 60 s four-station run at 500 Hz does not discard events.
lttng enable-channel -u --subbuf-size=1M --num-subbuf=8 haptic >/dev/null || fail "enable-channel failed"
lttng enable-event -u -c haptic 'haptic:*' >/dev/null || fail "enable-event haptic:* failed"
lttng add-context -u -c haptic -t vpid -t vtid -t procname >/dev/null || fail "add-context failed"
if [ "$kernel" -eq 1 ]; then
  lttng enable-event -k --syscall -a >/dev/null 2>&1 || echo "record.sh: kernel tracing unavailable (lttng-modules not loaded); UST only" >&2
  lttng enable-event -k sched_switch,sched_wakeup >/dev/null 2>&1 || true
fi
lttng start "$session" >/dev/null || fail "lttng start failed"

set +e
"$@"
rc=$?
set -e
lttng stop "$session" >/dev/null || true
discarded=$(lttng list "$session" 2>/dev/null | grep -i "discarded events" || true)
[ -z "$discarded" ] || echo "record.sh: $discarded" >&2
lttng destroy "$session" >/dev/null || true
trap - EXIT
echo "trace: $out"
exit $rc
