#!/usr/bin/env bash
# Build the Debian package haptic-station_<version>_<arch>.deb from a built tree (tools/package/README.md).
# Usage: build-deb.sh BUILD_DIR OUT_DIR     prints the path of the package it wrote
# Exit 0 written; 1 a step failed; 2 usage or a missing tool (dpkg-deb, dpkg-shlibdeps, gzip, strip).
set -euo pipefail
umask 022
[ $# -eq 2 ] || { echo "usage: build-deb.sh BUILD_DIR OUT_DIR" >&2; exit 2; }
build="$(cd "$1" && pwd)"
mkdir -p "$2"
out="$(cd "$2" && pwd)"
here="$(cd "$(dirname "$0")" && pwd)"
for t in dpkg-deb dpkg-shlibdeps dpkg-architecture gzip strip; do
  command -v "$t" >/dev/null || { echo "build-deb.sh: $t not found (apt-get install dpkg-dev binutils)" >&2; exit 2; }
done
work="$(mktemp -d /tmp/haptic-deb.XXXXXX)"
trap 'rm -rf "$work"' EXIT
root="$work/root"
pkg=haptic-station
# Who answers for this build (Maintainer, changelog): HAPTIC_DEB_MAINTAINER="Name <mail>", else the
# author of the newest commit of the tree when it is a git checkout.
maintainer="${HAPTIC_DEB_MAINTAINER:-}"
if [ -z "$maintainer" ] && src=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$build/CMakeCache.txt") && [ -n "$src" ]; then
  maintainer=$(git -C "$src" log -1 --format='%an <%ae>' 2>/dev/null || true)
fi
[ -n "$maintainer" ] || { echo "build-deb.sh: set HAPTIC_DEB_MAINTAINER=\"Name <mail>\" (no git history to take it from)" >&2; exit 2; }
doc="$root/usr/share/doc/$pkg"

DESTDIR="$root" cmake --install "$build" --prefix /usr >"$work/install.log" ||
  { cat "$work/install.log" >&2; echo "build-deb.sh: cmake --install failed" >&2; exit 1; }
[ -d "$doc" ] || { echo "build-deb.sh: no $doc (CMAKE_INSTALL_DOCDIR must be share/doc/$pkg)" >&2; exit 1; }

# Version: the project's and git describe, as --version prints them ("0.1.0 (git 63c9b84-dirty, ...").
line=$("$root/usr/bin/haptic-station" --version)
[[ "$line" =~ ^haptic-station\ ([0-9.]+)\ \(git\ ([^,]+), ]] || { echo "build-deb.sh: cannot read the version from: $line" >&2; exit 1; }
version="${BASH_REMATCH[1]}"
describe="${BASH_REMATCH[2]}"
[ "$describe" = unknown ] || [ "$describe" = "v$version" ] || [ "$describe" = "$version" ] ||
  version="$version+git.$(printf '%s' "${describe#v}" | tr -c 'A-Za-z0-9.+~\n' '.')"  # native: no '-' in the version
arch=$(dpkg-architecture -qDEB_HOST_ARCH)

# Debian's habits: stripped binaries, copyright and a compressed changelog, big docs compressed.
for f in "$root"/usr/bin/*; do
  if [ "$(head -c 4 "$f" | od -An -c | tr -d ' ')" = '177ELF' ]; then
    strip --strip-unneeded --remove-section=.comment --remove-section=.note "$f"
  fi
done
# Only programs are executable (the web view's .html/.js are installed with the scripts).
find "$root/usr/share" -type f -perm /111 | while read -r f; do
  [ "$(head -c 2 "$f")" = '#!' ] || chmod 0644 "$f"
done
install -m 0644 "$here/copyright" "$doc/copyright"
printf '%s (%s) unstable; urgency=medium\n\n  * Built from the source tree at %s (tools/package/build-deb.sh).\n\n -- %s  %s\n' \
  "$pkg" "$version" "$describe" "$maintainer" "$(date -u -R)" | gzip -9n >"$doc/changelog.gz"
# deploy-README.md stays as it is: the unit's Documentation= names it.
find "$doc" -type f -size +4k ! -name copyright ! -name '*.gz' ! -name deploy-README.md -exec gzip -9n {} +

# Manual pages (policy 12.1), from each program's --help: summary, the whole help text, see also.
declare -A summary=(
  [haptic-station]="a station of the consensus-based peer-to-peer multi-user haptics runtime"
  [haptic-lab]="plan, check, start and collect a whole lab of haptic stations from one file"
  [haptic-topology]="rank network topologies by the consensus spectrum (eq. 27)"
  [haptic-devices]="list haptic devices, their access rights and udev fixes; device diagnostics"
  [haptic-keygen]="create station key files for a haptic lab"
  [haptic-jitter]="wake-up latency of the station's periodic real-time loop"
  [haptic-study]="speed against accuracy studies of the haptic object model")
mkdir -p "$root/usr/share/man/man1"
for f in "$root"/usr/bin/*; do
  name=$(basename "$f")
  [ -n "${summary[$name]:-}" ] || { echo "build-deb.sh: no manual page summary for $name (add it to build-deb.sh)" >&2; exit 1; }
  help=$(HAPTIC_BIN_DIR="$root/usr/bin" "$f" --help 2>&1) || { echo "build-deb.sh: $name --help failed" >&2; exit 1; }
  upper=$(printf '%s' "$name" | tr a-z A-Z)
  {
    printf '.TH %s 1 "%s" "haptic-station %s" "User Commands"\n' "$upper" "$(date -u +%Y-%m-%d)" "$version"
    printf '.SH NAME\n%s \\- %s\n.SH DESCRIPTION\n.nf\n' "$name" "${summary[$name]}"
    printf '%s\n' "$help" | sed -e 's/\\/\\e/g' -e "s/^\([.']\)/\\\\\&\1/"
    printf '.fi\n.SH SEE ALSO\n/usr/share/doc/haptic-station/ (README.md, deploy-README.md, lab-README.md)\n'
  } | gzip -9n >"$root/usr/share/man/man1/$name.1.gz"
done

# Control files.
mkdir -p "$root/DEBIAN" "$work/shlibs/debian"
printf 'Source: %s\n\nPackage: %s\nArchitecture: any\n' "$pkg" "$pkg" >"$work/shlibs/debian/control"
elves=()
for f in "$root"/usr/bin/*; do
  [ "$(head -c 4 "$f" | od -An -c | tr -d ' ')" = '177ELF' ] && elves+=("$f")
done
shlibs=$(cd "$work/shlibs" && dpkg-shlibdeps -O "${elves[@]}" 2>"$work/shlibdeps.log") ||
  { cat "$work/shlibdeps.log" >&2; echo "build-deb.sh: dpkg-shlibdeps failed" >&2; exit 1; }
shlibs="${shlibs#shlibs:Depends=}"
size=$(du -sk --exclude=DEBIAN "$root" | cut -f1)
cat >"$root/DEBIAN/control" <<EOF
Package: $pkg
Version: $version
Architecture: $arch
Maintainer: $maintainer
Installed-Size: $size
Depends: $shlibs, adduser, python3
Recommends: python3-matplotlib, python3-numpy
Suggests: cyclictest | rt-tests, lttng-tools
Section: science
Priority: optional
Description: consensus-based peer-to-peer multi-user haptics station
 One station of a lab of haptic stations that share one deformable virtual
 object (Huang & Lee, IEEE T-RO 2013): the real-time station (haptic-station,
 run as the systemd unit haptic-station@N), its simulator, the lab planner and
 launcher (haptic-lab), the topology optimizer, device diagnostics, the jitter
 check, the udev rules for the supported devices, a sysctl drop-in for
 SCHED_FIFO, example labs and the deployment guide.
EOF
cat >"$root/DEBIAN/postinst" <<'EOF'
#!/bin/sh
# haptic-station postinst: the system user the unit runs as, the configuration directory, and
# systemd/udev/sysctl told about the new files. Nothing is enabled or started (the operator runs
# `systemctl enable --now haptic-station@N` once /etc/haptic/station-N.toml is written).
set -e
if [ "$1" = configure ]; then
  if ! getent passwd haptic >/dev/null; then
    adduser --system --group --no-create-home --home /nonexistent --gecos "haptic station" --quiet haptic
  fi
  if [ ! -d /etc/haptic ]; then
    install -d -m 0750 -o root -g haptic /etc/haptic
  fi
  if [ -d /run/systemd/system ]; then
    systemctl --system daemon-reload >/dev/null || true
  fi
  if [ -d /run/udev ] && command -v udevadm >/dev/null; then
    udevadm control --reload-rules || true
    udevadm trigger --subsystem-match=usb --subsystem-match=hidraw --subsystem-match=tty --action=change || true
  fi
  if [ -d /run/systemd/system ] && command -v /lib/systemd/systemd-sysctl >/dev/null; then
    /lib/systemd/systemd-sysctl /usr/lib/sysctl.d/90-haptic.conf || true
  fi
fi
exit 0
EOF
cat >"$root/DEBIAN/postrm" <<'EOF'
#!/bin/sh
# haptic-station postrm: systemd forgets the removed unit. The user 'haptic', /etc/haptic (keys and
# station files) and /var/lib/haptic (the stations' outputs) are kept, also on purge: they are the lab's.
set -e
if [ -d /run/systemd/system ]; then
  systemctl --system daemon-reload >/dev/null || true
fi
exit 0
EOF
chmod 0755 "$root/DEBIAN/postinst" "$root/DEBIAN/postrm"
(cd "$root" && find . -path ./DEBIAN -prune -o -type f -printf '%P\0' | sort -z | xargs -0 md5sum) >"$root/DEBIAN/md5sums"

deb="$out/${pkg}_${version}_${arch}.deb"
dpkg-deb -Zxz --root-owner-group --build "$root" "$deb" >/dev/null
echo "$deb"
