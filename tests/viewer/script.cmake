# A scripted session (--script) on character: switches technique, a parameter, the backend, moves
# the camera, plays the animation with a fixed step, resizes and minimises the window, splits the
# view and overlays the proxies. Each capture differs from the one before where the state changed
# what is drawn (kDiffers), matches it where only the backend changed (kParity), and equals the frame
# `softgi render` draws from the capture's record (kSame). Settings saved and loaded again give the
# same frame.
include(${CMAKE_CURRENT_LIST_DIR}/lib.cmake)
if(VIEWER_SKIP)
  return()
endif()
file(REMOVE_RECURSE ${WORK_DIR}/out)
file(MAKE_DIRECTORY ${WORK_DIR}/out)
set(O ${WORK_DIR}/out)
file(WRITE ${O}/script.json "{\"actions\": [
  {\"capture\": \"${O}/a\"},
  {\"technique\": \"image_splat\"},
  {\"capture\": \"${O}/b\"},
  {\"param\": \"receiver_scale=4\"},
  {\"capture\": \"${O}/c\"},
  {\"backend\": \"vulkan\"},
  {\"capture\": \"${O}/d\"},
  {\"camera\": {\"orbit\": [30, 10], \"zoom\": 0.8}},
  {\"capture\": \"${O}/e\"},
  {\"resize\": [500, 380]},
  {\"play\": true}, {\"fixed_dt\": 0.1}, {\"frames\": 3}, {\"play\": false},
  {\"minimise\": 2},
  {\"resize\": [900, 700]},
  {\"capture\": \"${O}/f\"},
  {\"split\": \"shexp\"}, {\"overlay\": true}, {\"view\": \"error\"},
  {\"window_shot\": \"${O}/window.png\"},
  {\"save_settings\": \"${O}/settings.json\"},
  {\"camera\": {\"reset\": true}}, {\"technique\": \"shexp\"}, {\"time\": 0},
  {\"load_settings\": \"${O}/settings.json\"},
  {\"capture\": \"${O}/g\"}
]}")
run_viewer(err --scene character --size 128x96 --script ${O}/script.json --ground-truth --ground-truth-spp 4)
message("${err}")
foreach(c a b c d e f g)
  if(NOT EXISTS ${O}/${c}/final.exr)
    message(FATAL_ERROR "the script wrote no capture ${c}:\n${err}")
  endif()
  rerender(${O}/${c} ${O}/cli_${c})
  # The Vulkan captures compare with their re-render on the same backend.
  expect_close(${O}/${c}/final.exr ${O}/cli_${c}/final.exr ${kSame} "capture ${c} against softgi render of its record")
endforeach()
expect_apart(${O}/b/final.exr ${O}/a/final.exr ${kDiffers} "shexp -> image_splat")
expect_apart(${O}/c/final.exr ${O}/b/final.exr ${kDiffers} "receiver_scale 2 -> 4")
expect_close(${O}/d/final.exr ${O}/c/final.exr ${kParity} "cpu -> vulkan")
expect_apart(${O}/e/final.exr ${O}/d/final.exr ${kDiffers} "camera orbit and zoom")
expect_apart(${O}/f/final.exr ${O}/e/final.exr ${kDiffers} "three frames of animation at 0.1 s")
expect_close(${O}/g/final.exr ${O}/f/final.exr ${kSame} "settings saved and loaded")

# The records say what changed.
file(READ ${O}/f/record.json rec)
string(JSON t GET "${rec}" frame_time)
string(JSON b GET "${rec}" backend)
string(JSON s GET "${rec}" params receiver_scale)
if(NOT b STREQUAL "vulkan" OR NOT s EQUAL 4 OR NOT t MATCHES "^0\\.3")
  message(FATAL_ERROR "capture f's record: backend ${b}, receiver_scale ${s}, frame_time ${t} (expected vulkan, 4, 0.3)")
endif()
# The window resize recreated the swapchain, and the window shot holds the interface and the image.
if(NOT err MATCHES "([1-9][0-9]*) swapchain recreations")
  message(FATAL_ERROR "no swapchain recreation after the resize:\n${err}")
endif()
if(NOT EXISTS ${O}/window.png)
  message(FATAL_ERROR "no window shot")
endif()

# A script with an unknown action fails before it opens the window, naming the action.
file(WRITE ${O}/bad.json "{\"actions\": [{\"techniqe\": \"shexp\"}]}")
execute_process(COMMAND ${XVFB_RUN} -a ${VIEWER} --script ${O}/bad.json OUTPUT_VARIABLE o ERROR_VARIABLE e RESULT_VARIABLE rc)
if(rc EQUAL 0 OR NOT e MATCHES "unknown action 'techniqe'")
  message(FATAL_ERROR "a misspelt action: expected an error naming it, got ${rc}:\n${o}${e}")
endif()
