#!/usr/bin/env bash
# Layering check (DESIGN.md "dependencies point downward only"): every project include in a
# layer's sources names a folder that layer may use.
#   rt/       -> rt/                      (plus Eigen and the standard library)
#   platform/ -> platform/                (plus the OS)
#   net/      -> net/ platform/
#   drivers/  -> drivers/ platform/ rt/
#   firmware/ -> firmware/ net/ drivers/ platform/ rt/   (never tools/ or tests/)
#   firmware/model/ -> firmware/model/ rt/   (the paper's model uses rt/ only; everything above calls it)
# and no Eigen include in platform/ or net/, and their CMake targets link neither haptic_rt nor
# Eigen. Prints every offending line; exit 1 if any.
# Usage: check_includes.sh SOURCE_DIR
set -euo pipefail
src="${1:?usage: check_includes.sh SOURCE_DIR}"
cd "$src"
bad=0
check() {  # check LAYER ALLOWED_REGEX
  local layer="$1" allowed="$2" hits
  # Only the layer's own files (sub-folders such as net/tools are executables, not the library).
  hits=$(grep -HnE '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$layer"/*.hpp "$layer"/*.cpp "$layer"/*.h 2>/dev/null |
         grep -vE "#[[:space:]]*include[[:space:]]*\"($allowed)/" || true)
  if [ -n "$hits" ]; then
    echo "$layer/ includes outside its layer (allowed: $allowed):"
    echo "$hits"
    bad=1
  fi
}
check rt 'rt'
check platform 'platform'
check net 'net|platform'
check drivers 'drivers|platform|rt'
check firmware 'firmware|net|drivers|platform|rt'
check firmware/model 'firmware/model|rt'
eigen=$(grep -HnE '#[[:space:]]*include[[:space:]]*<(Eigen|unsupported/Eigen)' platform/*.hpp platform/*.cpp platform/*.h net/*.hpp net/*.cpp 2>/dev/null || true)
if [ -n "$eigen" ]; then
  echo "platform/ or net/ includes Eigen:"
  echo "$eigen"
  bad=1
fi
# The libraries too: haptic_platform and haptic_net link neither haptic_rt nor Eigen.
links=$(grep -HnE 'haptic_rt|Eigen3::' platform/CMakeLists.txt net/CMakeLists.txt | grep -v '^[^:]*:[0-9]*:[[:space:]]*#' || true)
if [ -n "$links" ]; then
  echo "platform/ or net/ links the real-time core or Eigen:"
  echo "$links"
  bad=1
fi
[ "$bad" -eq 0 ] && echo "layers: every include points downward (rt, platform, net, drivers, firmware, firmware/model checked)"
exit "$bad"
