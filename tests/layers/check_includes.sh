#!/usr/bin/env bash
# Layering check (DESIGN.md "dependencies point downward only"): every project include in a
# folder's sources (the folder and everything below it) names a folder that folder may use.
#   rt/                 -> rt/                      (plus Eigen and the standard library)
#   platform/           -> platform/                (plus the OS)
#   net/                -> net/ platform/
#   drivers/            -> drivers/ platform/ rt/
#   firmware/model/     -> firmware/model/ rt/      (the paper's model, computed once)
#   firmware/scene/     -> firmware/scene/ rt/
#   firmware/scenario.* -> firmware/{scenario,model,scene} net/ platform/ rt/
#   firmware/session/   -> firmware/session/ platform/ rt/
#   firmware/view/      -> firmware/{view,session,model} platform/ rt/
#   firmware/run/       -> firmware/{run,scenario,model,scene} platform/ rt/
#   firmware/station/   -> firmware/ but sim/, net/ drivers/ platform/ rt/
#   firmware/sim/, firmware/*_main.cpp -> firmware/ net/ drivers/ platform/ rt/   (never tools/ or tests/)
# and no Eigen include in platform/ or net/, and their CMake targets link neither haptic_rt nor
# Eigen. Prints every offending line; exit 1 if any.
# Usage: check_includes.sh SOURCE_DIR
set -euo pipefail
src="${1:?usage: check_includes.sh SOURCE_DIR}"
cd "$src"
bad=0
check() {  # check NAME ALLOWED_REGEX PATH...   (PATH: folders, searched recursively, or files)
  local name="$1" allowed="$2" hits
  shift 2
  hits=$(grep -rHnE --include='*.hpp' --include='*.cpp' --include='*.h' \
           '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$@" 2>/dev/null |
         grep -vE "#[[:space:]]*include[[:space:]]*\"($allowed)[/.]" || true)
  if [ -n "$hits" ]; then
    echo "$name includes outside its layer (allowed: $allowed):"
    echo "$hits"
    bad=1
  fi
}
fw=firmware
check rt/ 'rt' rt
check platform/ 'platform' platform
check net/ 'net|platform' net
check drivers/ 'drivers|platform|rt' drivers
check $fw/model/ "$fw/model|rt" $fw/model
check $fw/scene/ "$fw/scene|rt" $fw/scene
check $fw/scenario "$fw/scenario|$fw/model|$fw/scene|net|platform|rt" $fw/scenario.hpp $fw/scenario.cpp
check $fw/session/ "$fw/session|platform|rt" $fw/session
check $fw/view/ "$fw/view|$fw/session|$fw/model|platform|rt" $fw/view
check $fw/run/ "$fw/run|$fw/scenario|$fw/model|$fw/scene|platform|rt" $fw/run
check $fw/station/ "$fw/station|$fw/run|$fw/view|$fw/session|$fw/scenario|$fw/model|$fw/scene|net|drivers|platform|rt" $fw/station
check $fw/ "$fw|net|drivers|platform|rt" $fw
# Every source file of firmware/ belongs to one of the parts above (a new folder gets its rule here).
stray=$(find $fw -name '*.cpp' -o -name '*.hpp' | grep -vE "^$fw/(model|scene|session|view|run|station|sim)/|^$fw/scenario\.(hpp|cpp)$|^$fw/[a-z_]+_main\.cpp$" || true)
if [ -n "$stray" ]; then
  echo "firmware/ sources outside its parts (model scene session view run station sim, scenario.*, *_main.cpp):"
  echo "$stray"
  bad=1
fi
eigen=$(grep -rHnE --include="*.hpp" --include="*.cpp" --include="*.h" '#[[:space:]]*include[[:space:]]*<(Eigen|unsupported/Eigen)' platform net 2>/dev/null || true)
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
[ "$bad" -eq 0 ] && echo "layers: every include points downward (rt, platform, net, drivers and each part of firmware checked)"
exit "$bad"
