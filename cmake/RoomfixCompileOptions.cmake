# Warnings for project code; errors only where ROOMFIX_WERROR is on (every
# build folder the Makefile configures, from the first, so that `make demo`
# then `make test` compile each file once; and .ci/run). A packager
# or a user with another compiler gets the warnings and still a build: a new
# compiler's new warning must not stop someone who only wants to run roomfix.
# Third-party headers come from system include directories (and the generated
# LCM headers are marked SYSTEM), so their warnings never show.
option(ROOMFIX_WERROR "Treat compiler warnings as errors (developers and CI)" OFF)

add_compile_options(-Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                    -Wcast-align -Wnull-dereference)
if(ROOMFIX_WERROR)
  add_compile_options(-Werror)
endif()

if(ROOMFIX_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=undefined
                      -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()
