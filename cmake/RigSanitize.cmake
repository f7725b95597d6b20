# Sanitizer and fuzzing builds (docs/fuzzing.md). Both go into a build folder of their own
# (scripts/test-sanitize.sh uses build-asan/); the plain build/ is never instrumented.
#
#   -DRIG_SANITIZE=address,undefined   every target built and linked with these sanitizers,
#                                      -O1 -g, frame pointers kept; undefined behaviour aborts
#                                      (-fno-sanitize-recover) instead of printing and going on
#   -DRIG_FUZZ=ON                      (clang only) every target also carries libFuzzer's
#                                      coverage instrumentation (-fsanitize=fuzzer-no-link), and
#                                      the harnesses of tests/fuzz/ are built; implies
#                                      RIG_SANITIZE=address,undefined when that is not set

set(RIG_SANITIZE "" CACHE STRING "Sanitizers for every target, e.g. address,undefined")
option(RIG_FUZZ "Build the libFuzzer harnesses of tests/fuzz/ (clang only)" OFF)

if(RIG_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "RIG_FUZZ=ON needs clang (libFuzzer), e.g. "
                        "-DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14")
  endif()
  if(RIG_SANITIZE STREQUAL "")
    set(RIG_SANITIZE "address,undefined" CACHE STRING "" FORCE)
  endif()
endif()

if(NOT RIG_SANITIZE STREQUAL "")
  # Added after the build type's flags, so -O1 replaces Release's -O3 (NDEBUG stays: the
  # instrumented code is the code that ships). Line tables only (with clang): a report's stack
  # names file and line; full debug information only costs CI build time and disk.
  add_compile_options(-fsanitize=${RIG_SANITIZE} -fno-omit-frame-pointer -O1)
  if(CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    add_compile_options(-gline-tables-only)
  else()
    add_compile_options(-g1)
  endif()
  add_link_options(-fsanitize=${RIG_SANITIZE})
  if(RIG_SANITIZE MATCHES "undefined")
    add_compile_options(-fno-sanitize-recover=undefined)
  endif()
  message(STATUS "rig: sanitizers ${RIG_SANITIZE}")
endif()

if(RIG_FUZZ)
  add_compile_options(-fsanitize=fuzzer-no-link)
  message(STATUS "rig: libFuzzer coverage instrumentation; harnesses in tests/fuzz/")
endif()

# rig_add_fuzzer(NAME SOURCES ... DEPS ...): a libFuzzer binary fuzz_<NAME>.
function(rig_add_fuzzer name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(fuzz_${name} ${ARG_SOURCES})
  target_link_libraries(fuzz_${name} PRIVATE ${ARG_DEPS})
  target_include_directories(fuzz_${name} PRIVATE ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR})
  target_link_options(fuzz_${name} PRIVATE -fsanitize=fuzzer)
  rig_warnings(fuzz_${name})
endfunction()
