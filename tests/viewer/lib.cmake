# Shared by the softgi-viewer tests (tests/viewer/*.cmake): the viewer runs on a virtual X server
# (xvfb-run) with lavapipe, with the validation layer on both its display device and the render
# backend; any validation message fails the run.
cmake_policy(SET CMP0057 NEW)

# Tolerances, as relMSE (softgi diff) between two final images:
# - kSame: the same state rendered twice through the same backend (the viewer and `softgi render`
#   call the same Backend::render on the same inputs): measured 0 on every technique and backend;
#   the bound leaves room only for float sums a device's atomics may reorder.
# - kParity: the same state on the CPU and Vulkan backends: the backends' parity bound for a final
#   image (measured 9e-10 for image_splat on character).
# - kDiffers: two states that should look different (another technique, a parameter that changes
#   the image, a camera move, a later time): the smallest change the scripted session makes,
#   image_splat's receiver_scale 2 -> 4 on character at 128x96, measured 5.6e-5; kSame's noise is
#   four orders of magnitude below 1e-5.
set(kSame 1e-9)
set(kParity 1e-6)
set(kDiffers 1e-5)

# A test that finds no virtual X server prints "SKIP: ..." (the tests' SKIP_REGULAR_EXPRESSION) and
# returns when VIEWER_SKIP is set.
find_program(XVFB_RUN xvfb-run)
set(VIEWER_SKIP FALSE)
if(NOT XVFB_RUN)
  message("SKIP: xvfb-run is not installed (scripts/install-deps.sh installs xvfb), so no window can be opened")
  set(VIEWER_SKIP TRUE)
endif()

set(ENV{SOFTGI_VULKAN_VALIDATION} 1)
if(NOT DEFINED ENV{XDG_RUNTIME_DIR})
  file(MAKE_DIRECTORY ${WORK_DIR}/xdg)
  set(ENV{XDG_RUNTIME_DIR} ${WORK_DIR}/xdg)
endif()

# run_viewer(OUT_VAR ARGS...): softgi-viewer ARGS under Xvfb; fails the test on a non-zero exit or any
# validation message; OUT_VAR receives stderr.
function(run_viewer out_var)
  execute_process(COMMAND ${XVFB_RUN} -a -s "-screen 0 1600x1200x24" ${VIEWER} ${ARGN}
    OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "softgi-viewer ${ARGN} failed (${rc}):\n${out}${err}")
  endif()
  if("${out}${err}" MATCHES "validation (error|warning)")
    message(FATAL_ERROR "softgi-viewer ${ARGN}: validation messages:\n${out}${err}")
  endif()
  set(${out_var} "${err}" PARENT_SCOPE)
endfunction()

# relmse(OUT_VAR TEST REFERENCE): softgi diff's relMSE of two images.
function(relmse out_var test ref)
  execute_process(COMMAND ${SOFTGI} diff ${test} ${ref} --metric relmse OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "relmse +([0-9.eE+-]+|inf|nan)")
    message(FATAL_ERROR "softgi diff ${test} ${ref} failed (${rc}):\n${out}${err}")
  endif()
  set(${out_var} ${CMAKE_MATCH_1} PARENT_SCOPE)
endfunction()

# Compares two numbers in floating point (CMake's if() compares integers only).
function(float_less out_var a b)
  execute_process(COMMAND awk "BEGIN { exit !(${a} < ${b}) }" RESULT_VARIABLE rc)
  if(rc EQUAL 0)
    set(${out_var} TRUE PARENT_SCOPE)
  else()
    set(${out_var} FALSE PARENT_SCOPE)
  endif()
endfunction()

# expect_close(A B TOL WHAT) / expect_apart(A B TOL WHAT): relMSE(A, B) <= TOL, or > TOL.
function(expect_close a b tol what)
  relmse(e ${a} ${b})
  float_less(bad ${tol} ${e})
  if(bad OR e STREQUAL "nan")
    message(FATAL_ERROR "${what}: relMSE ${e} > ${tol} (${a} against ${b})")
  endif()
  message("${what}: relMSE ${e} <= ${tol}")
endfunction()
function(expect_apart a b tol what)
  relmse(e ${a} ${b})
  float_less(close ${e} ${tol})
  if(close OR e STREQUAL ${tol})
    message(FATAL_ERROR "${what}: relMSE ${e} <= ${tol}: the images should differ (${a} against ${b})")
  endif()
  message("${what}: relMSE ${e} > ${tol}")
endfunction()

# rerender(CAPTURE_DIR OUT_DIR): runs the `command_line` a capture's record.json gives (softgi render
# with the capture's scene, camera, technique, parameters, backend, time and size) into OUT_DIR.
function(rerender capture out)
  file(READ ${capture}/record.json rec)
  string(JSON cmd GET "${rec}" command_line)
  separate_arguments(args UNIX_COMMAND "${cmd}")
  list(POP_FRONT args program)  # softgi
  list(FIND args "--out" i)
  if(i LESS 0)
    message(FATAL_ERROR "${capture}/record.json: command_line has no --out: ${cmd}")
  endif()
  math(EXPR j "${i} + 1")
  list(REMOVE_AT args ${j})
  list(INSERT args ${j} ${out})
  execute_process(COMMAND ${SOFTGI} ${args} OUTPUT_VARIABLE o ERROR_VARIABLE e RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "re-render of ${capture} failed (${rc}): ${cmd}\n${o}${e}")
  endif()
endfunction()
