#!/usr/bin/env bash
# The Debian package (tools/package/build-deb.sh) holds what a lab PC needs and passes lintian:
#   contents: the seven programs in /usr/bin with manual pages, the unit (ExecStart
#   /usr/bin/haptic-station, station files from /etc/haptic, its Documentation= file), the udev rules, the sysctl drop-in, the example labs, the docs with
#   copyright and changelog; Depends names adduser; postinst creates the system user 'haptic';
#   the packaged unit never restarts a safety stop (unit_restart_check.py) and passes
#   `systemd-analyze verify` (its ExecStart pointed at the extracted binary);
#   lintian: no error (E:) and no warning (W:) (its output is printed).
# Exit 77 (CTest SKIP, said on the first line) without dpkg-deb/dpkg-shlibdeps, or without lintian
# or systemd-analyze (then everything else was checked).
# Usage: deb_check.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build="$1"; src="$(cd "$2" && pwd)"
for t in dpkg-deb dpkg-shlibdeps; do
  command -v "$t" >/dev/null || { echo "SKIPPED: $t not installed (apt-get install dpkg-dev): no package built"; exit 77; }
done
work="$(mktemp -d /tmp/haptic-deb-check.XXXXXX)"
trap 'rm -rf "$work"' EXIT
fail=0
bad() { echo "FAILED: $*"; fail=1; }

deb=$("$src/tools/package/build-deb.sh" "$build" "$work/out" 2>"$work/build.log") || { cat "$work/build.log"; echo "FAILED: build-deb.sh"; exit 1; }
echo "built $(basename "$deb") ($(du -k "$deb" | cut -f1) kB)"
dpkg-deb -c "$deb" | awk '{print $6}' | sed 's|^\./|/|' >"$work/files"
for f in /usr/bin/haptic-station /usr/bin/haptic-lab /usr/bin/haptic-topology /usr/bin/haptic-devices /usr/bin/haptic-keygen \
         /usr/bin/haptic-jitter /usr/bin/haptic-study /usr/lib/systemd/system/haptic-station@.service \
         /usr/lib/udev/rules.d/99-haptic.rules /usr/lib/sysctl.d/90-haptic.conf \
         /usr/share/haptic/examples/lab-4-stations/station-1.toml /usr/share/haptic/examples/lab/loopback-16.toml \
         /usr/share/haptic/tools/plots/plot_run.py /usr/share/doc/haptic-station/copyright /usr/share/doc/haptic-station/changelog.gz; do
  grep -qx "$f" "$work/files" || bad "$f not in the package"
done
for p in $(grep '^/usr/bin/[^/]\+$' "$work/files"); do
  grep -qx "/usr/share/man/man1/$(basename "$p").1.gz" "$work/files" || bad "no manual page for $p"
done
docs=$(grep -c '^/usr/share/doc/haptic-station/.*README' "$work/files")
[ "$docs" -ge 4 ] || bad "only $docs READMEs under /usr/share/doc/haptic-station"
outside=$(grep -v -e '^/usr/' -e '^/$' "$work/files" | head -3)
[ -z "$outside" ] || bad "files outside /usr: $outside"
dpkg-deb -f "$deb" Depends | grep -q adduser || bad "Depends lacks adduser: $(dpkg-deb -f "$deb" Depends)"
dpkg-deb -e "$deb" "$work/control"
grep -q 'adduser --system --group .* haptic' "$work/control/postinst" || bad "postinst does not create the system user haptic"
dpkg-deb -x "$deb" "$work/root"
unit="$work/root/usr/lib/systemd/system/haptic-station@.service"
grep -qx 'ExecStart=/usr/bin/haptic-station run --config /etc/haptic/station-%i.toml' "$unit" || bad "unit: $(grep ExecStart "$unit")"
docfile=$(sed -n 's|^Documentation=file://||p' "$unit")
[ -n "$docfile" ] && [ -f "$work/root$docfile" ] || bad "the unit's Documentation= names $docfile, not in the package"
python3 "$src/tests/firmware/deploy/unit_restart_check.py" "$unit" "$src/firmware" | tail -1 || bad "the packaged unit restarts a safety stop"
"$work/root/usr/bin/haptic-station" --version || bad "the packaged haptic-station does not run"
echo "ok: contents, Depends, postinst, unit ($(wc -l <"$work/files") paths)"

skipped=""
if command -v systemd-analyze >/dev/null; then
  mkdir -p "$work/units"
  sed "s|^ExecStart=/usr/bin/|ExecStart=$work/root/usr/bin/|" "$unit" >"$work/units/haptic-station@.service"
  out=$(cd "$work/units" && SYSTEMD_LOG_LEVEL=notice systemd-analyze verify --man=no "$work/units/haptic-station@1.service" 2>&1) ||
    { echo "$out"; bad "systemd-analyze verify of the packaged unit"; }
  if echo "$out" | grep -i "haptic-station@" | grep -iv "no such user\|Failed to resolve user\|group"; then bad "systemd-analyze: $out"; fi
  echo "ok: systemd-analyze verify of the packaged unit${out:+ ($out)}"
else
  skipped="systemd-analyze"
fi
if command -v lintian >/dev/null; then
  lintian --tag-display-limit 0 --display-info "$deb" >"$work/lintian.log" 2>&1
  echo "lintian $(lintian --version | head -1): $(grep -c . "$work/lintian.log") line(s)"
  cat "$work/lintian.log"
  grep -Eq '^[EW]: ' "$work/lintian.log" && bad "lintian reports errors or warnings"
else
  skipped="$skipped lintian"
fi
[ "$fail" -eq 0 ] || exit 1
if [ -n "$skipped" ]; then echo "SKIPPED: not installed:$skipped (apt-get install lintian systemd); the rest passed"; exit 77; fi
echo "ok: $(basename "$deb") lintian clean"
