# SPDX-License-Identifier: BSD-3-Clause
# Debian's GeographicLib ships only a find module, outside CMake's default
# path, and that module defines variables, not a target. This finds it and
# provides GeographicLib::GeographicLib. Used by the build (Dependencies.cmake)
# and by the installed package (aerotriConfig.cmake), whose exported targets
# link GeographicLib::GeographicLib.
list(APPEND CMAKE_MODULE_PATH /usr/share/cmake/geographiclib)
find_package(GeographicLib 2 REQUIRED MODULE)
if(NOT TARGET GeographicLib::GeographicLib)
  add_library(GeographicLib::GeographicLib UNKNOWN IMPORTED)
  set_target_properties(GeographicLib::GeographicLib PROPERTIES
    IMPORTED_LOCATION "${GeographicLib_LIBRARIES}"
    INTERFACE_INCLUDE_DIRECTORIES "${GeographicLib_INCLUDE_DIRS}")
endif()
