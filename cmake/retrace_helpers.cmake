# Small helpers so that each layer's CMakeLists.txt reads as a list of files.

set(RETRACE_WARNINGS -Wall -Wextra -Wno-unused-parameter)

# retrace_add_library(NAME <layer> SRCS <files...> DEPS <targets...>)
# Defines the static library retrace_<layer>; sources include headers as "retrace/<layer>/foo.h".
function(retrace_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_library(retrace_${ARG_NAME} STATIC ${ARG_SRCS})
  target_include_directories(retrace_${ARG_NAME} PUBLIC "${PROJECT_SOURCE_DIR}/src")
  target_compile_options(retrace_${ARG_NAME} PRIVATE ${RETRACE_WARNINGS})
  target_link_libraries(retrace_${ARG_NAME} PUBLIC ${ARG_DEPS})
endfunction()

# retrace_add_test(NAME <name> SRCS <files...> DEPS <targets...> [END_TO_END])
# One GoogleTest executable per *_test.cc, registered in ctest as <layer>/<name>. END_TO_END marks a test that
# teaches, repeats or drives whole sequences (minutes under the sanitizers): it carries the ctest label
# end_to_end and is neither built nor registered when RETRACE_BUILD_END_TO_END_TESTS is OFF.
function(retrace_add_test)
  if(NOT RETRACE_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "END_TO_END" "NAME" "SRCS;DEPS" ${ARGN})
  if(ARG_END_TO_END AND NOT RETRACE_BUILD_END_TO_END_TESTS)
    return()
  endif()
  get_filename_component(layer "${CMAKE_CURRENT_SOURCE_DIR}" NAME)
  set(target "${layer}_${ARG_NAME}")
  add_executable(${target} ${ARG_SRCS})
  target_compile_options(${target} PRIVATE ${RETRACE_WARNINGS})
  target_compile_definitions(${target} PRIVATE RETRACE_SHARED_DATA_DIR="${RETRACE_SHARED_DATA_DIR}")
  target_link_libraries(${target} PRIVATE ${ARG_DEPS} retrace_testing GTest::gtest GTest::gtest_main)
  add_test(NAME "${layer}/${ARG_NAME}" COMMAND ${target})
  set_tests_properties("${layer}/${ARG_NAME}" PROPERTIES TIMEOUT 600)
  if(ARG_END_TO_END)
    set_tests_properties("${layer}/${ARG_NAME}" PROPERTIES LABELS end_to_end)
  endif()
endfunction()

# retrace_add_benchmark(NAME <name> SRCS <files...> DEPS <targets...>)
# A Google Benchmark executable named bench_<layer>_<name>; benchmarks are run by hand, never by ctest.
function(retrace_add_benchmark)
  if(NOT RETRACE_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  get_filename_component(layer "${CMAKE_CURRENT_SOURCE_DIR}" NAME)
  set(target "bench_${layer}_${ARG_NAME}")
  add_executable(${target} ${ARG_SRCS})
  target_compile_options(${target} PRIVATE ${RETRACE_WARNINGS})
  target_compile_definitions(${target} PRIVATE RETRACE_SHARED_DATA_DIR="${RETRACE_SHARED_DATA_DIR}")
  target_link_libraries(${target} PRIVATE ${ARG_DEPS} benchmark::benchmark benchmark::benchmark_main)
endfunction()
