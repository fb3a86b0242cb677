# Install rules of the deployment files; the top level includes this file:
#   include(firmware/deploy/install.cmake)
# then `cmake --install build --prefix /usr/local` (station binaries come from their own
# install(TARGETS)). Directories follow the GNU layout; systemd and udev want their files
# under /usr/lib or /etc regardless of the prefix, so those two paths are absolute by default.
include(GNUInstallDirs)
set(_deploy "${CMAKE_CURRENT_LIST_DIR}")
set(HAPTIC_SYSTEMD_UNIT_DIR "/etc/systemd/system" CACHE PATH "Where haptic-station@.service is installed")
set(HAPTIC_UDEV_RULES_DIR "/etc/udev/rules.d" CACHE PATH "Where 99-haptic.rules is installed")
set(HAPTIC_SYSCTL_DIR "/etc/sysctl.d" CACHE PATH "Where 90-haptic.conf is installed")
# The unit names the binary by absolute path. It is generated at install time, so it points into
# the prefix actually installed to (`cmake --install build --prefix P`), not the configure-time
# CMAKE_INSTALL_PREFIX.
foreach(_kind BINDIR DOCDIR)
  if(IS_ABSOLUTE "${CMAKE_INSTALL_${_kind}}")
    set(_haptic_${_kind} "${CMAKE_INSTALL_${_kind}}")
  else()
    set(_haptic_${_kind} "\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_${_kind}}")
  endif()
endforeach()
install(CODE "
  set(HAPTIC_INSTALL_BINDIR \"${_haptic_BINDIR}\")
  set(HAPTIC_INSTALL_DOCDIR \"${_haptic_DOCDIR}\")
  configure_file(\"${_deploy}/haptic-station@.service.in\" \"${PROJECT_BINARY_DIR}/deploy/haptic-station@.service\" @ONLY)
" COMPONENT deploy)
install(FILES "${PROJECT_BINARY_DIR}/deploy/haptic-station@.service" DESTINATION "${HAPTIC_SYSTEMD_UNIT_DIR}" COMPONENT deploy)
install(FILES "${_deploy}/99-haptic.rules" DESTINATION "${HAPTIC_UDEV_RULES_DIR}" COMPONENT deploy)
install(FILES "${_deploy}/sysctl-haptic.conf" DESTINATION "${HAPTIC_SYSCTL_DIR}" RENAME 90-haptic.conf COMPONENT deploy)
install(DIRECTORY "${_deploy}/lab-4-stations" DESTINATION "${CMAKE_INSTALL_DATADIR}/haptic/examples" COMPONENT deploy)
install(FILES "${_deploy}/README.md" DESTINATION "${CMAKE_INSTALL_DOCDIR}" RENAME deploy-README.md COMPONENT deploy)
install(PROGRAMS "${_deploy}/../../tools/trace/record.sh" "${_deploy}/../../tools/trace/analyze.py"
        DESTINATION "${CMAKE_INSTALL_DATADIR}/haptic/tools/trace" COMPONENT deploy)
