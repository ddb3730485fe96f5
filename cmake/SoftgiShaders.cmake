# softgi_add_shaders(TARGET SOURCES a.comp b.vert ... [INCLUDE_DIRS dirs] [DEPENDS generated includes])
# Compiles each GLSL source with glslangValidator at build time (Vulkan 1.2 SPIR-V) into a generated
# header <softgi/shaders/FOLDER/NAME_EXT.h> holding `const uint32_t FOLDER_NAME_EXT[]` (FOLDER: the
# source's folder under shaders/, NAME_EXT: the file name with '.' replaced by '_'), so that two
# folders may each have a shade.comp, and makes TARGET depend on them. Included GLSL headers are tracked through
# glslangValidator's --depfile; included GLSL that the build generates is named in DEPENDS, so that it
# exists before the first compile. shaders/include (softgi_shared.h) is always on the include path.
set(SOFTGI_SHADER_INCLUDE_DIR ${PROJECT_SOURCE_DIR}/shaders/include)
function(softgi_add_shaders target)
  cmake_parse_arguments(A "" "" "SOURCES;INCLUDE_DIRS;DEPENDS" ${ARGN})
  set(_gen_root ${CMAKE_CURRENT_BINARY_DIR}/generated_shaders)
  set(_incs -I${SOFTGI_SHADER_INCLUDE_DIR})
  foreach(_d ${A_INCLUDE_DIRS})
    list(APPEND _incs -I${_d})
  endforeach()
  set(_headers)
  foreach(_src ${A_SOURCES})
    get_filename_component(_abs ${_src} ABSOLUTE)
    get_filename_component(_file ${_abs} NAME)
    get_filename_component(_dir ${_abs} DIRECTORY)
    get_filename_component(_folder ${_dir} NAME)
    string(MAKE_C_IDENTIFIER ${_file} _stem)
    string(MAKE_C_IDENTIFIER "${_folder}_${_file}" _var)
    set(_out_dir ${_gen_root}/softgi/shaders/${_folder})
    file(MAKE_DIRECTORY ${_out_dir})
    set(_header ${_out_dir}/${_stem}.h)
    add_custom_command(OUTPUT ${_header}
      COMMAND Vulkan::glslangValidator -V --target-env vulkan1.2 --quiet ${_incs} --vn ${_var}
              --depfile ${_header}.d -o ${_header} ${_abs}
      MAIN_DEPENDENCY ${_abs}
      DEPENDS ${A_DEPENDS}
      DEPFILE ${_header}.d
      WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}
      COMMENT "glslang ${_folder}/${_file} -> softgi/shaders/${_folder}/${_stem}.h"
      VERBATIM)
    list(APPEND _headers ${_header})
  endforeach()
  target_sources(${target} PRIVATE ${_headers})
  target_include_directories(${target} PRIVATE $<BUILD_INTERFACE:${_gen_root}> $<BUILD_INTERFACE:${SOFTGI_SHADER_INCLUDE_DIR}>)
endfunction()
