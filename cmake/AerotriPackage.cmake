# SPDX-License-Identifier: BSD-3-Clause
# The installed package: aerotriTargets (every library exported as aerotri::<name>
# by aerotri_add_library), aerotriConfig.cmake that finds their dependencies
# with find_dependency, a version file, aerotri.pc for pkg-config, the licence.
include(CMakePackageConfigHelpers)

set(AEROTRI_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/aerotri)
install(EXPORT aerotriTargets NAMESPACE aerotri:: DESTINATION ${AEROTRI_CMAKE_DIR}
        COMPONENT development)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/aerotriConfig.cmake.in
  ${PROJECT_BINARY_DIR}/aerotriConfig.cmake INSTALL_DESTINATION ${AEROTRI_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/aerotriConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/aerotriConfig.cmake
              ${PROJECT_BINARY_DIR}/aerotriConfigVersion.cmake
              ${PROJECT_SOURCE_DIR}/cmake/AerotriFindGeographicLib.cmake
        DESTINATION ${AEROTRI_CMAKE_DIR} COMPONENT development)

# pkg-config: static archives, so Libs lists them in link order (dependants
# first) followed by what they need. Ceres has no .pc file on Debian; it and
# its glog (and CHOLMOD, which the adjust library calls) are named directly.
set(AEROTRI_PC_LIBS "")
foreach(lib pipeline simulate report export dense sfm survey adjust geometry matching features
            ingest io model georef camera base)
  string(APPEND AEROTRI_PC_LIBS " -laerotri_${lib}")
endforeach()
file(RELATIVE_PATH AEROTRI_PC_PREFIX_FROM_PCFILEDIR
     /root/${CMAKE_INSTALL_LIBDIR}/pkgconfig /root)
configure_file(${PROJECT_SOURCE_DIR}/cmake/aerotri.pc.in ${PROJECT_BINARY_DIR}/aerotri.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/aerotri.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
        COMPONENT development)
install(FILES ${PROJECT_SOURCE_DIR}/LICENSE DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/aerotri
        COMPONENT runtime)
