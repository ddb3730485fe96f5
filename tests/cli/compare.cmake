# `softgi compare` on `spheres` at a tiny size and few samples: every technique and both references
# rendered, errors recorded in compare.json and summary.md; bad arguments fail clearly.
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)

# References go through a cache of this test's own, rendered on the first run and served on the
# second (the same scene, frame and options), with the same images.
set(ENV{SOFTGI_CACHE_DIR} ${WORK_DIR}/cache)
set(OUT ${WORK_DIR}/spheres)
execute_process(COMMAND ${SOFTGI} compare --scene spheres --width 48 --height 36 --spp 4 --out ${OUT}
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "softgi compare failed (${rc}):\n${out}${err}")
endif()
if(NOT err MATCHES "compare: reference")
  message(FATAL_ERROR "no progress on stderr:\n${err}")
endif()
foreach(f compare.json summary.md reference_full.exr reference_full.png reference_sh4.png
          shexp/final.exr shexp/final.png shexp/error_full.png shexp/error_sh4.png shexp/record.json)
  if(NOT EXISTS ${OUT}/${f})
    message(FATAL_ERROR "softgi compare did not write ${f}:\n${err}")
  endif()
endforeach()

file(READ ${OUT}/compare.json j)
string(JSON cached GET "${j}" references 0 cached)
if(cached)
  message(FATAL_ERROR "the first run's reference came from the cache:\n${j}")
endif()
execute_process(COMMAND ${SOFTGI} compare --scene spheres --width 48 --height 36 --spp 4 --out ${WORK_DIR}/again
  OUTPUT_VARIABLE out2 ERROR_VARIABLE err2 RESULT_VARIABLE rc)
file(READ ${WORK_DIR}/again/compare.json j2)
string(JSON cached GET "${j2}" references 0 cached)
if(NOT rc EQUAL 0 OR NOT cached OR NOT err2 MATCHES "\\(cached")
  message(FATAL_ERROR "the second run did not use the cached reference (${rc}):\n${err2}")
endif()
execute_process(COMMAND ${SOFTGI} diff ${OUT}/reference_full.exr ${WORK_DIR}/again/reference_full.exr --json
  OUTPUT_VARIABLE d RESULT_VARIABLE rc)
string(JSON max_abs GET "${d}" max_abs)
if(NOT rc EQUAL 0 OR NOT max_abs EQUAL 0)
  message(FATAL_ERROR "the cached reference image differs from the rendered one (${rc}):\n${d}")
endif()
string(JSON scene GET "${j}" scene name)
string(JSON n LENGTH "${j}" techniques)
string(JSON n_refs LENGTH "${j}" references)
if(NOT scene STREQUAL "spheres" OR n LESS 1 OR n_refs LESS 2)
  message(FATAL_ERROR "compare.json: scene '${scene}', ${n} techniques, ${n_refs} references:\n${j}")
endif()
math(EXPR last "${n} - 1")
foreach(i RANGE ${last})
  string(JSON name GET "${j}" techniques ${i} name)
  foreach(ref full sh4)
    foreach(field relmse relmse_raw noise ci_low ci_high ssim flip)
      string(JSON ${field} GET "${j}" techniques ${i} errors_final ${ref} ${field})
    endforeach()
    # The raw relMSE is a mean of non-negative terms; the reference (two halves of 2 spp) has noise,
    # which the corrected value removes, so it lies below the raw one and inside its interval. SSIM of two
    # non-constant images lies in [-1, 1]; a technique against a path-traced reference differs visibly
    # somewhere, so its FLIP mean lies strictly in (0, 1).
    if(relmse_raw LESS 0 OR NOT noise GREATER 0 OR NOT relmse LESS relmse_raw OR ci_low GREATER relmse OR ci_high LESS relmse
       OR ssim LESS -1 OR ssim GREATER 1 OR NOT flip GREATER 0 OR NOT flip LESS 1)
      message(FATAL_ERROR "${name} vs ${ref}: relmse ${relmse} (raw ${relmse_raw}, noise ${noise}, [${ci_low}, ${ci_high}]), ssim ${ssim}, flip ${flip}")
    endif()
  endforeach()
  string(JSON frame_seconds GET "${j}" techniques ${i} frame_seconds)
  if(NOT frame_seconds GREATER 0)
    message(FATAL_ERROR "${name}: frame_seconds ${frame_seconds}")
  endif()
endforeach()

file(READ ${OUT}/summary.md md)
foreach(needle "| technique | total \\(ms\\)" "FLIP vs full" "\\| shexp \\| [0-9.]+ \\|" "shexp/final.png" "reference_full.png"
               "own noise removed" "full: 4 spp, noise ")
  if(NOT md MATCHES "${needle}")
    message(FATAL_ERROR "summary.md lacks '${needle}':\n${md}")
  endif()
endforeach()

expect_failure("unknown technique 'nosuch'" compare --scene spheres --out ${WORK_DIR}/bad --techniques shexp,nosuch)
expect_failure("--spp" compare --scene spheres --out ${WORK_DIR}/bad --spp 0)
expect_failure("--spp must be even, got 3" compare --scene spheres --out ${WORK_DIR}/bad --spp 3)
expect_failure("--target-noise must be a finite relMSE > 0" compare --scene spheres --out ${WORK_DIR}/bad --target-noise 0)
expect_failure("--max-spp must be even and at least --spp" compare --scene spheres --out ${WORK_DIR}/bad --target-noise 1e-3 --spp 8 --max-spp 4)

# --target-noise: rounds until the references' noise over the surface pixels is at most the target,
# or the cap; the record says which, and the noise removed from each error is that noise.
execute_process(COMMAND ${SOFTGI} compare --scene spheres --techniques shexp --width 32 --height 24 --spp 4 --target-noise 0.02
  --max-spp 64 --out ${WORK_DIR}/converged OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "softgi compare --target-noise failed (${rc}):\n${out}${err}")
endif()
file(READ ${WORK_DIR}/converged/compare.json cj)
string(JSON ref_noise GET "${cj}" references 0 noise)
string(JSON ref_spp GET "${cj}" references 0 spp)
string(JSON converged GET "${cj}" references 0 converged)
string(JSON err_noise GET "${cj}" techniques 0 errors_final full noise)
if(NOT ref_spp GREATER 4 OR (converged AND ref_noise GREATER 0.02) OR (NOT converged AND NOT ref_spp EQUAL 64)
   OR NOT err_noise EQUAL ref_noise)
  message(FATAL_ERROR "compare --target-noise 0.02: ${ref_spp} spp, noise ${ref_noise} (converged ${converged}), noise removed ${err_noise}:\n${cj}")
endif()
expect_failure("unknown scene 'nowhere'" compare --scene nowhere --out ${WORK_DIR}/bad)
expect_failure("--scene" compare --out ${WORK_DIR}/bad)
