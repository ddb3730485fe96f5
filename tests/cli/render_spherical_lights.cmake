# `softgi render --technique spherical_lights` as a user runs it: a small frame of the bending
# cylinder (skinned, soft deformations) writes the direct, indirect and final images and a record with
# the technique's passes and parameters; shadows only leaves the indirect passes out; bad parameters
# fail naming the parameter; a scene without proxies renders with a warning saying what is left out.
cmake_policy(SET CMP0057 NEW)  # if(IN_LIST) in script mode
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)

function(pass_names rec out)
  string(JSON n LENGTH "${rec}" passes)
  set(names "")
  math(EXPR last "${n} - 1")
  foreach(i RANGE ${last})
    string(JSON name GET "${rec}" passes ${i} name)
    list(APPEND names ${name})
  endforeach()
  set(${out} "${names}" PARENT_SCOPE)
endfunction()

set(OUT ${WORK_DIR}/bend)
execute_process(COMMAND ${SOFTGI} render --scene bend --technique spherical_lights --width 48 --height 32
  --param blocking=per_object --param geodesic_frequency=2 --frame 1 --out ${OUT}
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
string(JSON blocking GET "${rec}" params blocking)
string(JSON freq GET "${rec}" params geodesic_frequency)
if(NOT tech STREQUAL "spherical_lights" OR NOT blocking STREQUAL "per_object" OR NOT freq STREQUAL "2")
  message(FATAL_ERROR "record: technique '${tech}', blocking '${blocking}', geodesic_frequency '${freq}':\n${rec}")
endif()
pass_names("${rec}" names)
foreach(p gbuffer sl_setup sl_pose receiver_setup accumulate_log exponentiate shade accumulate_log_samples exponentiate_samples
          sample_shading intensity_update sl_cut accumulate_indirect indirect_image compose)
  if(NOT p IN_LIST names)
    message(FATAL_ERROR "pass ${p} missing from the record: ${names}")
  endif()
endforeach()
# Frequency 2: 42 sample directions per SL, leaves and parents.
string(JSON n_passes LENGTH "${rec}" passes)
math(EXPR last "${n_passes} - 1")
foreach(i RANGE ${last})
  string(JSON name GET "${rec}" passes ${i} name)
  if(name STREQUAL "sl_setup")
    string(JSON dirs GET "${rec}" passes ${i} counters sample_directions)
    string(JSON parents GET "${rec}" passes ${i} counters parent_sls)
    string(REGEX REPLACE "\\.0$" "" parents "${parents}")
    string(REGEX REPLACE "\\.0$" "" dirs "${dirs}")
    math(EXPR expect "(8 + ${parents}) * 42")
    if(NOT dirs EQUAL expect)
      message(FATAL_ERROR "sl_setup: ${dirs} sample directions, expected (8 leaves + ${parents} parents) x 42")
    endif()
  endif()
endforeach()

# Shadows only: no indirect passes, no indirect image.
set(OUT2 ${WORK_DIR}/shadows)
execute_process(COMMAND ${SOFTGI} render --scene sphere_plane --technique spherical_lights --width 24 --height 16
  --param indirect=false --out ${OUT2} OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "softgi render (indirect=false) failed (${rc}):\n${out}${err}")
endif()
file(READ ${OUT2}/record.json rec2)
pass_names("${rec2}" names2)
foreach(p sample_shading intensity_update accumulate_indirect)
  if(p IN_LIST names2)
    message(FATAL_ERROR "indirect=false still ran ${p}: ${names2}")
  endif()
endforeach()

# A scene file with a mesh and no proxies: the frame renders unshadowed and says why.
file(WRITE ${WORK_DIR}/bare.json "{\"name\": \"bare\", \"objects\": [{\"mesh\": \"builtin:plane\", \"size\": [4, 4]}]}")
execute_process(COMMAND ${SOFTGI} render --scene ${WORK_DIR}/bare.json --technique spherical_lights --width 16 --height 12
  --out ${WORK_DIR}/bare OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT err MATCHES "spherical_lights.*proxy")
  message(FATAL_ERROR "a scene without proxies: rc ${rc}, expected a warning naming the missing proxies:\n${out}${err}")
endif()

expect_failure("parameter 'blocking'" render --scene sphere_plane --technique spherical_lights --width 16 --height 12
  --param blocking=diagonal --out ${WORK_DIR}/bad)
expect_failure("parameter 'geodesic_frequency'" render --scene sphere_plane --technique spherical_lights --width 16 --height 12
  --param geodesic_frequency=0 --out ${WORK_DIR}/bad)
