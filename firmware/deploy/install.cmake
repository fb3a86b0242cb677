# Install rules of the deployment files; the top level includes this file:
#   include(firmware/deploy/install.cmake)
# then `cmake --install build --prefix P` (station binaries come from their own install(TARGETS)).
include(GNUInstallDirs)
set(_deploy "${CMAKE_CURRENT_LIST_DIR}")
# System files (systemd unit, udev rules, sysctl drop-in, the stations' configuration directory)
# go under the install prefix (P/lib/systemd/system, P/lib/udev/rules.d, P/lib/sysctl.d,
# P/etc/haptic), so `cmake --install build --prefix P` writes nothing outside P. On a lab PC,
# -DHAPTIC_SYSTEM_FILES_IN_ETC=ON puts them where systemd, udev and sysctl read them:
# /etc/systemd/system, /etc/udev/rules.d, /etc/sysctl.d, and the unit reads /etc/haptic/.
option(HAPTIC_SYSTEM_FILES_IN_ETC "Install the systemd unit, udev rules and sysctl drop-in to /etc (default: under the install prefix)" OFF)
if(HAPTIC_SYSTEM_FILES_IN_ETC)
  set(_unit_dir "/etc/systemd/system")
  set(_udev_dir "/etc/udev/rules.d")
  set(_sysctl_dir "/etc/sysctl.d")
  set(_haptic_CONFDIR "/etc/haptic")
else()
  set(_unit_dir "lib/systemd/system")
  set(_udev_dir "lib/udev/rules.d")
  set(_sysctl_dir "lib/sysctl.d")
  set(_haptic_CONFDIR "\${CMAKE_INSTALL_PREFIX}/etc/haptic")
endif()
set(HAPTIC_SYSTEMD_UNIT_DIR "${_unit_dir}" CACHE PATH "Where haptic-station@.service is installed (relative: under the prefix)" FORCE)
set(HAPTIC_UDEV_RULES_DIR "${_udev_dir}" CACHE PATH "Where 99-haptic.rules is installed (relative: under the prefix)" FORCE)
set(HAPTIC_SYSCTL_DIR "${_sysctl_dir}" CACHE PATH "Where 90-haptic.conf is installed (relative: under the prefix)" FORCE)
# The unit names the binary and the configuration directory by absolute path. It is generated at
# install time, so it points into the prefix actually installed to (`cmake --install build
# --prefix P`), not the configure-time CMAKE_INSTALL_PREFIX.
foreach(_kind BINDIR DOCDIR)
  if(IS_ABSOLUTE "${CMAKE_INSTALL_${_kind}}")
    set(_haptic_${_kind} "${CMAKE_INSTALL_${_kind}}")
  else()
    set(_haptic_${_kind} "\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_${_kind}}")
  endif()
endforeach()
# An install to the prefix /usr (a distribution package: tools/package/build-deb.sh) reads its
# configuration from /etc/haptic, as GNUInstallDirs puts SYSCONFDIR for /usr.
install(CODE "
  set(HAPTIC_INSTALL_BINDIR \"${_haptic_BINDIR}\")
  set(HAPTIC_INSTALL_DOCDIR \"${_haptic_DOCDIR}\")
  set(HAPTIC_INSTALL_CONFDIR \"${_haptic_CONFDIR}\")
  if(CMAKE_INSTALL_PREFIX STREQUAL \"/usr\")
    set(HAPTIC_INSTALL_CONFDIR \"/etc/haptic\")
  endif()
  configure_file(\"${_deploy}/haptic-station@.service.in\" \"${PROJECT_BINARY_DIR}/deploy/haptic-station@.service\" @ONLY)
" COMPONENT deploy)
install(FILES "${PROJECT_BINARY_DIR}/deploy/haptic-station@.service" DESTINATION "${HAPTIC_SYSTEMD_UNIT_DIR}" COMPONENT deploy)
install(FILES "${_deploy}/99-haptic.rules" DESTINATION "${HAPTIC_UDEV_RULES_DIR}" COMPONENT deploy)
install(FILES "${_deploy}/sysctl-haptic.conf" DESTINATION "${HAPTIC_SYSCTL_DIR}" RENAME 90-haptic.conf COMPONENT deploy)
install(DIRECTORY "${_deploy}/lab-4-stations" DESTINATION "${CMAKE_INSTALL_DATADIR}/haptic/examples" COMPONENT deploy)
install(FILES "${_deploy}/README.md" DESTINATION "${CMAKE_INSTALL_DOCDIR}" RENAME deploy-README.md COMPONENT deploy)
install(PROGRAMS "${_deploy}/../../tools/trace/record.sh" "${_deploy}/../../tools/trace/analyze.py"
        DESTINATION "${CMAKE_INSTALL_DATADIR}/haptic/tools/trace" COMPONENT deploy)
