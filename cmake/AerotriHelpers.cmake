# SPDX-License-Identifier: BSD-3-Clause
# Thin helpers so per-folder CMake files stay a list of sources and dependencies.

# aerotri_add_library(<name> SOURCES ... [DEPS ...])
# Creates target aerotri_<name> with alias aerotri::<name>. Headers are included
# relative to the project root: #include "camera_models/brown.h".
function(aerotri_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(aerotri_${name} STATIC ${ARG_SOURCES})
  add_library(aerotri::${name} ALIAS aerotri_${name})
  target_include_directories(aerotri_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(aerotri_${name} PUBLIC ${ARG_DEPS})
endfunction()

# aerotri_add_test(<module> <name> SOURCES ... [DEPS ...])
# One gtest executable per unit; registered in ctest as <module>/<name> so that
# `ctest -R georef/` runs one module.
function(aerotri_add_test module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  set(target test_${module}_${name})
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${target} PRIVATE
    AEROTRI_SHARED_DATA="${AEROTRI_SHARED_DATA}"
    AEROTRI_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    AEROTRI_BINARY_DIR="${PROJECT_BINARY_DIR}")
  add_test(NAME ${module}/${name} COMMAND ${target})
  set_tests_properties(${module}/${name} PROPERTIES
    ENVIRONMENT "AEROTRI_EXE=$<TARGET_FILE:aerotri>")
endfunction()
