# Sourced by the insider tests (insider_check.sh, resilient_insider_check.sh):
#
#   insider_bin BIN_DIR WORK_DIR
#
# makes WORK_DIR/bin: every program of BIN_DIR, and a `haptic-station` wrapper that runs the station
# whose file is station-1.toml as haptic-insider (the TEST-ONLY liar, insider_main.cpp) when
# INSIDER_LIE is set (with INSIDER_AMPLITUDE, from run time 1 s), every other one as haptic-station.
# haptic-lab starts "haptic-station" from HAPTIC_BIN_DIR: point it at WORK_DIR/bin.
insider_bin() {
  local bindir="$1" work="$2" f
  mkdir -p "$work/bin"
  for f in "$bindir"/*; do ln -s "$f" "$work/bin/$(basename "$f")"; done
  rm "$work/bin/haptic-station"
  cat > "$work/bin/haptic-station" <<WRAP
#!/usr/bin/env bash
case " \$* " in
  *station-1.toml*) [ -n "\${INSIDER_LIE:-}" ] && exec env HAPTIC_INSIDER_LIE="\$INSIDER_LIE" HAPTIC_INSIDER_AMPLITUDE="\$INSIDER_AMPLITUDE" \\
                      HAPTIC_INSIDER_FROM_S=1.0 "$bindir/haptic-insider" "\$@" ;;
esac
exec "$bindir/haptic-station" "\$@"
WRAP
  chmod +x "$work/bin/haptic-station"
}

# Exits 77 (CTest: skipped, with the reason) when BIN_DIR has no haptic-insider or there is no python3.
insider_skip_unless_built() {
  [ -x "$1/haptic-insider" ] || { echo "SKIPPED: $1/haptic-insider not built"; exit 77; }
  [ -x /usr/bin/python3 ] || { echo "SKIPPED: /usr/bin/python3 missing for the checks"; exit 77; }
}
