# Debian package for the robot computer: `cpack --preset arm64` (or `--preset release` for
# amd64) writes rankslam_<version>_<arch>.deb into <build dir>/packages, holding the rankslam
# binary, the default configuration, the CAN database and, when deploy/ has them, the systemd
# units with their helper, the udev rules and the reference configuration files.
# Its Depends are computed from the binary by dpkg-shlibdeps (deploy/shlibdeps.sh): for a cross
# build against the sysroot's dpkg database, so they name the robot's Debian packages.
#
# Included at the end of the top-level CMakeLists.txt, after every install() rule.

if(NOT TARGET rankslam)
  message(STATUS "Packaging: no rankslam executable in this configuration, no package")
  return()
endif()

# Systemd units, their helper programs and udev rules, packaged where Debian's systemd and udev
# read them. Units written for a hand install name helpers under /usr/local; a package installs
# under /usr, so the packaged copies name /usr/lib/rankslam instead (these rules are meant for
# the package's /usr prefix; `cmake --install` elsewhere gets units naming /usr paths).
file(GLOB _rankslam_units CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/deploy/systemd/*.service)
file(GLOB _rankslam_udev_rules CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/deploy/udev/*.rules)
file(GLOB _rankslam_systemd_files CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/deploy/systemd/*)
foreach(_unit IN LISTS _rankslam_units)
  get_filename_component(_name ${_unit} NAME)
  file(READ ${_unit} _text)
  string(REPLACE "/usr/local/lib/rankslam/" "/usr/lib/rankslam/" _text "${_text}")
  string(REPLACE "/usr/local/bin/" "/usr/bin/" _text "${_text}")
  file(WRITE ${CMAKE_BINARY_DIR}/deb/systemd/${_name} "${_text}")
  install(FILES ${CMAKE_BINARY_DIR}/deb/systemd/${_name} DESTINATION lib/systemd/system)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${_unit})
endforeach()
set(_rankslam_helpers "")
foreach(_file IN LISTS _rankslam_systemd_files)
  if(NOT _file MATCHES "\\.(service|socket|timer|path|target)$" AND NOT IS_DIRECTORY ${_file})
    list(APPEND _rankslam_helpers ${_file})
  endif()
endforeach()
if(_rankslam_helpers)
  install(PROGRAMS ${_rankslam_helpers} DESTINATION lib/rankslam)
endif()
if(_rankslam_udev_rules)
  install(FILES ${_rankslam_udev_rules} DESTINATION lib/udev/rules.d)
endif()
# Reference files an integrator copies and edits: the example robot configuration and the
# systemd-networkd alternative to the CAN link unit.
file(GLOB _rankslam_example_configs CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/deploy/config/*.yaml)
list(FILTER _rankslam_example_configs EXCLUDE REGEX "/default\\.yaml$")  # top level installs it
if(_rankslam_example_configs)
  install(FILES ${_rankslam_example_configs} DESTINATION share/rankslam/config)
endif()
# The configuration the service runs with, ready for the robot as installed (first OpenNI2
# sensor; the CAN interface is the unit's instance): a conffile, so dpkg keeps local edits.
install(FILES ${PROJECT_SOURCE_DIR}/deploy/config/example-robot.yaml DESTINATION /etc/rankslam RENAME robot.yaml)
file(WRITE ${CMAKE_BINARY_DIR}/deb/conffiles "/etc/rankslam/robot.yaml\n")
# The units' Documentation= points here; the README's links to docs/ resolve beside it.
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION share/doc/rankslam)
install(FILES ${PROJECT_SOURCE_DIR}/docs/methods.md ${PROJECT_SOURCE_DIR}/docs/results.md DESTINATION share/doc/rankslam/docs)
file(GLOB _rankslam_networkd CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/deploy/network/*.network)
if(_rankslam_networkd)
  install(FILES ${_rankslam_networkd} DESTINATION share/rankslam/network)
endif()

# Debian architecture of the binaries being packaged.
if(CMAKE_CROSSCOMPILING)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
    set(_rankslam_deb_arch arm64)
  else()
    message(FATAL_ERROR "Packaging: no Debian architecture known for ${CMAKE_SYSTEM_PROCESSOR}")
  endif()
else()
  find_program(RANKSLAM_DPKG dpkg)
  if(RANKSLAM_DPKG)
    execute_process(COMMAND ${RANKSLAM_DPKG} --print-architecture
                    OUTPUT_VARIABLE _rankslam_deb_arch OUTPUT_STRIP_TRAILING_WHITESPACE)
  else()
    set(_rankslam_deb_arch amd64)
  endif()
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME rankslam)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Visual SLAM for indoor robots (RGB-D, fisheye and wheel odometry; pose over CAN)")
set(CPACK_PACKAGE_DESCRIPTION
    "rankslam estimates the robot's pose from a Kinect RGB-D camera, a wide-angle fisheye camera and wheel odometry on SocketCAN, and sends it to the base controller over CAN. The same binary replays recorded sensor streams. Includes the default configuration (/usr/share/rankslam/config) and the CAN database (/usr/share/rankslam/can).")
set(RANKSLAM_PACKAGE_MAINTAINER "rankslam maintainers <rankslam@invalid>" CACHE STRING
    "Maintainer field of the Debian package")
set(CPACK_PACKAGE_CONTACT "${RANKSLAM_PACKAGE_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${RANKSLAM_PACKAGE_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${_rankslam_deb_arch})
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # rankslam_<version>_<arch>.deb
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # the build tree keeps the debug info; CMAKE_STRIP is the target's
set(CPACK_OUTPUT_FILE_PREFIX ${CMAKE_BINARY_DIR}/packages)

# Maintainer scripts, only for what the package holds: the service's system user (the units run
# as User=rankslam), and systemd and udev told about new or removed units and rules. Nothing
# is enabled or started: that is the integrator's choice (README, "Deploying to the robot").
set(_rankslam_extra_depends "")
if(_rankslam_units OR _rankslam_udev_rules)
  set(_postinst "#!/bin/sh\nset -e\n")
  set(_postrm "#!/bin/sh\nset -e\n")
  if(_rankslam_units)
    string(APPEND _postinst
      "if [ \"$1\" = configure ] && ! getent passwd rankslam >/dev/null; then\n"
      "  adduser --system --group --home /var/lib/rankslam --no-create-home rankslam\n"
      "fi\n"
      "if [ -d /run/systemd/system ]; then systemctl daemon-reload || true; fi\n")
    string(APPEND _postrm
      "if [ -d /run/systemd/system ]; then systemctl daemon-reload || true; fi\n")
    list(APPEND _rankslam_extra_depends adduser)
  endif()
  if(_rankslam_helpers)
    list(APPEND _rankslam_extra_depends iproute2)  # the CAN link helper runs ip(8)
  endif()
  if(_rankslam_udev_rules)
    set(_reload_udev
        "if command -v udevadm >/dev/null 2>&1; then udevadm control --reload-rules || true; fi\n")
    string(APPEND _postinst "${_reload_udev}")
    string(APPEND _postrm "${_reload_udev}")
  endif()
  file(WRITE ${CMAKE_BINARY_DIR}/deb/postinst "${_postinst}")
  file(WRITE ${CMAKE_BINARY_DIR}/deb/postrm "${_postrm}")
  foreach(_script postinst postrm)
    file(CHMOD ${CMAKE_BINARY_DIR}/deb/${_script}
         PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE
                     WORLD_READ WORLD_EXECUTE)
  endforeach()
  set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
      ${CMAKE_BINARY_DIR}/deb/postinst ${CMAKE_BINARY_DIR}/deb/postrm)
endif()
list(APPEND CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA ${CMAKE_BINARY_DIR}/deb/conffiles)
list(JOIN _rankslam_extra_depends ", " _rankslam_extra_depends)

# Depends, computed when cpack runs (the binary exists only after the build).
set(_rankslam_shlibdeps_args "")
if(CMAKE_CROSSCOMPILING)
  if(NOT CMAKE_SYSROOT)
    message(FATAL_ERROR "Packaging a cross build needs CMAKE_SYSROOT (the toolchain file sets it)")
  endif()
  set(_rankslam_shlibdeps_args
      --sysroot "${CMAKE_SYSROOT}" --arch ${_rankslam_deb_arch} --multiarch ${CMAKE_LIBRARY_ARCHITECTURE})
endif()
list(JOIN _rankslam_shlibdeps_args "\" \"" _rankslam_shlibdeps_args)
if(_rankslam_shlibdeps_args)
  set(_rankslam_shlibdeps_args "\"${_rankslam_shlibdeps_args}\"")
endif()
file(GENERATE OUTPUT ${CMAKE_BINARY_DIR}/CPackProjectConfig.cmake CONTENT
"# Generated by deploy/packaging.cmake: read by cpack before it builds the package.
if(CPACK_GENERATOR STREQUAL \"DEB\")
  execute_process(
    COMMAND \"${PROJECT_SOURCE_DIR}/deploy/shlibdeps.sh\" ${_rankslam_shlibdeps_args} \"$<TARGET_FILE:rankslam>\"
    OUTPUT_VARIABLE CPACK_DEBIAN_PACKAGE_DEPENDS OUTPUT_STRIP_TRAILING_WHITESPACE
    RESULT_VARIABLE _result)
  if(NOT _result EQUAL 0 OR CPACK_DEBIAN_PACKAGE_DEPENDS STREQUAL \"\")
    message(FATAL_ERROR \"Could not compute the package's Depends (deploy/shlibdeps.sh)\")
  endif()
  if(NOT \"${_rankslam_extra_depends}\" STREQUAL \"\")
    string(APPEND CPACK_DEBIAN_PACKAGE_DEPENDS \", ${_rankslam_extra_depends}\")
  endif()
endif()
")
set(CPACK_PROJECT_CONFIG_FILE ${CMAKE_BINARY_DIR}/CPackProjectConfig.cmake)

include(CPack)
