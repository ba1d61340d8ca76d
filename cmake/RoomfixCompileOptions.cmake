# Warnings are errors for project code. Third-party headers come from system
# include directories (and the generated LCM headers are marked SYSTEM), so
# their warnings do not stop the build.
add_compile_options(-Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                    -Wcast-align -Wnull-dereference -Werror)

if(ROOMFIX_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=undefined
                      -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()
