# `PROGRAM --help` (run by INTERPRETER when given, e.g. bash for a script)
# must print its usage first, on stdout, and exit 0, within seconds: a
# benchmark or script that ignored --help would instead start its work
# (render frames, install packages, build) and print that first.
#   cmake -DPROGRAM=path [-DINTERPRETER=bash] -P check_help.cmake
if(INTERPRETER)
  set(command ${INTERPRETER} ${PROGRAM})
else()
  set(command ${PROGRAM})
endif()
execute_process(COMMAND ${command} --help
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 20)
if(NOT rc STREQUAL "0")
  message(FATAL_ERROR "${PROGRAM} --help: exit ${rc}, expected 0\nstdout:\n${out}\nstderr:\n${err}")
endif()
if(NOT out MATCHES "^usage: ")
  message(FATAL_ERROR "${PROGRAM} --help: stdout does not start with 'usage: '\nstdout:\n${out}\nstderr:\n${err}")
endif()
