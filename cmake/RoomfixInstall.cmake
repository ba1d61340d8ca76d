# Install rules and the Debian package (docs/install.md says what goes where).
#
#   <prefix>/bin/                     the processes, the roomfix tool, its
#                                     benchmarks (roomfix_bench) and
#                                     roomfix-spy (scripts/spy; with the jar)
#   <prefix>/share/roomfix/config/    sites, calibrations, bot-procman files
#   <prefix>/share/roomfix/lcmtypes/  the message definitions (.lcm)
#   <prefix>/include/roomfix/         the generated C++ message headers
#   <prefix>/<libdir>/cmake/roomfix/  find_package(roomfix): roomfix::lcmtypes
#                                     (header-only)
#   <prefix>/share/java/              roomfix-lcmtypes-<version>.jar and its
#                                     unversioned symlink (lcm-spy)
#   <prefix>/lib/python3/dist-packages/roomfix/
#                                     the Python message types (lcm-gen
#                                     --python; docs/python.md)
#   <prefix>/share/doc/roomfix/       README and docs; copyright (DEP-5) and
#                                     changelog.gz (packaging/)
#   <prefix>/share/man/man1/          a manual page per program (help2man)
# Programs find share/roomfix from their own folder (msgio/install_paths.h),
# so the tree works wherever it is put. Every library of the project is
# static: the programs need no RPATH and link system libraries only.
include(CMakePackageConfigHelpers)

# roomfix_bench too: docs/operations.md, "Sizing a lab", has a lab run its
# capacity bench on its own hosts (docs/install.md).
set(ROOMFIX_PROGRAMS camera_proc trilat_proc fusion_proc zigbee_bridge roomfix_logger
    roomfix_viewer roomfix_sim roomfix roomfix_bench)
install(TARGETS ${ROOMFIX_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        COMPONENT runtime)

install(DIRECTORY config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/roomfix/config
        COMPONENT runtime)
# lcm-spy with roomfix's types (scripts/spy), named so that it cannot clash in
# /usr/bin; it is of use only with the jar, so it goes where the jar goes.
if(ROOMFIX_JAVA)
  install(PROGRAMS scripts/spy DESTINATION ${CMAKE_INSTALL_BINDIR} RENAME roomfix-spy
          COMPONENT dev)
endif()
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)
# The devices' firmware images for avrdude (docs/devices.md), when built.
if(ROOMFIX_FIRMWARE)
  install(FILES ${CMAKE_BINARY_DIR}/firmware/beacon.hex ${CMAKE_BINARY_DIR}/firmware/receiver.hex
          DESTINATION ${CMAKE_INSTALL_DATADIR}/roomfix/firmware COMPONENT runtime)
endif()
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs COMPONENT runtime)

# The licence as Debian wants it (docs/install.md, "Licence"): the
# machine-readable copyright file (DEP-5; it refers to the GPL's text in
# /usr/share/common-licenses, so LICENSE itself is not installed) and the
# changelog, compressed without a timestamp (gzip -9n) so that two builds of
# one version give the same bytes. roomfix is its own upstream, a native
# package (a version without a Debian revision), whose changelog Debian names
# changelog.gz (changelog.Debian.gz is for a package of someone else's code).
install(FILES packaging/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)
file(STRINGS packaging/changelog changelog_head LIMIT_COUNT 1)
if(NOT changelog_head MATCHES "^roomfix \\(${PROJECT_VERSION}\\) ")
  message(FATAL_ERROR "packaging/changelog's latest entry (${changelog_head}) is not version "
                      "${PROJECT_VERSION}: add an entry for it (dch, or by hand)")
endif()
set(changelog_gz ${CMAKE_BINARY_DIR}/packaging/changelog.gz)
add_custom_command(OUTPUT ${changelog_gz}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/packaging
  COMMAND sh -c "gzip -9nc '${CMAKE_SOURCE_DIR}/packaging/changelog' > '${changelog_gz}'"
  DEPENDS packaging/changelog
  COMMENT "gzip -9n packaging/changelog"
  VERBATIM)
set(man_pages)
if(ROOMFIX_MAN_PAGES)
  # What each manual page's NAME line says (`apropos roomfix`).
  set(man_name_camera_proc "ceiling camera process: finds the robots' markers, publishes poses")
  set(man_name_trilat_proc "ultrasonic trilateration: a pose from each firing's ranges")
  set(man_name_fusion_proc "fuses the camera's and the ultrasound's poses of each robot")
  set(man_name_zigbee_bridge "bridge from the ZigBee coordinator's serial port to LCM range sets")
  set(man_name_roomfix_logger "records roomfix's LCM channels into log files")
  set(man_name_roomfix_viewer "shows the room, the robots' poses and every process's health")
  set(man_name_roomfix_sim "simulates a site: robots, ultrasonic beacons and receivers, cameras")
  set(man_name_roomfix "roomfix's tool: check-config, listen, log-info, analyze, replay, export")
  set(man_name_roomfix_bench "roomfix's benchmarks: camera, trilat, radio, capacity, logger, replay")
  set(man_name_roomfix-spy "lcm-spy with roomfix's message types")
  set(man_programs ${ROOMFIX_PROGRAMS})
  if(ROOMFIX_JAVA)
    list(APPEND man_programs roomfix-spy)
  endif()
  foreach(program IN LISTS man_programs)
    if(program STREQUAL "roomfix-spy")
      set(executable ${CMAKE_SOURCE_DIR}/scripts/spy)
      set(depends ${executable})
    else()
      set(executable $<TARGET_FILE:${program}>)
      set(depends ${program})
    endif()
    set(page ${CMAKE_BINARY_DIR}/man/${program}.1)
    # --version-string names the program (help2man would take the script's
    # file name, spy); --no-info: there is no info manual. A sanitizer build
    # runs the programs too: leak checking off, as --help leaks nothing of
    # interest and LeakSanitizer cannot run under every tracer.
    add_custom_command(OUTPUT ${page}.gz
      COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/man
      COMMAND ${CMAKE_COMMAND} -E env ASAN_OPTIONS=detect_leaks=0 ${HELP2MAN} --no-info
              --section=1 --name=${man_name_${program}}
              "--version-string=${program} (roomfix) ${PROJECT_VERSION}"
              --output=${page} ${executable}
      COMMAND gzip -9nf ${page}
      DEPENDS ${depends}
      COMMENT "help2man: ${program}.1"
      VERBATIM)
    list(APPEND man_pages ${page}.gz)
  endforeach()
  install(FILES ${man_pages} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT runtime)
