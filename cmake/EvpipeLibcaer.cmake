# Finds the real libcaer according to EVPIPE_WITH_LIBCAER (ON, OFF or AUTO; top-level CMakeLists.txt) and sets,
# in the caller's scope:
#   EVPIPE_WITH_LIBCAER          the resolved ON (real libcaer) or OFF (stub), shadowing the cache entry, so that
#                                `if(EVPIPE_WITH_LIBCAER)` everywhere means "the real library"
#   EVPIPE_LIBCAER_TARGET        libcaer::caer (CMake package) or PkgConfig::LIBCAER (pkg-config), when ON
#   EVPIPE_LIBCAER_VERSION       its version, when ON
#   EVPIPE_LIBCAER_LIBDIR        the folder of its shared library, when ON
#   EVPIPE_LIBCAER_LIBDIR_EXTRA  ON when that folder is not one the dynamic linker searches by default (e.g.
#                                /opt/libcaer/lib): the installed programs then need an RPATH (EVPIPE_LIBCAER_RPATH)
#                                or the package's /etc/ld.so.conf.d entry (cmake/EvpipePackaging.cmake)
# Both lookups require libcaer >= 3.3 (the API evpipe is written against; docs/device.md).
macro(evpipe_resolve_libcaer)
  string(TOUPPER "${EVPIPE_WITH_LIBCAER}" _evpipe_caer_mode)
  if(_evpipe_caer_mode MATCHES "^(ON|YES|TRUE|Y|1)$")
    set(_evpipe_caer_mode ON)
  elseif(_evpipe_caer_mode MATCHES "^(OFF|NO|FALSE|N|0|)$")
    set(_evpipe_caer_mode OFF)
  elseif(NOT _evpipe_caer_mode STREQUAL "AUTO")
    message(FATAL_ERROR "EVPIPE_WITH_LIBCAER must be ON, OFF or AUTO, not '${EVPIPE_WITH_LIBCAER}'")
  endif()

  set(EVPIPE_LIBCAER_TARGET "")
  set(EVPIPE_LIBCAER_VERSION "")
  if(NOT _evpipe_caer_mode STREQUAL "OFF")
    find_package(libcaer 3.3 CONFIG QUIET)
    if(libcaer_FOUND AND TARGET libcaer::caer)
      set(EVPIPE_LIBCAER_TARGET libcaer::caer)
      set(EVPIPE_LIBCAER_VERSION "${libcaer_VERSION}")
    else()
      pkg_check_modules(LIBCAER QUIET IMPORTED_TARGET "libcaer >= 3.3")
      if(LIBCAER_FOUND)
        set(EVPIPE_LIBCAER_TARGET PkgConfig::LIBCAER)
        set(EVPIPE_LIBCAER_VERSION "${LIBCAER_VERSION}")
      endif()
    endif()
  endif()

  if(NOT EVPIPE_LIBCAER_TARGET AND NOT _evpipe_caer_mode STREQUAL "OFF")
    # Say what was found instead (an old 2.x, or nothing), for the message below.
    set(_evpipe_caer_seen "no libcaer at all")
    if(libcaer_CONSIDERED_VERSIONS)
      set(_evpipe_caer_seen "only libcaer ${libcaer_CONSIDERED_VERSIONS} (CMake package)")
    else()
      pkg_check_modules(_EVPIPE_LIBCAER_ANY QUIET libcaer)
      if(_EVPIPE_LIBCAER_ANY_FOUND)
        set(_evpipe_caer_seen "only libcaer ${_EVPIPE_LIBCAER_ANY_VERSION} (pkg-config)")
      endif()
    endif()
    if(_evpipe_caer_mode STREQUAL "ON")
      message(FATAL_ERROR
        "EVPIPE_WITH_LIBCAER=ON, but libcaer >= 3.3 was not found (CMake package 'libcaer' or pkg-config "
        "'libcaer'; found ${_evpipe_caer_seen}).\n"
        "Debian 12 has no libcaer package: build and install it from iniVation's source as docs/operations.md "
        "describes (Install, step 2 'Install libcaer': libusb-1.0-0-dev, then libcaer's own CMake build, installed to "
        "/usr/local). If it is installed under another prefix, configure with -DCMAKE_PREFIX_PATH=<that prefix>.\n"
        "To build without camera support (replay only, the stub in third_party_stubs/), configure with "
        "-DEVPIPE_WITH_LIBCAER=AUTO or OFF.")
    endif()
    message(STATUS "evpipe: libcaer >= 3.3 not found (${_evpipe_caer_seen}): EVPIPE_WITH_LIBCAER=AUTO builds the stub")
  endif()

  set(EVPIPE_LIBCAER_LIBDIR "")
  set(EVPIPE_LIBCAER_LIBDIR_EXTRA OFF)
  if(EVPIPE_LIBCAER_TARGET)
    set(EVPIPE_WITH_LIBCAER ON)
    # The shared library's folder: the imported target's location, or pkg-config's full link path.
    set(_evpipe_caer_lib "")
    if(EVPIPE_LIBCAER_TARGET STREQUAL "libcaer::caer")
      get_target_property(_evpipe_caer_lib libcaer::caer LOCATION)
    else()
      foreach(_evpipe_l IN LISTS LIBCAER_LINK_LIBRARIES)
        if(_evpipe_l MATCHES "/libcaer\\.so")
          set(_evpipe_caer_lib "${_evpipe_l}")
        endif()
      endforeach()
    endif()
    if(_evpipe_caer_lib)
      get_filename_component(EVPIPE_LIBCAER_LIBDIR "${_evpipe_caer_lib}" DIRECTORY)
      get_filename_component(EVPIPE_LIBCAER_LIBDIR "${EVPIPE_LIBCAER_LIBDIR}" REALPATH)
      # The folders Debian's dynamic linker searches without configuration (trusted dirs + ld.so.conf.d/*.conf).
      set(_evpipe_ld_default_dirs /lib /usr/lib /usr/local/lib)
      if(CMAKE_LIBRARY_ARCHITECTURE)
        list(APPEND _evpipe_ld_default_dirs /lib/${CMAKE_LIBRARY_ARCHITECTURE} /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}
             /usr/local/lib/${CMAKE_LIBRARY_ARCHITECTURE})
      endif()
      if(NOT EVPIPE_LIBCAER_LIBDIR IN_LIST _evpipe_ld_default_dirs)
        set(EVPIPE_LIBCAER_LIBDIR_EXTRA ON)
      endif()
    endif()
    message(STATUS "evpipe: libcaer ${EVPIPE_LIBCAER_VERSION} (${EVPIPE_LIBCAER_TARGET}, ${EVPIPE_LIBCAER_LIBDIR})")
  else()
    set(EVPIPE_WITH_LIBCAER OFF)
  endif()

  # A libcaer outside the linker's default folders: the installed programs find it through their RPATH (cmake
  # --install of device.md's -DCMAKE_PREFIX_PATH=/opt/libcaer), or, with EVPIPE_LIBCAER_RPATH=OFF (the Debian
  # package: lintian forbids custom RPATHs), through the /etc/ld.so.conf.d entry the package ships.
  option(EVPIPE_LIBCAER_RPATH "Give installed programs an RPATH to a libcaer outside the linker's default folders" ON)
  if(EVPIPE_LIBCAER_LIBDIR_EXTRA AND EVPIPE_LIBCAER_RPATH)
    list(APPEND CMAKE_INSTALL_RPATH "${EVPIPE_LIBCAER_LIBDIR}")
  endif()
endmacro()
