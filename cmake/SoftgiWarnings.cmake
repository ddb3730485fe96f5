# Warning and sanitizer flags, applied per target through softgi_set_target_options().
add_library(softgi_options INTERFACE)
target_compile_options(softgi_options INTERFACE -Wall -Wextra -Wpedantic -Wshadow=local -Wno-missing-field-initializers)
if(SOFTGI_WERROR)
  target_compile_options(softgi_options INTERFACE -Werror)
endif()
if(SOFTGI_SANITIZE)
  target_compile_options(softgi_options INTERFACE -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
  # -O1 in the sanitised Debug build, as AddressSanitizer's documentation advises for usable speed:
  # at -O0 the instrumented suite was the longest part of the test command by far. Frame pointers
  # stay, so the sanitisers' stack traces keep their frames.
  target_compile_options(softgi_options INTERFACE $<$<CONFIG:Debug>:-O1>)
  target_link_options(softgi_options INTERFACE -fsanitize=address,undefined)
endif()

function(softgi_set_target_options target)
  target_link_libraries(${target} PRIVATE $<BUILD_INTERFACE:softgi_options>)
endfunction()
