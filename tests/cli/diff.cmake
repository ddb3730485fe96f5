# `softgi diff` on the checked-in images under tests/data/ (definitions and the hand-computed values
# below are checked by softgi_tests_metrics, DiffTestData.*):
#   diff_reference.exr  16x16 grey, 0.5 left of column 8, 2.0 right of it
#   diff_test.exr       diff_reference + 0.25
#   diff_small.exr      8x8 (size mismatch)      diff_mask.png  white left of column 8
#   diff_nan.pfm        diff_test with a NaN in G at pixel (3, 5)
set(D ${SOURCE_DIR}/tests/data)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)

function(run_json var)
  execute_process(COMMAND ${SOFTGI} ${ARGN} --json OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "softgi ${ARGN} --json failed (${rc}): ${err}")
  endif()
  set(${var} "${out}" PARENT_SCOPE)
endfunction()

# lo <= json[key] <= hi. CMake has no float arithmetic, but if() compares numbers as doubles, so the
# callers write each interval out: the hand value +- 1e-6 (the JSON carries full double precision).
function(expect_within json key lo hi)
  string(JSON v GET "${json}" ${key})
  if(v LESS lo OR v GREATER hi)
    message(FATAL_ERROR "${key} = ${v}, expected within [${lo}, ${hi}]:\n${json}")
  endif()
endfunction()

# All pixels: RMSE = 0.25, relMSE = (0.0625/0.26 + 0.0625/4.01)/2 = 0.127985, PSNR = 10 log10(4/0.0625)
# = 18.0618 dB (peak 2 = reference max), SSIM strictly inside (0, 1).
run_json(j diff ${D}/diff_test.exr ${D}/diff_reference.exr)
expect_within("${j}" rmse 0.249999 0.250001)
expect_within("${j}" max_abs 0.249999 0.250001)
expect_within("${j}" relmse 0.1279843 0.1279863)
expect_within("${j}" psnr 18.0617987 18.0618007)
expect_within("${j}" psnr_peak 1.999999 2.000001)
expect_within("${j}" ssim 0.000001 0.999999)
string(JSON pixels GET "${j}" pixels)
if(NOT pixels EQUAL 256)
  message(FATAL_ERROR "pixels = ${pixels}, expected 256")
endif()

# Mask: left half only. relMSE = 0.0625/0.26, PSNR = 10 log10(0.25/0.0625) = 6.0206 dB (peak 0.5), and the
# counted half is constant, so SSIM = (2 mt mr + 1e-4) / (mt^2 + mr^2 + 1e-4), mt = 3/7, mr = 1/3.
run_json(j diff ${D}/diff_test.exr ${D}/diff_reference.exr --mask ${D}/diff_mask.png
  --map ${WORK_DIR}/map.png --signed-map ${WORK_DIR}/signed.png)
expect_within("${j}" relmse 0.2403836 0.2403856)
expect_within("${j}" psnr 6.0205989 6.0206009)
expect_within("${j}" ssim 0.9692402 0.9692422)
string(JSON pixels GET "${j}" pixels)
if(NOT pixels EQUAL 128)
  message(FATAL_ERROR "masked pixels = ${pixels}, expected 128")
endif()
foreach(f map.png signed.png)
  file(SIZE ${WORK_DIR}/${f} size)
  if(NOT size GREATER 0)
    message(FATAL_ERROR "${f} was not written")
  endif()
endforeach()

# Identical images: RMSE 0, SSIM 1, PSNR infinite, written as the string "inf" (JSON has no infinity).
run_json(j diff ${D}/diff_reference.exr ${D}/diff_reference.exr)
string(JSON psnr GET "${j}" psnr)
string(JSON rmse GET "${j}" rmse)
string(JSON ssim GET "${j}" ssim)
if(NOT psnr STREQUAL "inf" OR NOT rmse EQUAL 0 OR NOT ssim EQUAL 1)
  message(FATAL_ERROR "identical images: psnr=${psnr} rmse=${rmse} ssim=${ssim}")
endif()

# --metric selects what is printed; text output names the metric.
execute_process(COMMAND ${SOFTGI} diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric rmse
  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT out MATCHES "rmse +0.25" OR out MATCHES "ssim")
  message(FATAL_ERROR "--metric rmse (${rc}):\n${out}${err}")
endif()
run_json(j diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric ssim)
string(JSON has_rmse ERROR_VARIABLE no_rmse GET "${j}" rmse)
if(NOT no_rmse)
  message(FATAL_ERROR "--metric ssim --json still prints rmse:\n${j}")
endif()

# Errors: non-zero exit, message naming the problem.
expect_failure("no-such\\.exr" diff ${D}/no-such.exr ${D}/diff_reference.exr)
expect_failure("16x16.*8x8" diff ${D}/diff_test.exr ${D}/diff_small.exr)
expect_failure("metric" diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric flop)
expect_failure("\\(3, 5\\)" diff ${D}/diff_nan.pfm ${D}/diff_reference.exr)
expect_failure("mask.*8x8" diff ${D}/diff_test.exr ${D}/diff_reference.exr --mask ${D}/diff_small.exr)
expect_failure("--epsilon" diff ${D}/diff_test.exr ${D}/diff_reference.exr --epsilon 0)
expect_failure("--map-scale" diff ${D}/diff_test.exr ${D}/diff_reference.exr --map-scale nan --map ${WORK_DIR}/x.png)
expect_failure("reference|required" diff ${D}/diff_test.exr)