endif()
add_custom_target(roomfix_package_docs ALL DEPENDS ${changelog_gz} ${man_pages})
install(FILES ${changelog_gz} DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)

# The message types for other lab software (headers and .lcm files are
# installed by roomfix_lcm_types, cmake/RoomfixLcmTypes.cmake).
set_target_properties(roomfix_lcmtypes PROPERTIES EXPORT_NAME lcmtypes)
install(TARGETS roomfix_lcmtypes EXPORT roomfixTargets COMPONENT dev)
set(ROOMFIX_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/roomfix)
install(EXPORT roomfixTargets NAMESPACE roomfix:: DESTINATION ${ROOMFIX_CMAKE_DIR}
        COMPONENT dev)
set(ROOMFIX_INSTALL_LCMTYPES_DIR ${CMAKE_INSTALL_DATADIR}/roomfix/lcmtypes)
set(ROOMFIX_INSTALL_JAVA_DIR ${CMAKE_INSTALL_DATADIR}/java)
configure_package_config_file(cmake/roomfixConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/roomfixConfig.cmake
  INSTALL_DESTINATION ${ROOMFIX_CMAKE_DIR}
  PATH_VARS ROOMFIX_INSTALL_LCMTYPES_DIR ROOMFIX_INSTALL_JAVA_DIR)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/roomfixConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/roomfixConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/roomfixConfigVersion.cmake
        DESTINATION ${ROOMFIX_CMAKE_DIR} COMPONENT dev)

# The Python message types (docs/python.md). The package is `roomfix`, not a
# name of our choosing: lcm-gen names it after the .lcm files' `package
# roomfix;` and every generated module imports its nested types as
# `roomfix.counter_t`, so under any other name they would not import. (The
# LCM package name cannot change either: it is the C++ namespace and the Java
# package.) lib/python3/dist-packages is where Debian puts pure-Python
# modules for every python3 version (Debian's python3 has it on sys.path;
# python3.11 on Debian 12). The modules are plain Python 3 with no compiled
# part; no __pycache__ is shipped (Python writes it where it may).
set(ROOMFIX_INSTALL_PYTHONDIR lib/python3/dist-packages CACHE STRING
    "Where the Python message types are installed, relative to the prefix")
install(DIRECTORY ${ROOMFIX_LCMTYPES_PYTHON_DIR} DESTINATION ${ROOMFIX_INSTALL_PYTHONDIR}
        COMPONENT dev PATTERN __pycache__ EXCLUDE)

# `make package` (cpack -G DEB): roomfix_<version>_amd64.deb for /usr, its
# Depends worked out by dpkg-shlibdeps from the programs' shared libraries.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME roomfix)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
# The maintainer: the project itself, at an address under a reserved example
# domain (RFC 2606) until it has one of its own; no person is named.
set(CPACK_PACKAGE_CONTACT "roomfix developers <roomfix@example.org>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "indoor robot localisation from a ceiling camera and ultrasonic ranges")
# The extended description, one line per line of the control file (CPack
# indents them; Debian wants each under 80 characters).
set(CPACK_PACKAGE_DESCRIPTION [=[
Small processes exchanging LCM messages: camera_proc (the ceiling camera),
zigbee_bridge and trilat_proc (ultrasonic trilateration), fusion_proc,
roomfix_logger, roomfix_viewer, roomfix_sim, the roomfix tool and
roomfix_bench (its benchmarks).
For other lab software: the message headers, the .lcm files, a CMake
package (roomfix::lcmtypes) and the Java types jar.]=])
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The Python message types in /usr/lib/python3/dist-packages/roomfix need
# python3 (lintian: python-package-missing-depends-on-python); dpkg-shlibdeps
# adds the libraries' packages to it.
set(CPACK_DEBIAN_PACKAGE_DEPENDS "python3")
# lcm-logplayer and lcm-spy; the C++ headers need liblcm-dev, the jar lcm.jar.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "liblcm-bin")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "liblcm-dev, liblcm-java, default-jre-headless")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# One package holding every component (docs/install.md: the same package on
# every host; each host starts only its own programs).
set(CPACK_DEB_COMPONENT_INSTALL OFF)
include(CPack)
