# roomfix_lcm_types(TARGET <name> JAR <jar-name> SOURCES <file.lcm>...)
#
# Runs lcm-gen on the given type definitions and makes
#  - <name>: a header-only (INTERFACE) library whose include directory holds
#    the generated C++ headers (<package>/<type>.hpp), linked with liblcm;
#  - <name>_java (when ROOMFIX_JAVA is on): the Java classes compiled against
#    lcm.jar and packed into ${CMAKE_BINARY_DIR}/share/java/<jar-name>, so
#    lcm-spy decodes the types;
#  - <name>_python: the Python modules (lcm-gen --python) in
#    ${CMAKE_BINARY_DIR}/python/<package>/, one module per struct and an
#    __init__.py importing them all. They need only Python's standard library
#    to encode and decode (the `lcm` module is for the bus); the folder is
#    returned in <name>_PYTHON_DIR and installed by cmake/RoomfixInstall.cmake.
# Generated file names follow lcm-gen: one header and one class per struct,
# named after the .lcm file (one struct per file, as DESIGN.md requires).
function(roomfix_lcm_types)
  cmake_parse_arguments(ARG "" "TARGET;JAR;PACKAGE" "SOURCES" ${ARGN})
  set(cpp_dir ${CMAKE_CURRENT_BINARY_DIR}/cpp)
  set(java_dir ${CMAKE_CURRENT_BINARY_DIR}/java)
  set(class_dir ${CMAKE_CURRENT_BINARY_DIR}/classes)
  set(jar ${CMAKE_BINARY_DIR}/share/java/${ARG_JAR})
  set(python_dir ${CMAKE_BINARY_DIR}/python)
  set(headers)
  set(java_sources)
  set(python_sources ${python_dir}/${ARG_PACKAGE}/__init__.py)
  set(lcm_files)
  foreach(src IN LISTS ARG_SOURCES)
    get_filename_component(type ${src} NAME_WE)
    list(APPEND lcm_files ${CMAKE_CURRENT_SOURCE_DIR}/${src})
    list(APPEND headers ${cpp_dir}/${ARG_PACKAGE}/${type}.hpp)
    list(APPEND java_sources ${java_dir}/${ARG_PACKAGE}/${type}.java)
    list(APPEND python_sources ${python_dir}/${ARG_PACKAGE}/${type}.py)
  endforeach()

  add_custom_command(
    OUTPUT ${headers} ${java_sources}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${cpp_dir} ${java_dir}
    COMMAND ${LCM_GEN} --cpp --cpp-std c++11 --cpp-hpath ${cpp_dir} ${lcm_files}
    COMMAND ${LCM_GEN} --java --jpath ${java_dir} ${lcm_files}
    DEPENDS ${lcm_files}
    COMMENT "lcm-gen: C++ headers and Java sources for ${ARG_TARGET}"
    VERBATIM)
  add_custom_target(${ARG_TARGET}_gen DEPENDS ${headers})

  # lcm-gen adds its imports to an existing __init__.py and never removes
  # one, so the package folder is made afresh: a type taken out of
  # lcmtypes/ must not stay importable from the build tree.
  add_custom_command(
    OUTPUT ${python_sources}
    COMMAND ${CMAKE_COMMAND} -E remove_directory ${python_dir}/${ARG_PACKAGE}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${python_dir}
    COMMAND ${LCM_GEN} --python --ppath ${python_dir} ${lcm_files}
    DEPENDS ${lcm_files}
    COMMENT "lcm-gen: Python modules for ${ARG_TARGET}"
    VERBATIM)
  add_custom_target(${ARG_TARGET}_python ALL DEPENDS ${python_sources})
  set(${ARG_TARGET}_PYTHON_DIR ${python_dir}/${ARG_PACKAGE} PARENT_SCOPE)

  # Integer constants: by default lcm-gen 1.3.1 declares them
  # `static const int8_t X = 1;` inside the class and defines them nowhere,
  # so an odr-use (binding one to a const reference, as EXPECT_EQ does) fails
  # to link unless some object file defines them. With --cpp-std c++11 they
  # are `static constexpr`, which C++17 makes inline variables: defined in
  # every translation unit that includes the header, so the types need no
  # library of their own (an archive holding only those definitions has no
  # code, which lintian refuses as no-code-sections). Consumers must
  # therefore compile as C++17 or later (cxx_std_17 below).
  # (CMake follows an interface library's add_dependencies in its place, so
  # whatever links it is built after lcm-gen has run.)
  add_library(${ARG_TARGET} INTERFACE)
  target_compile_features(${ARG_TARGET} INTERFACE cxx_std_17)
  add_dependencies(${ARG_TARGET} ${ARG_TARGET}_gen)
  target_include_directories(${ARG_TARGET} SYSTEM INTERFACE $<BUILD_INTERFACE:${cpp_dir}>)
  target_link_libraries(${ARG_TARGET} INTERFACE lcm::lcm)
  # LCM 1.3.1's lcm_coretypes.h decodes a double by writing through an
  # int64_t pointer. With strict aliasing (GCC 12 at -O2) the compiler may
  # keep the double's old value: decoded poses came back as x_m = 0. Every
  # file that includes the generated headers must be built without it.
  target_compile_options(${ARG_TARGET} INTERFACE -fno-strict-aliasing)

  # The headers and the .lcm files are installed for other lab software
  # (find_package(roomfix): roomfix::lcmtypes, see cmake/roomfixConfig.cmake.in).
  target_include_directories(${ARG_TARGET} SYSTEM INTERFACE
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  install(FILES ${headers} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/${ARG_PACKAGE}
          COMPONENT dev)
  install(FILES ${lcm_files} DESTINATION ${CMAKE_INSTALL_DATADIR}/roomfix/lcmtypes
          COMPONENT dev)

  set(${ARG_TARGET}_JAR "" PARENT_SCOPE)
  if(NOT ROOMFIX_JAVA)
    return()
  endif()
  add_custom_command(
    OUTPUT ${jar}
    COMMAND ${CMAKE_COMMAND} -E remove_directory ${class_dir}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${class_dir} ${CMAKE_BINARY_DIR}/share/java
    COMMAND ${Java_JAVAC_EXECUTABLE} -nowarn -source 8 -target 8 -Xlint:-options
            -cp ${LCM_JAR} -d ${class_dir} ${java_sources}
    COMMAND ${Java_JAR_EXECUTABLE} cf ${jar} -C ${class_dir} .
    DEPENDS ${java_sources}
    COMMENT "javac + jar: ${ARG_JAR}"
    VERBATIM)
  add_custom_target(${ARG_TARGET}_java ALL DEPENDS ${jar})
  # Java policy 2.4 (lintian: bad-jar-name): a public jar is installed as
  # <name>-<version>.jar with the unversioned name as a symlink to it, which
  # is what class paths (scripts/spy, ROOMFIX_LCMTYPES_JAR) name.
  get_filename_component(jar_stem ${ARG_JAR} NAME_WE)
  set(versioned_jar ${jar_stem}-${PROJECT_VERSION}.jar)
  install(FILES ${jar} DESTINATION ${CMAKE_INSTALL_DATADIR}/java RENAME ${versioned_jar}
          COMPONENT dev)
  install(CODE "file(CREATE_LINK ${versioned_jar}
    \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DATADIR}/java/${ARG_JAR}\" SYMBOLIC)"
    COMPONENT dev)
  set(${ARG_TARGET}_JAR ${jar} PARENT_SCOPE)
endfunction()
