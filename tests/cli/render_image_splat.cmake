# `softgi render --technique image_splat` as a user runs it: a small frame on `spheres` writes the
# direct, indirect and final images and a record with the technique's passes and parameters; bad
# parameter combinations fail with a message naming the parameters.
cmake_policy(SET CMP0057 NEW)  # if(IN_LIST) in script mode
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)

set(OUT ${WORK_DIR}/spheres)
execute_process(COMMAND ${SOFTGI} render --scene spheres --technique image_splat --width 64 --height 48
  --param receiver_scale=4 --param indirect_operator=exact --frame 0.5 --out ${OUT}
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "softgi render failed (${rc}):\n${out}${err}")
endif()
foreach(f final.exr final.png direct.exr direct.png indirect.exr indirect.png record.json)
  if(NOT EXISTS ${OUT}/${f})
    message(FATAL_ERROR "softgi render did not write ${f}:\n${err}")
  endif()
endforeach()
file(READ ${OUT}/record.json rec)
string(JSON tech GET "${rec}" technique)
string(JSON scale GET "${rec}" params receiver_scale)
string(JSON op GET "${rec}" params indirect_operator)
if(NOT tech STREQUAL "image_splat" OR NOT scale STREQUAL "4" OR NOT op STREQUAL "exact")
  message(FATAL_ERROR "record: technique '${tech}', receiver_scale '${scale}', indirect_operator '${op}':\n${rec}")
endif()
# The receiver buffer is 16 x 12 at scale 4, and the passes the paper's pipeline needs all ran.
string(JSON n_passes LENGTH "${rec}" passes)
set(names "")
math(EXPR last "${n_passes} - 1")
foreach(i RANGE ${last})
  string(JSON name GET "${rec}" passes ${i} name)
  list(APPEND names ${name})
  if(name STREQUAL "receiver_gbuffer")
    string(JSON rays GET "${rec}" passes ${i} counters rays)
    if(NOT rays EQUAL 192)
      message(FATAL_ERROR "receiver_gbuffer traced ${rays} rays, expected 16 x 12 = 192")
    endif()
  endif()
endforeach()
foreach(p receiver_gbuffer tables bin_proxies accumulate_log exponentiate accumulate_indirect normalize_indirect upsample shade_direct shade_indirect compose)
  if(NOT p IN_LIST names)
    message(FATAL_ERROR "pass ${p} missing from the record: ${names}")
  endif()
endforeach()

expect_failure("indirect_order" render --scene spheres --technique image_splat --width 16 --height 12
  --param indirect_order=4 --out ${WORK_DIR}/bad)
expect_failure("receiver_scale" render --scene spheres --technique image_splat --width 16 --height 12
  --param receiver_scale=3 --out ${WORK_DIR}/bad)
