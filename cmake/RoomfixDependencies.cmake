# Every dependency is a Debian 12 package (scripts/install_deps.sh installs
# them; docs/install.md lists the fewest that build the processes). LCM 1.3.1
# ships neither CMake files nor a pkg-config file usable without glib's
# development headers, so it is found by hand.
find_package(Threads REQUIRED)
find_package(yaml-cpp REQUIRED)
find_package(CLI11 REQUIRED)
find_package(spdlog REQUIRED)
find_package(fmt REQUIRED)
# SHA-256 of the site texts (msgio/site_message.h).
find_package(OpenSSL REQUIRED COMPONENTS Crypto)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(GSL REQUIRED)
# camera_proc's JPEG frames (libjpeg-turbo: DCT scaling, cropped scanlines).
find_package(JPEG REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
# zigbee_bridge's serial port.
find_package(PkgConfig REQUIRED)
pkg_check_modules(SERIALPORT REQUIRED IMPORTED_TARGET libserialport)

# OpenCV: every module roomfix uses, and highgui (the viewer's window, below)
# if it is there. Debian's OpenCV targets carry no include directory, so it
# is added to them here: a target that links a module then gets OpenCV's
# headers, as system headers (those of an imported target are), which keeps
# project warnings (-Wshadow, -Wpedantic) off them; and it gets them only as
# far as it links the module (PRIVATE stays private).
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs videoio calib3d features2d
             OPTIONAL_COMPONENTS highgui)
foreach(module IN LISTS OpenCV_LIBS)
  if(TARGET ${module})
    set_property(TARGET ${module} APPEND PROPERTY INTERFACE_INCLUDE_DIRECTORIES
                 ${OpenCV_INCLUDE_DIRS})
  endif()
endforeach()

find_path(LCM_INCLUDE_DIR lcm/lcm-cpp.hpp REQUIRED)
find_library(LCM_LIBRARY lcm REQUIRED)
find_program(LCM_GEN lcm-gen REQUIRED)
add_library(lcm::lcm UNKNOWN IMPORTED)
set_target_properties(lcm::lcm PROPERTIES
  IMPORTED_LOCATION ${LCM_LIBRARY}
  INTERFACE_INCLUDE_DIRECTORIES ${LCM_INCLUDE_DIR})

# Optional parts. Each is on when what it needs is found and off, saying so,
# when not; asking for one explicitly (-D...=ON) without its packages fails at
# configure time with the packages to install.

# The tests: GoogleTest is needed for them only.
find_package(GTest QUIET)
option(BUILD_TESTING "Build the tests (libgtest-dev, libgmock-dev)" ${GTest_FOUND})
if(BUILD_TESTING)
  if(NOT GTest_FOUND)
    message(FATAL_ERROR "BUILD_TESTING is on but GoogleTest is missing: apt-get install "
                        "libgtest-dev libgmock-dev, or configure with -DBUILD_TESTING=OFF")
  endif()
  enable_testing()
  include(GoogleTest)
endif()

# The Java types jar (lcm-spy decodes roomfix's messages with it).
find_package(Java 11 QUIET COMPONENTS Development Runtime)
find_file(LCM_JAR lcm.jar PATHS /usr/share/java NO_DEFAULT_PATH)
if(Java_FOUND AND LCM_JAR)
  set(roomfix_java_default ON)
else()
  set(roomfix_java_default OFF)
endif()
option(ROOMFIX_JAVA "Build the Java types jar for lcm-spy (default-jdk-headless, liblcm-java)"
       ${roomfix_java_default})
if(ROOMFIX_JAVA AND NOT (Java_FOUND AND LCM_JAR))
  message(FATAL_ERROR "ROOMFIX_JAVA is on but a JDK (11 or later) or lcm.jar is missing: "
                      "apt-get install default-jdk-headless liblcm-java, or -DROOMFIX_JAVA=OFF")
endif()

# LCM's Python module (`import lcm`: PyPI wheels since LCM 1.5, not packaged
# by Debian 12), used only by the test of docs/python.md's bus example: a
# folder holding lcm/__init__.py and lcm/_lcm*.so, e.g. an LCM 1.5 build's
# python/ folder. Empty: the test tries python3's own path and skips, saying
# so, when the module is not there.
set(ROOMFIX_LCM_PYTHON_DIR "" CACHE PATH
    "Folder with LCM's Python module (lcm/), for the test of docs/python.md's bus example")

