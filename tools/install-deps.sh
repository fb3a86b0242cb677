#!/usr/bin/env bash
# Installs the Debian 12 packages that the build, the tests and the main job need.
# Run as root on a fresh machine:  tools/install-deps.sh
set -euo pipefail
if [ "$(id -u)" -ne 0 ]; then
  echo "install-deps.sh: run as root (it calls apt-get)" >&2; exit 1
fi
export DEBIAN_FRONTEND=noninteractive
PKGS=(
  # build
  build-essential cmake ninja-build pkg-config git
  # compiler cache: the mutation suite's lean build reuses the main build's objects (tools/test.sh)
  ccache
  # the Debian package and its checks (tools/package, tests/tools/package/deb_check.sh): lintian, systemd-analyze
  lintian systemd
  # core libraries
  libeigen3-dev libtomlplusplus-dev libcli11-dev libsodium-dev
  # devices
  libusb-1.0-0-dev libhidapi-dev umockdev libumockdev-dev
  # platform: GPIO, tracing, jitter reference
  libgpiod-dev gpiod liblttng-ust-dev lttng-tools babeltrace2 python3-bt2 rt-tests
  # tests, benchmarks, fuzzing
  cpputest libbenchmark-dev clang libclang-rt-14-dev
  # CHOLMOD: the prefactored sparse baseline in bench-rt-tick
  libsuitesparse-dev
  # network tests and wire inspection
  iproute2 tshark
  # plots and reports (Debian's python3, /usr/bin/python3)
  python3 python3-matplotlib python3-numpy
  # topology optimizer: JSON in/out (tools/topology)
  nlohmann-json3-dev
  # network namespace reachability check (tools/netns/netns.sh check)
  iputils-ping
  # session logs and bit-exact replay (firmware/session/log.hpp): HDF5, xxHash state hashes, h5py readers
  libhdf5-dev libxxhash-dev python3-h5py
  # scenes from files: TetGen tetrahedralizes surface meshes; Gmsh makes the tests' meshes
  tetgen gmsh
  # live web view (firmware/view/server.hpp, tools/view/): libwebsockets, three.js, Chart.js (local, no CDN);
  # chromium for its headless test (tests/firmware/view/view_check.sh; a visible skip without it)
  libwebsockets-dev libjs-three libjs-chart.js chromium
)
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${PKGS[@]}"
echo "install-deps.sh: installed ${#PKGS[@]} packages"
