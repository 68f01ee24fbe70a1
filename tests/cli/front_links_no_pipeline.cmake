# The `aerotri` front runs `bal` without the photo pipeline's libraries:
# its dynamic dependencies (ldd) name neither GDAL, OpenCV nor PROJ, and
# every other command still reaches aerotri-photo.
# Usage: cmake -DEXE=path/to/aerotri -P front_links_no_pipeline.cmake
execute_process(COMMAND ldd ${EXE} OUTPUT_VARIABLE libs RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "ldd ${EXE} failed (${rc})")
endif()
foreach(heavy gdal opencv proj)
  if(libs MATCHES "lib${heavy}")
    message(FATAL_ERROR "${EXE} links lib${heavy}, which bal does not use:\n${libs}")
  endif()
endforeach()
if(NOT libs MATCHES "libstdc\\+\\+")
  message(FATAL_ERROR "ldd output unexpected for ${EXE}:\n${libs}")
endif()
execute_process(COMMAND ${EXE} --version OUTPUT_VARIABLE version RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT version MATCHES "gdal")
  message(FATAL_ERROR "aerotri --version did not reach aerotri-photo (exit ${rc}): ${version}")
endif()