# The viewer's window (OpenCV's highgui, which brings GTK); without it the
# viewer still renders headless to PNG and video.
option(ROOMFIX_VIEWER_WINDOW "roomfix_viewer can open a window (OpenCV highgui)"
       ${OpenCV_highgui_FOUND})
if(ROOMFIX_VIEWER_WINDOW AND NOT OpenCV_highgui_FOUND)
  message(FATAL_ERROR "ROOMFIX_VIEWER_WINDOW is on but OpenCV's highgui is missing: "
                      "apt-get install libopencv-highgui-dev, or -DROOMFIX_VIEWER_WINDOW=OFF")
endif()

# Manual pages of the installed programs, written from their --help by
# help2man at build time (cmake/RoomfixInstall.cmake); without help2man the
# package has none (lintian then warns no-manual-page). Not an option: a
# NOTFOUND result is searched again at the next configure, so installing
# help2man (scripts/install_deps.sh does, for `make test` and `make package`)
# is enough.
find_program(HELP2MAN help2man)
if(HELP2MAN)
  set(ROOMFIX_MAN_PAGES ON)
else()
  set(ROOMFIX_MAN_PAGES OFF)
endif()

# The devices' firmware (firmware/, docs/devices.md): avr-gcc and avr-libc
# build it; simavr runs it in the tests. Without avr-gcc the firmware is not
# built and its tests skip, saying so.
find_program(AVR_GCC avr-gcc)
find_program(AVR_OBJCOPY avr-objcopy)
find_program(AVR_SIZE avr-size)
if(AVR_GCC AND AVR_OBJCOPY AND AVR_SIZE AND EXISTS /usr/lib/avr/include/avr/io.h)
  set(roomfix_firmware_default ON)
else()
  set(roomfix_firmware_default OFF)
endif()
# Not an option() with the found state as its default: that would be cached
# by the first configure, so a `make demo` on a machine without avr-gcc would
# keep the firmware off after `make test` installs it. Given on the command
# line (-DROOMFIX_FIRMWARE=OFF or ON) it is the user's; otherwise it follows
# what is installed at every configure.
if(NOT DEFINED ROOMFIX_FIRMWARE)
  set(ROOMFIX_FIRMWARE ${roomfix_firmware_default})
endif()
if(ROOMFIX_FIRMWARE AND NOT roomfix_firmware_default)
  message(FATAL_ERROR "ROOMFIX_FIRMWARE is on but avr-gcc, avr-objcopy, avr-size or avr-libc is "
                      "missing: apt-get install gcc-avr binutils-avr avr-libc, or -DROOMFIX_FIRMWARE=OFF")
endif()
# libsimavr (GPL-3+; only the tests and the simulator link it): runs the
# firmware images. Found by hand: Debian's simavr.pc requires libelf.pc,
# which only libelf-dev has, though libsimavr.so links libelf itself.
find_path(SIMAVR_INCLUDE_DIR sim_avr.h PATH_SUFFIXES simavr)
find_library(SIMAVR_LIBRARY simavr)
if(SIMAVR_INCLUDE_DIR AND SIMAVR_LIBRARY AND NOT TARGET Simavr::simavr)
  add_library(Simavr::simavr UNKNOWN IMPORTED)
  set_target_properties(Simavr::simavr PROPERTIES
    IMPORTED_LOCATION ${SIMAVR_LIBRARY}
    INTERFACE_INCLUDE_DIRECTORIES ${SIMAVR_INCLUDE_DIR})
endif()
# The firmware device model (sim/firmware/: roomfix_sim --devices firmware)
# needs simavr; its tests' own AVR programs need avr-gcc too.
if(TARGET Simavr::simavr)
  set(ROOMFIX_HAVE_SIMAVR ON)
else()
  set(ROOMFIX_HAVE_SIMAVR OFF)
  message(STATUS "simavr not found (apt-get install libsimavr-dev simavr): no firmware device "
                 "model (roomfix_sim --devices firmware), its tests are skipped")
endif()
