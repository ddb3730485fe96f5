# `softgi render` of a frame too large for the memory it may use: refused in seconds, before any
# pass, with a non-zero exit, a message naming the memory needed, the largest resource and the limit,
# and no output written. The limit is declared (SOFTGI_MEMORY_LIMIT) so that the outcome does not
# depend on this machine's memory; a frame that fits still renders under it, and a limit that is
# not a size is an error naming the variable.
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)
set(ENV{SOFTGI_MEMORY_LIMIT} 4GiB)

# Planning and the estimate take milliseconds; the rest is process start and scene construction.
# Before the estimate, this frame ran 45 s into its G-buffer before std::bad_alloc.
set(kMaxSeconds 20)

function(expect_refused technique backend largest)
  set(out_dir ${WORK_DIR}/${technique}_${backend})
  string(TIMESTAMP t0 "%s")
  execute_process(COMMAND ${SOFTGI} render --scene spheres --technique ${technique} --backend ${backend}
    --width 16384 --height 16384 --out ${out_dir}
    OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  string(TIMESTAMP t1 "%s")
  math(EXPR seconds "${t1} - ${t0}")
  if(rc EQUAL 0)
    message(FATAL_ERROR "${technique} on ${backend} at 16384x16384 rendered under SOFTGI_MEMORY_LIMIT=4GiB:\n${out}${err}")
  endif()
  if(seconds GREATER kMaxSeconds)
    message(FATAL_ERROR "${technique} on ${backend}: refused after ${seconds} s (expected at most ${kMaxSeconds}):\n${err}")
  endif()
  set(pattern "render: ${technique} at 16384x16384 needs about [0-9.]+ GiB of [a-z ()]*memory[a-z ()]* \\(largest: '${largest}' [0-9.]+ [GM]iB")
  if(NOT "${err}" MATCHES "${pattern}")
    message(FATAL_ERROR "${technique} on ${backend}: the message does not match '${pattern}':\n${out}${err}")
  endif()
  if(NOT "${err}" MATCHES "the ${backend} backend( \\(device '[^']+'\\))? has 4.0 GiB available \\(SOFTGI_MEMORY_LIMIT=4GiB\\)")
    message(FATAL_ERROR "${technique} on ${backend}: the message does not name the limit:\n${err}")
  endif()
  foreach(f final.exr final.png record.json)
    if(EXISTS ${out_dir}/${f})
      message(FATAL_ERROR "${technique} on ${backend}: a refused frame wrote ${f}")
    endif()
  endforeach()
endfunction()

expect_refused(shexp cpu gbuffer)
expect_refused(image_splat cpu gbuffer)

# The Vulkan backend where this machine has one (lavapipe at least). Its per-buffer limits are the
# device's own and may refuse the frame first: whichever limit refuses it is named.
execute_process(COMMAND ${SOFTGI} backends --json OUTPUT_VARIABLE backends RESULT_VARIABLE rc)
string(JSON n LENGTH "${backends}")
math(EXPR last "${n} - 1")
set(vulkan_available OFF)
foreach(i RANGE ${last})
  string(JSON name GET "${backends}" ${i} name)
  string(JSON avail GET "${backends}" ${i} available)
  if(name STREQUAL "vulkan" AND avail)
    set(vulkan_available ON)
  endif()
endforeach()
if(vulkan_available)
  foreach(technique shexp image_splat)
    set(out_dir ${WORK_DIR}/${technique}_vulkan)
    string(TIMESTAMP t0 "%s")
    execute_process(COMMAND ${SOFTGI} render --scene spheres --technique ${technique} --backend vulkan
      --width 16384 --height 16384 --out ${out_dir}
      OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
    string(TIMESTAMP t1 "%s")
    math(EXPR seconds "${t1} - ${t0}")
    if(rc EQUAL 0 OR seconds GREATER kMaxSeconds)
      message(FATAL_ERROR "${technique} on vulkan at 16384x16384: exit ${rc} after ${seconds} s:\n${out}${err}")
    endif()
    if(NOT "${err}" MATCHES "render: ${technique} at 16384x16384 needs [^\n]*'[^']+' [^\n]*(available|maxStorageBufferRange|maxMemoryAllocationSize)")
      message(FATAL_ERROR "${technique} on vulkan: the message names no resource and limit:\n${out}${err}")
    endif()
    if(EXISTS ${out_dir}/final.exr)
      message(FATAL_ERROR "${technique} on vulkan: a refused frame wrote final.exr")
    endif()
  endforeach()
else()
  message(STATUS "no Vulkan device: the Vulkan half of this test is left out")
endif()

# A frame that fits renders under the same limit.
execute_process(COMMAND ${SOFTGI} render --scene spheres --technique image_splat --width 64 --height 48 --out ${WORK_DIR}/small
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK_DIR}/small/final.exr)
  message(FATAL_ERROR "a 64x48 frame failed under SOFTGI_MEMORY_LIMIT=4GiB (${rc}):\n${out}${err}")
endif()

set(ENV{SOFTGI_MEMORY_LIMIT} "lots")
expect_failure("SOFTGI_MEMORY_LIMIT: 'lots' is not a memory size" render --scene spheres --technique shexp --width 64 --height 48
  --out ${WORK_DIR}/bad)
