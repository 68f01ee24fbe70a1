# SPDX-License-Identifier: BSD-3-Clause
# Every find_package of the project lives here (the COLMAP FindDependencies pattern).
# All are Debian 12 packages; scripts/install-deps.sh installs them.

find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(Ceres 2.1 REQUIRED)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs features2d calib3d flann stitching)
find_package(PROJ 9 REQUIRED CONFIG)
find_package(GDAL REQUIRED CONFIG)  # GDALConfig accepts only its own minor version
find_package(CLI11 2 REQUIRED CONFIG)
find_package(nlohmann_json 3 REQUIRED CONFIG)
find_package(BZip2 REQUIRED)

include(AerotriFindGeographicLib)

if(AEROTRI_BUILD_TESTS)
  find_package(GTest REQUIRED)
  include(GoogleTest)  # gtest_discover_tests
endif()
