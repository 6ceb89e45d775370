# The Debian package evpipe_<version>_<arch>.deb (CPack DEB), from a tree configured with the `deb` preset: prefix
# /usr, configuration in /etc/evpipe (conffiles), unit in /lib/systemd/system, udev rule in /lib/udev/rules.d, LCM
# types and the lcm-spy jar in /usr/share/evpipe, docs in /usr/share/doc/evpipe; Depends computed by dpkg-shlibdeps;
# maintainer scripts in config/deb/. docs/operations.md ("Install") gives the steps, tools/check_deb.sh checks them.
#
#   cmake --preset deb && cmake --build --preset deb && cpack --preset deb      (or: cmake --workflow --preset deb)

set(EVPIPE_DEB_MAINTAINER "evpipe maintainers <evpipe@example.com>" CACHE STRING
    "Maintainer field of the Debian package (\"Name <mail>\"); set it for a release")
set(EVPIPE_DEB_VERSION "${PROJECT_VERSION}")
set(_deb_dir "${PROJECT_BINARY_DIR}/deb")
set(_deb_src "${PROJECT_SOURCE_DIR}/config/deb")

# /usr/share/doc/evpipe/{copyright,changelog.gz}: Debian policy (lintian: no-copyright-file, no-changelog). The
# changelog's date is the configure time (SOURCE_DATE_EPOCH when set), compressed with gzip -9n as policy asks.
string(TIMESTAMP EVPIPE_DEB_DATE "%a, %d %b %Y %H:%M:%S +0000" UTC)
configure_file(${_deb_src}/changelog.in ${_deb_dir}/changelog @ONLY)
find_program(EVPIPE_GZIP gzip REQUIRED)
add_custom_command(OUTPUT ${_deb_dir}/changelog.gz
  COMMAND ${EVPIPE_GZIP} -9nc ${_deb_dir}/changelog > ${_deb_dir}/changelog.gz
  DEPENDS ${_deb_dir}/changelog
  COMMENT "changelog.gz for the Debian package"
  VERBATIM)
add_custom_target(evpipe_deb_changelog ALL DEPENDS ${_deb_dir}/changelog.gz)
install(FILES ${_deb_src}/copyright ${_deb_dir}/changelog.gz DESTINATION ${CMAKE_INSTALL_DOCDIR})

# A libcaer outside the dynamic linker's default folders, without an RPATH (EVPIPE_LIBCAER_RPATH=OFF, the deb
# preset: lintian rejects custom RPATHs): the package ships an ld.so.conf.d entry for its folder instead.
set(_deb_ldconf "")
if(EVPIPE_WITH_LIBCAER AND EVPIPE_LIBCAER_LIBDIR_EXTRA AND NOT EVPIPE_LIBCAER_RPATH)
  file(WRITE ${_deb_dir}/evpipe-libcaer.conf
       "# libcaer for evpipe (installed outside the dynamic linker's default folders)\n${EVPIPE_LIBCAER_LIBDIR}\n")
  install(FILES ${_deb_dir}/evpipe-libcaer.conf DESTINATION /etc/ld.so.conf.d)
  set(_deb_ldconf /etc/ld.so.conf.d/evpipe-libcaer.conf)
  # lintian reports both ways of reaching a library outside the linker's folders as errors (an RPATH:
  # custom-library-search-path; this entry: package-modifies-ld.so-search-path). The entry is the one needed here
  # (libcaer is not a Debian package and lies where the operator installed it), so the package says so in
  # lintian's overrides. The documented install (libcaer in /usr/local, operations.md) needs neither.
  file(WRITE ${_deb_dir}/lintian-overrides
       "# libcaer (not in Debian) was installed under ${EVPIPE_LIBCAER_LIBDIR}: evpipe's programs find it through\n"
       "# this entry; no RPATH (cmake/EvpipePackaging.cmake).\n"
       "evpipe: package-modifies-ld.so-search-path [etc/ld.so.conf.d/evpipe-libcaer.conf]\n"
       "# The ldconfig trigger makes the entry above take effect (the package has no shared library itself).\n"
       "evpipe: package-has-unnecessary-activation-of-ldconfig-trigger\n")
  install(FILES ${_deb_dir}/lintian-overrides DESTINATION ${CMAKE_INSTALL_DATADIR}/lintian/overrides RENAME evpipe)
endif()

