# Install rules and the Debian package (docs/install.md says what goes where).
#
#   <prefix>/bin/                     the processes, the roomfix tool and
#                                     roomfix-spy (scripts/spy; with the jar)
#   <prefix>/share/roomfix/config/    sites, calibrations, bot-procman files
#   <prefix>/share/roomfix/lcmtypes/  the message definitions (.lcm)
#   <prefix>/include/roomfix/         the generated C++ message headers
#   <prefix>/<libdir>/                libroomfix_lcmtypes.a (the constants'
#                                     definitions lcm-gen 1.3.1 leaves out)
#   <prefix>/<libdir>/cmake/roomfix/  find_package(roomfix): roomfix::lcmtypes
#   <prefix>/share/java/              roomfix_lcmtypes.jar (lcm-spy)
#   <prefix>/share/doc/roomfix/       README and docs
# Programs find share/roomfix from their own folder (msgio/install_paths.h),
# so the tree works wherever it is put. Every library of the project is
# static: the programs need no RPATH and link system libraries only.
include(CMakePackageConfigHelpers)

set(ROOMFIX_PROGRAMS camera_proc trilat_proc fusion_proc zigbee_bridge roomfix_logger
    roomfix_viewer roomfix_sim roomfix)
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

# The message types for other lab software (headers and .lcm files are
# installed by roomfix_lcm_types, cmake/RoomfixLcmTypes.cmake).
set_target_properties(roomfix_lcmtypes PROPERTIES EXPORT_NAME lcmtypes)
install(TARGETS roomfix_lcmtypes EXPORT roomfixTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
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

# `make package` (cpack -G DEB): roomfix_<version>_amd64.deb for /usr, its
# Depends worked out by dpkg-shlibdeps from the programs' shared libraries.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME roomfix)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "roomfix maintainers <roomfix@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "indoor robot localisation from a ceiling camera and ultrasonic ranges")
set(CPACK_PACKAGE_DESCRIPTION
    "Small processes exchanging LCM messages: camera_proc (ceiling camera), zigbee_bridge and \
trilat_proc (ultrasonic trilateration), fusion_proc, roomfix_logger, roomfix_viewer, \
roomfix_sim and the roomfix tool; with the message headers, .lcm files, a CMake package \
(roomfix::lcmtypes) and the Java types jar for other lab software.")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# lcm-logplayer and lcm-spy; the C++ headers need liblcm-dev, the jar lcm.jar.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "liblcm-bin")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "liblcm-dev, liblcm-java, default-jre-headless")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# One package holding every component (docs/install.md: the same package on
# every host; each host starts only its own programs).
set(CPACK_DEB_COMPONENT_INSTALL OFF)
include(CPack)
