# Runs one aerotri command and checks its exit code and output, so that CLI
# behaviour is tested as data in ctest (see tests/CMakeLists.txt).
#   -DEXE=path -DARGS=a|b|c -DCODE=n [-DSTDOUT=regex] [-DSTDOUT_NOT=regex] [-DSTDERR=regex]
#   [-DSTDERR_EMPTY=1] [-DWORKDIR=dir] [-DFILE=path -DFILE_MATCHES=regex]
string(REPLACE "|" ";" arg_list "${ARGS}")
if(NOT WORKDIR)
  set(WORKDIR ".")
endif()
execute_process(COMMAND ${EXE} ${arg_list}
  WORKING_DIRECTORY ${WORKDIR}
  RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT code STREQUAL CODE)
  message(FATAL_ERROR "exit code ${code}, expected ${CODE}\nstdout:\n${out}\nstderr:\n${err}")
endif()
if(DEFINED STDOUT AND NOT out MATCHES "${STDOUT}")
  message(FATAL_ERROR "stdout does not match '${STDOUT}':\n${out}")
endif()
if(DEFINED STDOUT_NOT AND out MATCHES "${STDOUT_NOT}")
  message(FATAL_ERROR "stdout should not match '${STDOUT_NOT}':\n${out}")
endif()
if(DEFINED STDERR AND NOT err MATCHES "${STDERR}")
  message(FATAL_ERROR "stderr does not match '${STDERR}':\n${err}")
endif()
if(DEFINED FILE)
  file(READ ${FILE} content)
  if(NOT content MATCHES "${FILE_MATCHES}")
    message(FATAL_ERROR "${FILE} does not match '${FILE_MATCHES}':\n${content}")
  endif()
endif()
if(STDERR_EMPTY AND NOT err STREQUAL "")
  message(FATAL_ERROR "stderr should be empty (--quiet):\n${err}")
endif()
