# SPDX-License-Identifier: BSD-3-Clause
# The layering rule, checked at configure time (and by ctest on fixtures):
#   1. the declared aerotri:: links form no cycle;
#   2. a source or header in a library's folder includes headers only from
#      its own folder or from folders of libraries it links, directly or
#      through their PUBLIC/PRIVATE links.
# A static library does not refuse a cycle or an undeclared include at link
# time, so without this an upward #include would build; with it, configuring
# fails and names the file, the include and the missing link.
#
# Input: MANIFEST, a CMake list of "target|folder|dep,dep" (written by
# aerotri_check_layering()), and ROOT, the folder the folders are relative to.
# Usage: cmake -DMANIFEST=layers.txt -DROOT=src -P cmake/CheckLayering.cmake

if(CMAKE_SCRIPT_MODE_FILE)
  cmake_minimum_required(VERSION 3.22)  # policies of the project, also under -P
endif()
if(NOT MANIFEST OR NOT ROOT)
  message(FATAL_ERROR "CheckLayering: MANIFEST and ROOT are required")
endif()
file(READ "${MANIFEST}" _layers)
string(STRIP "${_layers}" _layers)

set(_targets "")
foreach(_entry IN LISTS _layers)
  string(REPLACE "|" ";" _parts "${_entry}")
  list(LENGTH _parts _n)
  if(_n LESS 2)
    message(FATAL_ERROR "CheckLayering: ${MANIFEST}: malformed entry '${_entry}'")
  endif()
  list(GET _parts 0 _t)
  list(GET _parts 1 _folder)
  set(_deps "")
  if(_n GREATER 2)
    list(GET _parts 2 _deps)
    string(REPLACE "," ";" _deps "${_deps}")
  endif()
  string(MAKE_C_IDENTIFIER "${_t}" _id)
  set(_folder_${_id} "${_folder}")
  set(_deps_${_id} "${_deps}")
  string(MAKE_C_IDENTIFIER "${_folder}" _fid)
  set(_owner_${_fid} "${_t}")
  list(APPEND _targets "${_t}")
endforeach()

# _aerotri_closure(<target> <out>): every aerotri target <target> links,
# transitively. Stops with FATAL_ERROR naming the cycle when it meets one.
function(_aerotri_closure target out)
  string(MAKE_C_IDENTIFIER "${target}" id)
  if(DEFINED _closure_${id})
    set(${out} "${_closure_${id}}" PARENT_SCOPE)
    return()
  endif()
  if("${target}" IN_LIST _visiting)
    list(APPEND _visiting "${target}")
    string(REPLACE ";" " -> " chain "${_visiting}")
    message(FATAL_ERROR "aerotri layering: the libraries link in a cycle: ${chain}")
  endif()
  list(APPEND _visiting "${target}")
  set(result "")
  foreach(dep IN LISTS _deps_${id})
    string(MAKE_C_IDENTIFIER "${dep}" did)
    if(NOT DEFINED _folder_${did})
      continue()  # an aerotri:: target outside the manifest (none today)
    endif()
    _aerotri_closure("${dep}" sub)
    list(APPEND result "${dep}" ${sub})
  endforeach()
  list(REMOVE_DUPLICATES result)
  set(_closure_${id} "${result}" PARENT_SCOPE)
  set(${out} "${result}" PARENT_SCOPE)
endfunction()

set(_errors "")
foreach(_t IN LISTS _targets)
  set(_visiting "")
  _aerotri_closure("${_t}" _reach)
  string(MAKE_C_IDENTIFIER "${_t}" _id)
  set(_closure_${_id} "${_reach}")
  set(_folder "${_folder_${_id}}")
  file(GLOB _files "${ROOT}/${_folder}/*.h" "${ROOT}/${_folder}/*.cc")
  foreach(_file IN LISTS _files)
    file(STRINGS "${_file}" _includes REGEX "^[ \t]*#[ \t]*include[ \t]*\"[^\"]+\"")
    foreach(_line IN LISTS _includes)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*$" "\\1" _header "${_line}")
      get_filename_component(_dir "${_header}" DIRECTORY)
      string(MAKE_C_IDENTIFIER "${_dir}" _fid)
      if(NOT DEFINED _owner_${_fid})
        continue()  # not a library folder of this project
      endif()
      set(_owner "${_owner_${_fid}}")
      if(_owner STREQUAL _t OR _owner IN_LIST _reach)
        continue()
      endif()
      file(RELATIVE_PATH _rel "${ROOT}" "${_file}")
      list(APPEND _errors
        "${_rel} includes \"${_header}\" (${_owner}), but ${_t} does not link ${_owner}")
    endforeach()
  endforeach()
endforeach()

if(_errors)
  string(REPLACE ";" "\n  " _text "${_errors}")
  message(FATAL_ERROR "aerotri layering: an include reaches a library that is not linked "
                      "(declare the link, or move the code down a layer):\n  ${_text}")
endif()
list(LENGTH _targets _count)
message(STATUS "aerotri layering: ${_count} libraries, no cycle, every include linked")
