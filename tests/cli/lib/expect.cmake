# Shared by the tests/cli/*.cmake scripts (this folder is outside their glob, so it is no test itself).
# expect_failure(PATTERN ARGS...): `softgi ARGS...` must exit non-zero with a message matching PATTERN.
function(expect_failure pattern)
  execute_process(COMMAND ${SOFTGI} ${ARGN} OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(rc EQUAL 0)
    message(FATAL_ERROR "softgi ${ARGN} succeeded; expected failure")
  endif()
  if(NOT "${out}${err}" MATCHES "${pattern}")
    message(FATAL_ERROR "softgi ${ARGN}: message does not mention '${pattern}':\n${out}${err}")
  endif()
endfunction()
