# Test helpers shared by every folder.
#
# Tests find the source tree, the build tree and the real reference data
# through these environment variables; tests/testing compiles the same paths
# in as defaults, which is what GoogleTest-discovered tests use (a list-valued
# ENVIRONMENT does not survive gtest_discover_tests' generated script).
set(ROOMFIX_TEST_ENVIRONMENT
  "ROOMFIX_SOURCE_DIR=${CMAKE_SOURCE_DIR}"
  "ROOMFIX_BUILD_DIR=${CMAKE_BINARY_DIR}"
  "ROOMFIX_SHARED_DATA_DIR=${ROOMFIX_SHARED_DATA_DIR}")

# Exit code with which a test says "could not run here" (ctest: Skipped).
set(ROOMFIX_SKIP_CODE 77)

# roomfix_add_gtest(<name> SOURCES ... LIBS ...): a GoogleTest binary beside
# the code it tests; each TEST becomes its own ctest entry. Nothing when
# BUILD_TESTING is off (no GoogleTest needed then).
function(roomfix_add_gtest name)
  if(NOT BUILD_TESTING)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} roomfix::testing GTest::gtest_main)
  # The sanitizer build's leak suppressions (third-party libraries' own
  # teardown leaks, each with its reason in the file); one value, so it
  # survives gtest_discover_tests. `make test SANITIZE=1` also exports it for
  # every other test.
  set(environment "")
  if(ROOMFIX_SANITIZE)
    set(environment ENVIRONMENT "LSAN_OPTIONS=suppressions=${CMAKE_SOURCE_DIR}/tests/lsan_suppressions.txt")
  endif()
  gtest_discover_tests(${name}
    DISCOVERY_TIMEOUT 60
    PROPERTIES TIMEOUT 300 ${environment})
endfunction()

# roomfix_add_netns_test(<name> COMMAND <cmd> [args...]): runs the command in
# a private network namespace (scripts/netns_run), so UDP multicast stays on
# this host. Skipped (not failed) where user namespaces are not allowed.
function(roomfix_add_netns_test name)
  if(NOT BUILD_TESTING)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "COMMAND" ${ARGN})
  add_test(NAME ${name}
    COMMAND ${CMAKE_SOURCE_DIR}/scripts/netns_run ${ARG_COMMAND})
  set_tests_properties(${name} PROPERTIES
    ENVIRONMENT "${ROOMFIX_TEST_ENVIRONMENT}"
    SKIP_RETURN_CODE ${ROOMFIX_SKIP_CODE}
    LABELS netns
    TIMEOUT 300)
endfunction()
