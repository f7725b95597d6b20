# Small helpers that keep each folder's CMakeLists short and the warnings uniform.

function(rig_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wno-missing-field-initializers
    # GCC 12 reports false -Wrestrict positives inside std::string (GCC bug 105329).
    $<$<CXX_COMPILER_ID:GNU>:-Wno-restrict>)
  if(RIG_PCH)
    # With the standard headers precompiled, GCC 12 at -O3 also reports std::string's inlined
    # copies as -Wstringop-overflow / -Wstringop-overread / -Warray-bounds (GCC bugs 105651,
    # 106199), false positives it otherwise hides as system-header code. Clang's own -Warray-bounds still checks ours in
    # the sanitizer build (scripts/test-sanitize.sh).
    target_compile_options(${target} PRIVATE
      $<$<CXX_COMPILER_ID:GNU>:-Wno-stringop-overflow> $<$<CXX_COMPILER_ID:GNU>:-Wno-stringop-overread>
      $<$<CXX_COMPILER_ID:GNU>:-Wno-array-bounds>)
  endif()
  if(RIG_UNITY_BUILD)
    # A source compiled inside a batch is no longer GCC's "main file", so a class of it with
    # a field of a file-local (anonymous-namespace) type is reported as if it were in a header.
    target_compile_options(${target} PRIVATE $<$<CXX_COMPILER_ID:GNU>:-Wno-subobject-linkage>)
  endif()
  if(RIG_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# rig_precompile(TARGET HEADER...): the heavy headers most of a target's sources include,
# parsed once for the target instead of once per source (RIG_PCH; measured in docs/build.md).
# Only headers of libraries the target links: a precompiled header is included first in every
# source of the target.
function(rig_precompile target)
  if(RIG_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN})
  endif()
endfunction()

# rig_add_library(NAME SOURCES ... DEPS ...)
function(rig_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR})
  target_link_libraries(${name} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  rig_warnings(${name})
  # RIG_UNITY_BUILD (default ON; docs/build.md): a library's sources compiled in batches, each
  # template instantiated and each inline function of the heavy headers compiled once per
  # batch instead of once per source. File-local names must therefore be unique within a
  # library (a collision is a compile error, so every build catches it).
  if(RIG_UNITY_BUILD)
    set_target_properties(${name} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${RIG_UNITY_BATCH})
  endif()
endfunction()

# rig_add_test(NAME SOURCES ... DEPS ... [LABELS ...] [ENV ...] [FIXTURES ...])
function(rig_add_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS;ENV;FIXTURES" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR})
  rig_warnings(${name})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  gtest_discover_tests(${name}
    DISCOVERY_TIMEOUT 60
    PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}" ENVIRONMENT "${ARG_ENV}"
               FIXTURES_REQUIRED "${ARG_FIXTURES}"
               WORKING_DIRECTORY ${PROJECT_BINARY_DIR})
endfunction()