# --halves: relMSE with the reference's noise removed. Identical halves carry no noise: the corrected
# value is the plain relMSE against them. Halves diff_test and diff_reference have the mean
# reference + 0.125, which diff_test misses by exactly their half-difference (0.125) at every pixel:
# all of its error is the reference's noise, so the corrected value is 0 and below the noise floor.
run_json(j diff ${D}/diff_test.exr ${D}/diff_reference.exr --halves ${D}/diff_reference.exr ${D}/diff_reference.exr)
string(JSON nc GET "${j}" relmse_noise_corrected)
expect_within("${nc}" corrected 0.1279843 0.1279863)
expect_within("${nc}" reference_noise -0.000001 0.000001)
run_json(j diff ${D}/diff_test.exr ${D}/diff_reference.exr --halves ${D}/diff_test.exr ${D}/diff_reference.exr)
string(JSON nc GET "${j}" relmse_noise_corrected)
expect_within("${nc}" corrected -0.000001 0.000001)
string(JSON floor GET "${nc}" below_noise_floor)
if(NOT floor)
  message(FATAL_ERROR "an error that is all reference noise is not below the noise floor:\n${j}")
endif()
execute_process(COMMAND ${SOFTGI} diff ${D}/diff_test.exr ${D}/diff_reference.exr --halves ${D}/diff_test.exr ${D}/diff_reference.exr
  OUTPUT_VARIABLE o ERROR_VARIABLE e RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT o MATCHES "reference noise removed.*below the reference's noise floor")
  message(FATAL_ERROR "diff --halves text (${rc}):\n${o}${e}")
endif()
expect_failure("second half image is 8x8" diff ${D}/diff_test.exr ${D}/diff_reference.exr --halves ${D}/diff_reference.exr ${D}/diff_small.exr)
expect_failure("--halves" diff ${D}/diff_test.exr ${D}/diff_reference.exr --halves ${D}/diff_reference.exr)

# FLIP (values checked against closed forms in softgi_tests_metrics, Flip*): EXR inputs select HDR-FLIP;
# a 0.25 offset on a 0.5 / 2.0 reference is visible at every exposure, identical images give exactly 0.
run_json(j diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric flip --flip-map ${WORK_DIR}/flip.png)
string(JSON flip GET "${j}" flip)
string(JSON variant GET "${flip}" variant)
string(JSON nexp LENGTH "${flip}" exposures)
if(NOT variant STREQUAL "hdr" OR nexp LESS 2)
  message(FATAL_ERROR "EXR inputs: expected HDR-FLIP over at least 2 exposures:\n${j}")
endif()
expect_within("${flip}" mean 0.01 0.99)
file(SIZE ${WORK_DIR}/flip.png size)
if(NOT size GREATER 0)
  message(FATAL_ERROR "flip.png was not written")
endif()
run_json(j diff ${D}/diff_reference.exr ${D}/diff_reference.exr --metric flip)
string(JSON flip GET "${j}" flip)
expect_within("${flip}" mean 0 0)
# PNG inputs select LDR-FLIP; the masked mean differs from the whole image's.
run_json(j diff ${WORK_DIR}/flip.png ${WORK_DIR}/signed.png --metric flip)
string(JSON flip GET "${j}" flip)
string(JSON variant GET "${flip}" variant)
string(JSON whole GET "${flip}" mean)
if(NOT variant STREQUAL "ldr")
  message(FATAL_ERROR "PNG inputs: expected LDR-FLIP:\n${j}")
endif()
run_json(j diff ${WORK_DIR}/flip.png ${WORK_DIR}/signed.png --metric flip --mask ${D}/diff_mask.png)
string(JSON flip GET "${j}" flip)
string(JSON masked GET "${flip}" mean)
if(masked EQUAL whole)
  message(FATAL_ERROR "the mask did not change the FLIP mean (${whole})")
endif()
expect_failure("outside \\[0, 1\\].*HDR-FLIP" diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric flip --flip ldr)
expect_failure("pixels per degree" diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric flip --ppd 0.5)
expect_failure("HDR-FLIP only" diff ${WORK_DIR}/map.png ${WORK_DIR}/signed.png --metric flip --exposures 3)
expect_failure("start exposure.*above stop" diff ${D}/diff_test.exr ${D}/diff_reference.exr --metric flip
  --start-exposure 2 --stop-exposure 1)
expect_failure("--flip-map names the same file" diff ${D}/diff_test.exr ${D}/diff_reference.exr --map ${WORK_DIR}/m.png
  --flip-map ${WORK_DIR}/m.png)