# conffiles: every file the package puts in /etc (dpkg keeps an edited one on upgrade and removes them on purge).
set(_deb_conffiles "")
file(GLOB _deb_config_files RELATIVE ${PROJECT_SOURCE_DIR}/config ${PROJECT_SOURCE_DIR}/config/*.yaml
     ${PROJECT_SOURCE_DIR}/config/*.dxf)
set(_deb_confdir "${CMAKE_INSTALL_FULL_SYSCONFDIR}/evpipe")
foreach(_f IN LISTS _deb_config_files ITEMS evpipe.yaml.default)  # evpipe.yaml itself is in the glob
  string(APPEND _deb_conffiles "${_deb_confdir}/${_f}\n")
endforeach()
if(_deb_ldconf)
  string(APPEND _deb_conffiles "${_deb_ldconf}\n")
endif()
file(WRITE ${_deb_dir}/control/conffiles "${_deb_conffiles}")
set(_deb_control ${_deb_dir}/control/conffiles)
foreach(_script postinst prerm postrm)
  configure_file(${_deb_src}/${_script} ${_deb_dir}/control/${_script} COPYONLY)
  list(APPEND _deb_control ${_deb_dir}/control/${_script})
endforeach()
if(_deb_ldconf)
  file(WRITE ${_deb_dir}/control/triggers "activate-noawait ldconfig\n")
  list(APPEND _deb_control ${_deb_dir}/control/triggers)
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME evpipe)
set(CPACK_PACKAGE_VERSION "${EVPIPE_DEB_VERSION}")
set(CPACK_PACKAGE_CONTACT "${EVPIPE_DEB_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${EVPIPE_DEB_MAINTAINER}")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # evpipe_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "event-camera pose pipeline for a DAVIS346, as a systemd service")
# Extended description: lines of at most 72 characters (lintian: extended-description-line-too-long at 80).
if(EVPIPE_WITH_LIBCAER)
  set(_deb_camera "It reads the camera through libcaer ${EVPIPE_LIBCAER_VERSION}, which is not a Debian\n"
                  "package: install it from iniVation's source first (docs/operations.md).")
else()
  set(_deb_camera "This build has NO camera support (libcaer stub: EVPIPE_WITH_LIBCAER\n"
                  "OFF, or AUTO without libcaer): it only replays recordings. Release\n"
                  "packages are built with EVPIPE_WITH_LIBCAER=ON.")
endif()
# CPack puts the summary in front of it as the synopsis line.
string(CONCAT CPACK_DEBIAN_PACKAGE_DESCRIPTION
       "evpipe turns the event stream of a DAVIS346 event camera into the\n"
       "6-DoF pose of a mining machine: denoising, line-model pose estimation\n"
       "and tracking, one thread per stage, poses and statistics published on\n"
       "LCM. The service (evpipe.service, not enabled on install) runs with a\n"
       "watchdog; /etc/evpipe/evpipe.yaml is its configuration. Tools:\n"
       "evconvert, evsim, evdenoise, evpose-eval, evpipe-lcm-echo and\n"
       "evpipe-lcm-spy.\n"
       ${_deb_camera})
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
if(EVPIPE_WITH_LIBCAER AND EVPIPE_LIBCAER_LIBDIR_EXTRA)
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS "${EVPIPE_LIBCAER_LIBDIR}")  # dpkg-shlibdeps -l<dir>
endif()
# evpipe-lcm-spy needs Java and LCM's jars, evpipe-lcm-echo's companions lcm-logger/lcm-logplayer are liblcm-bin:
# suggested only (a headless industrial PC needs none of them).
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "liblcm-bin, liblcm-java, libjchart2d-java, default-jre")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA "${_deb_control}")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_STRIP_FILES ON)
# Absolute destinations (/etc/evpipe, /lib/systemd/system, /lib/udev/rules.d) are staged under DESTDIR.
set(CPACK_SET_DESTDIR ON)
set(CPACK_PACKAGING_INSTALL_PREFIX "${CMAKE_INSTALL_PREFIX}")
set(CPACK_INSTALL_PREFIX "${CMAKE_INSTALL_PREFIX}")
# cpack refuses a tree whose layout is not the package's (e.g. the release preset's /usr/local).
set(EVPIPE_DEB_LAYOUT_OK OFF)
if(CMAKE_INSTALL_PREFIX STREQUAL "/usr" AND EVPIPE_INSTALL_SYSTEMDUNITDIR STREQUAL "/lib/systemd/system"
   AND EVPIPE_INSTALL_UDEVRULESDIR STREQUAL "/lib/udev/rules.d" AND NOT (EVPIPE_LIBCAER_LIBDIR_EXTRA AND EVPIPE_LIBCAER_RPATH))
  set(EVPIPE_DEB_LAYOUT_OK ON)
endif()
configure_file(${PROJECT_SOURCE_DIR}/cmake/EvpipeCPackOptions.cmake.in ${_deb_dir}/CPackOptions.cmake @ONLY)
set(CPACK_PROJECT_CONFIG_FILE ${_deb_dir}/CPackOptions.cmake)
include(CPack)
