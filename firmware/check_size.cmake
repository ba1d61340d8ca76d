# Prints a firmware image's flash and RAM use (avr-size -C) and fails the
# build when either passes its budget. Run by firmware/CMakeLists.txt:
#   cmake -DAVR_SIZE=... -DELF=... -DFLASH_BUDGET=... -DRAM_BUDGET=... -P check_size.cmake
execute_process(COMMAND ${AVR_SIZE} -C --mcu=atmega328p ${ELF}
                OUTPUT_VARIABLE report RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "avr-size failed on ${ELF}")
endif()
string(REGEX MATCH "Program: +([0-9]+) bytes" _ "${report}")
set(flash ${CMAKE_MATCH_1})
string(REGEX MATCH "Data: +([0-9]+) bytes" _ "${report}")
set(ram ${CMAKE_MATCH_1})
if(flash STREQUAL "" OR ram STREQUAL "")
  message(FATAL_ERROR "could not read avr-size's report for ${ELF}:\n${report}")
endif()
get_filename_component(name ${ELF} NAME)
math(EXPR flash_pct "100 * ${flash} / 32768")
math(EXPR ram_pct "100 * ${ram} / 2048")
message("firmware ${name}: flash ${flash} of 32768 bytes (${flash_pct} %, budget ${FLASH_BUDGET}), "
        "static RAM ${ram} of 2048 bytes (${ram_pct} %, budget ${RAM_BUDGET})")
if(flash GREATER FLASH_BUDGET)
  message(FATAL_ERROR "${name}: flash ${flash} bytes is over the budget of ${FLASH_BUDGET}")
endif()
if(ram GREATER RAM_BUDGET)
  message(FATAL_ERROR "${name}: static RAM ${ram} bytes is over the budget of ${RAM_BUDGET}")
endif()
