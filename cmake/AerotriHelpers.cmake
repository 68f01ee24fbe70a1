# SPDX-License-Identifier: BSD-3-Clause
# Thin helpers so per-folder CMake files stay a list of sources and dependencies.

# aerotri_add_library(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Creates target aerotri_<name> with alias aerotri::<name>, one per folder
# (the folder that calls it). Headers are included relative to the project
# root: #include "camera_models/brown.h". PUBLIC_DEPS are what the folder's
# headers include; PRIVATE_DEPS what only its sources do (the COLMAP
# PUBLIC_LINK_LIBS / PRIVATE_LINK_LIBS split). The folder and its aerotri
# dependencies are recorded for aerotri_check_layering(), which refuses a
# cycle and any #include of a folder the target does not link.
#
# Unless NO_INSTALL is given, the library and its folder's headers are
# installed (headers under include/aerotri/<folder>, so the same #include
# lines work for a consumer) and exported as aerotri::<name> in the
# aerotriTargets set that aerotriConfig.cmake loads.
function(aerotri_add_library name)
  cmake_parse_arguments(ARG "NO_INSTALL" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(aerotri_${name} STATIC ${ARG_SOURCES})
  add_library(aerotri::${name} ALIAS aerotri_${name})
  target_include_directories(aerotri_${name} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}/aerotri>)
  target_link_libraries(aerotri_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  aerotri_record_layer(aerotri::${name} ${ARG_PUBLIC_DEPS} ${ARG_PRIVATE_DEPS})
  if(NOT ARG_NO_INSTALL)
    aerotri_install_library(aerotri_${name} ${name})
    file(RELATIVE_PATH folder ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
    file(GLOB headers CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.h)
    install(FILES ${headers} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/aerotri/${folder}
            COMPONENT development)
  endif()
endfunction()

# aerotri_install_library(<target> <export name>): installs <target> into the
# aerotriTargets export set, where it is known as aerotri::<export name>.
function(aerotri_install_library target export_name)
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${export_name})
  install(TARGETS ${target} EXPORT aerotriTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/aerotri)
endfunction()

# aerotri_record_layer(<target> <deps>...): one line of the layering manifest,
# "target|folder|dep,dep", for the aerotri:: targets among <deps>.
function(aerotri_record_layer target)
  file(RELATIVE_PATH folder ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  set(deps "")
  foreach(dep ${ARGN})
    if(dep MATCHES "^aerotri::")
      list(APPEND deps ${dep})
    endif()
  endforeach()
  string(REPLACE ";" "," deps "${deps}")
  set_property(GLOBAL APPEND PROPERTY AEROTRI_LAYERS "${target}|${folder}|${deps}")
endfunction()

# Writes the manifest of every recorded library and checks it (cmake/CheckLayering.cmake):
# configuration fails on a cycle or an upward include.
function(aerotri_check_layering)
  get_property(layers GLOBAL PROPERTY AEROTRI_LAYERS)
  set(manifest ${PROJECT_BINARY_DIR}/aerotri_layers.txt)
  file(WRITE ${manifest} "${layers}")
  set(AEROTRI_LAYERS_MANIFEST ${manifest} PARENT_SCOPE)
  set(MANIFEST ${manifest})
  set(ROOT ${PROJECT_SOURCE_DIR})
  include(${PROJECT_SOURCE_DIR}/cmake/CheckLayering.cmake)
endfunction()

# aerotri_add_test(<module> <name> SOURCES ... [DEPS ...] [TIER unit|pipeline|realdata]
#                  [STATISTICS <gtest pattern>...])
# One gtest executable per unit; each of its test cases is registered in ctest
# as <module>/<name>.<Suite>.<Case> (gtest_discover_tests, listed when ctest
# runs), so `ctest -R georef/` runs one module, cases run in parallel, and a
# case that calls GTEST_SKIP() is reported as skipped, not passed. TIER
# becomes the ctest label (default unit): `ctest -L unit` is the fast tier.
# WHOLE registers the executable as one ctest entry instead: for suites whose
# cases share expensive state in one process (a rendered survey and its
# workspace); a skip anywhere marks the whole entry skipped.
function(aerotri_add_test module name)
  cmake_parse_arguments(ARG "WHOLE" "TIER;TIMEOUT" "SOURCES;DEPS;STATISTICS;INTEGRATION" ${ARGN})
  if(NOT ARG_TIER)
    set(ARG_TIER unit)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  set(target test_${module}_${name})
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  # The unit tier's executables, for the `unit_tier` target (scripts/sanitize.sh
  # builds only what the tier runs).
  if(ARG_TIER STREQUAL "unit")
    set_property(GLOBAL APPEND PROPERTY AEROTRI_UNIT_TIER_TARGETS ${target})
  endif()
  target_compile_definitions(${target} PRIVATE
    AEROTRI_SHARED_DATA="${AEROTRI_SHARED_DATA}"
    AEROTRI_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    AEROTRI_BINARY_DIR="${PROJECT_BINARY_DIR}")
  # "[  SKIPPED ]" as gtest prints it, brackets as character classes.
  set(skipped "[[]  SKIPPED []]")
  if(ARG_WHOLE)
    add_test(NAME ${module}/${name} COMMAND ${target})
    set_tests_properties(${module}/${name} PROPERTIES LABELS ${ARG_TIER} TIMEOUT ${ARG_TIMEOUT}
                         SKIP_REGULAR_EXPRESSION "${skipped}")
    return()
  endif()
  # STATISTICS: gtest patterns (Suite.Case, '*' allowed) of cases whose truth
  # is statistical and takes blocks big enough to judge it (8 s or more
  # each): labelled `statistics`. INTEGRATION: cases that run a whole
  # survey adjustment, command or orthomosaic end to end (4 s or more each):
  # labelled `integration`. The rest of the executable keeps its tier, so the
  # unit tier stays under two minutes.
  set(excluded ${ARG_STATISTICS} ${ARG_INTEGRATION})
  set(filter "")
  if(excluded)
    list(JOIN excluded ":" patterns)
    set(filter TEST_FILTER "-${patterns}")
  endif()
  gtest_discover_tests(${target}
    TEST_PREFIX "${module}/${name}."
    ${filter}
    DISCOVERY_MODE PRE_TEST
    PROPERTIES LABELS ${ARG_TIER} TIMEOUT ${ARG_TIMEOUT}
               SKIP_REGULAR_EXPRESSION "${skipped}")
  foreach(label statistics integration)
    string(TOUPPER ${label} key)
    if(NOT ARG_${key})
      continue()
    endif()
    list(JOIN ARG_${key} ":" patterns)
    gtest_discover_tests(${target}
      TEST_PREFIX "${module}/${name}."
      TEST_FILTER "${patterns}"
      DISCOVERY_MODE PRE_TEST
      PROPERTIES LABELS ${label} TIMEOUT ${ARG_TIMEOUT}
                 SKIP_REGULAR_EXPRESSION "${skipped}")
  endforeach()
endfunction()
