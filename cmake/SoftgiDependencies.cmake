# Every dependency is a Debian 12 package (scripts/install-deps.sh installs them). Nothing is
# vendored and nothing is downloaded during the build.
find_package(Threads REQUIRED)   # before glslang: its config uses Threads::Threads without finding it
find_package(Eigen3 3.4 CONFIG REQUIRED)
find_package(TBB CONFIG REQUIRED)
find_package(nlohmann_json 3 CONFIG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(Vulkan REQUIRED COMPONENTS glslangValidator)
find_package(glslang CONFIG REQUIRED)
find_package(SPIRV-Tools-opt CONFIG REQUIRED)
find_package(glfw3 3.3 CONFIG REQUIRED)
find_package(glm CONFIG REQUIRED)
find_package(TinyGLTF CONFIG REQUIRED)
find_package(draco CONFIG REQUIRED)   # tinygltf is built without Draco: KHR_draco_mesh_compression is decoded by softgi
find_package(embree 3 CONFIG REQUIRED)
if(SOFTGI_WITH_OIIO)
  find_package(OpenImageIO CONFIG REQUIRED)
  # Debian's OpenImageIO target lists /usr/include/opencv4, which does not exist; drop it or generation fails.
  get_target_property(_softgi_oiio_inc OpenImageIO::OpenImageIO INTERFACE_INCLUDE_DIRECTORIES)
  if(_softgi_oiio_inc)
    list(REMOVE_ITEM _softgi_oiio_inc /usr/include/opencv4)
    set_target_properties(OpenImageIO::OpenImageIO PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_softgi_oiio_inc}")
  endif()
endif()
if(SOFTGI_BUILD_APP AND SOFTGI_BUILD_VIEWER)
  # Debian's libimgui-dev: one static library with the GLFW and Vulkan backends, found by pkg-config.
  find_package(PkgConfig REQUIRED)
  pkg_check_modules(IMGUI REQUIRED IMPORTED_TARGET imgui>=1.86)
endif()
if(SOFTGI_BUILD_TESTS)
  find_package(GTest CONFIG REQUIRED)
endif()
if(SOFTGI_BUILD_BENCH)
  find_package(benchmark CONFIG REQUIRED)
endif()
# Build-time GLSL -> SPIR-V (softgi_add_shaders); needs Vulkan::glslangValidator found above.
include(SoftgiShaders)
