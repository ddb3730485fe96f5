# Output handling shared by every command that writes files (app/src/output_dir.hpp; docs/architecture.md,
# "Writing outputs"):
#  - an --out / -o path that cannot be written fails before the work: the error names the option and
#    the path, the exit status is non-zero, no work-progress line is printed, nothing is left behind;
#  - a write that fails midway (a directory where an output file should go) leaves no temporary,
#    the other files are written, and the record, written last, lists the missing file and every
#    file written; the exit status is non-zero.
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)

file(WRITE ${WORK_DIR}/afile "x")
file(MAKE_DIRECTORY ${WORK_DIR}/adir)

# expect_fast_failure(PATTERN NO_PROGRESS_PATTERN ARGS...): `softgi ARGS...` fails with a message
# matching PATTERN, prints nothing matching NO_PROGRESS_PATTERN (the first line its work prints),
# and returns within kFastSeconds. The work asked for takes far longer: the fit-proxies and
# reference runs below were still working after 90 s and 60 s; experiment, at its full size,
# relies on the progress line.
set(kFastSeconds 20)
function(expect_fast_failure pattern progress)
  string(TIMESTAMP t0 "%s")
  execute_process(COMMAND ${SOFTGI} ${ARGN} OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  string(TIMESTAMP t1 "%s")
  math(EXPR seconds "${t1} - ${t0}")
  if(rc EQUAL 0)
    message(FATAL_ERROR "softgi ${ARGN} succeeded; expected failure")
  endif()
  if(NOT "${out}${err}" MATCHES "${pattern}")
    message(FATAL_ERROR "softgi ${ARGN}: message does not match '${pattern}':\n${out}${err}")
  endif()
  if("${out}${err}" MATCHES "${progress}")
    message(FATAL_ERROR "softgi ${ARGN}: started the work ('${progress}') before failing on its output path:\n${out}${err}")
  endif()
  if(seconds GREATER kFastSeconds)
    message(FATAL_ERROR "softgi ${ARGN}: took ${seconds} s to fail on its output path (at most ${kFastSeconds} s expected)")
  endif()
endfunction()

# No temporary (*.tmp) and no probe file anywhere under DIR.
function(expect_no_temporaries dir)
  file(GLOB_RECURSE tmps LIST_DIRECTORIES true ${dir}/*)
  list(FILTER tmps INCLUDE REGEX "(\\.tmp|/\\.softgi-write-probe-[0-9]+)$")
  if(tmps)
    message(FATAL_ERROR "temporary files left behind: ${tmps}")
  endif()
endfunction()

# --- Fail fast: the path is checked before the work ------------------------------------------------
# fit-proxies on `spheres` with these settings fits for minutes; -o is checked first.
set(big_fit spheres --spheres 4000 --grid 256 --iterations 100000)
expect_fast_failure("-o '[^']*/adir': is a directory" "fit-proxies: |iteration" fit-proxies ${big_fit} -o ${WORK_DIR}/adir)
expect_fast_failure("-o '[^']*/afile/x.json': directory '[^']*/afile': exists and is not a directory" "fit-proxies: |iteration"
  fit-proxies ${big_fit} -o ${WORK_DIR}/afile/x.json)
expect_fast_failure("-o '[^']*/nodir/': names a directory, not a file" "fit-proxies: |iteration" fit-proxies ${big_fit} -o ${WORK_DIR}/nodir/)

# --out an existing file, or below one.
expect_fast_failure("--out '[^']*/afile': exists and is not a directory" "render: shexp on"
  render --scene spheres --technique shexp --out ${WORK_DIR}/afile)
expect_fast_failure("--out '[^']*/afile/sub': cannot create it: '[^']*/afile' is not a directory" "render: shexp on"
  render --scene spheres --technique shexp --out ${WORK_DIR}/afile/sub)
# reference at 4096 spp on the camera's size renders for many minutes.
expect_fast_failure("--out '[^']*/afile'" "reference spheres|softgi reference:"
  reference --scene spheres --spp 4096 --out ${WORK_DIR}/afile)
expect_fast_failure("--out '[^']*/afile'" "compare: scene|compare: G-buffer"
  compare --scene spheres --spp 4096 --out ${WORK_DIR}/afile)
expect_fast_failure("--out '[^']*/afile/sub'" "experiment: [a-z_]+: scene"
  experiment shexp_orders --out ${WORK_DIR}/afile/sub)
# The record's own name taken by a directory is found before the work too.
file(MAKE_DIRECTORY ${WORK_DIR}/record_taken/record.json)
expect_fast_failure("--out '[^']*/record_taken': 'record.json' there is not a regular file" "render: shexp on"
  render --scene spheres --technique shexp --out ${WORK_DIR}/record_taken)
# diff checks its map files before it reads the images.
set(D ${SOURCE_DIR}/tests/data)
expect_fast_failure("--map '[^']*/adir': is a directory" "^test " diff ${D}/diff_test.exr ${D}/diff_reference.exr --map ${WORK_DIR}/adir)
expect_fast_failure("--signed-map '[^']*/afile/m.png'" "^test " diff ${D}/diff_test.exr ${D}/diff_reference.exr --signed-map ${WORK_DIR}/afile/m.png)
expect_fast_failure("--map and --signed-map name the same file" "^test "
  diff ${D}/diff_test.exr ${D}/diff_reference.exr --map ${WORK_DIR}/m.png --signed-map ${WORK_DIR}/m.png)

# An unwritable directory (the probe file fails). root writes anywhere, so this needs another user.
file(MAKE_DIRECTORY ${WORK_DIR}/readonly)
file(CHMOD ${WORK_DIR}/readonly PERMISSIONS OWNER_READ OWNER_EXECUTE GROUP_READ GROUP_EXECUTE)
execute_process(COMMAND ${CMAKE_COMMAND} -E touch ${WORK_DIR}/readonly/can_write RESULT_VARIABLE touch_rc)
if(touch_rc EQUAL 0)
  message(STATUS "running as a user who writes into read-only directories (root): unwritable-directory checks not run")
else()
  expect_fast_failure("--out '[^']*/readonly': directory is not writable" "render: shexp on"
    render --scene spheres --technique shexp --out ${WORK_DIR}/readonly)
  expect_fast_failure("--out '[^']*/readonly/sub': cannot create directory" "render: shexp on"
    render --scene spheres --technique shexp --out ${WORK_DIR}/readonly/sub)
  expect_fast_failure("-o '[^']*/readonly/p.json': directory is not writable" "fit-proxies: |iteration"
    fit-proxies ${big_fit} -o ${WORK_DIR}/readonly/p.json)
endif()
file(CHMOD ${WORK_DIR}/readonly PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE)

# Nothing of the failed runs is left: no temporaries, no probe file, no directory a check created.
expect_no_temporaries(${WORK_DIR})
foreach(d readonly/sub nodir)
  if(EXISTS ${WORK_DIR}/${d})
    message(FATAL_ERROR "a failed run left ${d} behind")
  endif()
endforeach()
# A directory the check created is removed again when a later argument check fails.
expect_failure("unknown scene 'no-such-scene'" render --scene no-such-scene --technique shexp --out ${WORK_DIR}/new/deeper)
if(EXISTS ${WORK_DIR}/new)
  message(FATAL_ERROR "a render that failed on its scene left its (empty) output directory behind")
endif()

# --- Failure midway -------------------------------------------------------------------------------
# string(JSON) helpers: the value at KEYS..., and whether LIST (a JSON array of strings) holds NAME.
function(json_has_string json name out_var)
  set(found FALSE)
  string(JSON n LENGTH "${json}")
  if(n GREATER 0)
    math(EXPR last "${n} - 1")
    foreach(i RANGE ${last})
      string(JSON v GET "${json}" ${i})
      if(v STREQUAL name)
        set(found TRUE)
      endif()
    endforeach()
  endif()
  set(${out_var} ${found} PARENT_SCOPE)
endfunction()

# check_record(DIR RECORD MISSING WRITTEN...): DIR/RECORD says outputs.complete = false and lists
# exactly MISSING under outputs.missing (with its error); each WRITTEN name is under outputs.written
# and exists; every name under outputs.written exists and MISSING is not among them.
function(check_record dir record missing)
  if(NOT EXISTS ${dir}/${record})
    message(FATAL_ERROR "no ${record} after a failed write; the policy writes it listing the missing file")
  endif()
  file(READ ${dir}/${record} rec)
  string(JSON complete GET "${rec}" outputs complete)
  string(JSON n_missing LENGTH "${rec}" outputs missing)
  string(JSON missing_file GET "${rec}" outputs missing 0 file)
  string(JSON missing_error GET "${rec}" outputs missing 0 error)
  if(complete OR NOT n_missing EQUAL 1 OR NOT missing_file STREQUAL missing OR NOT missing_error MATCHES "${missing}")
    message(FATAL_ERROR "${record}: expected outputs.missing = [${missing}] and complete = false:\n${rec}")
  endif()
  string(JSON written GET "${rec}" outputs written)
  foreach(f ${ARGN})
    json_has_string("${written}" ${f} has)
    if(NOT has)
      message(FATAL_ERROR "${record}: outputs.written lacks ${f}:\n${written}")
    endif()
  endforeach()
  string(JSON n LENGTH "${written}")
  math(EXPR last "${n} - 1")
  foreach(i RANGE ${last})
    string(JSON f GET "${written}" ${i})
    if(NOT EXISTS ${dir}/${f} OR IS_DIRECTORY ${dir}/${f} OR f STREQUAL missing)
      message(FATAL_ERROR "${record} lists ${f} as written, but it is not a file there")
    endif()
  endforeach()
endfunction()

# render: final.png is a directory (not empty, so nothing may delete it). A complete run first, so
# the record of the failed run is seen replacing the previous one.
set(R ${WORK_DIR}/render_midway)
execute_process(COMMAND ${SOFTGI} render --scene spheres --technique shexp --width 32 --height 24 --out ${R}
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
file(READ ${R}/record.json rec)
string(JSON complete GET "${rec}" outputs complete)
if(NOT rc EQUAL 0 OR NOT complete)
  message(FATAL_ERROR "render failed (${rc}) or its record is not complete:\n${out}${err}\n${rec}")
endif()
file(REMOVE ${R}/final.png)
file(WRITE ${R}/final.png/keep "x")
execute_process(COMMAND ${SOFTGI} render --scene spheres --technique shexp --width 32 --height 24 --out ${R}
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(rc EQUAL 0 OR NOT err MATCHES "--out '[^']*/render_midway': 1 of [0-9]+ output file\\(s\\) not written: .*final\\.png")
  message(FATAL_ERROR "render with final.png in the way: exit ${rc}, expected a failure naming final.png:\n${out}${err}")
endif()
expect_no_temporaries(${R})
check_record(${R} record.json final.png final.exr direct.exr direct.png)
file(READ ${R}/record.json rec)
string(JSON final_exr GET "${rec}" images final exr)
string(JSON final_png ERROR_VARIABLE no_png GET "${rec}" images final png)
if(NOT final_exr STREQUAL "final.exr" OR NOT no_png)
  message(FATAL_ERROR "record.json images.final lists a file that was not written:\n${rec}")
endif()

# reference: convergence.json (a text file, written through a temporary as the images are) in the way.
set(F ${WORK_DIR}/reference_midway)
file(WRITE ${F}/convergence.json/keep "x")
execute_process(COMMAND ${SOFTGI} reference --scene spheres --spp 2 --width 16 --height 12 --convergence -q --out ${F}
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(rc EQUAL 0 OR NOT err MATCHES "convergence\\.json")
  message(FATAL_ERROR "reference with convergence.json in the way: exit ${rc}:\n${out}${err}")
endif()
expect_no_temporaries(${F})
check_record(${F} reference.json convergence.json final.exr direct.exr indirect.exr final.png)

# compare: a technique's folder is a file, so its images, error maps and record cannot be written.
set(C ${WORK_DIR}/compare_midway)
file(WRITE ${C}/shexp "x")
execute_process(COMMAND ${SOFTGI} compare --scene spheres --techniques shexp --spp 2 --width 16 --height 12 --out ${C}
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(rc EQUAL 0 OR NOT err MATCHES "shexp/final\\.exr")
  message(FATAL_ERROR "compare with shexp/ in the way: exit ${rc}:\n${out}${err}")
endif()
expect_no_temporaries(${C})
file(READ ${C}/compare.json cj)
string(JSON complete GET "${cj}" outputs complete)
string(JSON n_missing LENGTH "${cj}" outputs missing)
string(JSON written GET "${cj}" outputs written)
json_has_string("${written}" summary.md has_summary)
json_has_string("${written}" reference_full.png has_ref)
json_has_string("${written}" shexp/record.json has_shexp_record)
if(complete OR n_missing LESS 3 OR NOT has_summary OR NOT has_ref OR has_shexp_record)
  message(FATAL_ERROR "compare.json outputs: complete ${complete}, ${n_missing} missing, written ${written}:\n${cj}")
endif()
