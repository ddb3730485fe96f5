// libFuzzer entry point for glTF 2.0 / GLB loading, io::load_gltf (scripts/fuzz.sh builds and runs
// it). The loader reads a path, so each input is written to a scratch file (fuzz.glb or fuzz.gltf,
// by its magic: fuzz_inputs.hpp) in a directory of this process; relative buffer and image URIs
// resolve there and find nothing, data: URIs and the GLB BIN chunk are read.
//
// Properties checked on every input (a violation aborts, which libFuzzer reports as a crash):
//   - no crash, no sanitizer report, JSON of any depth included;
//   - a rejected input throws a std::exception whose message names the file, and leaves the scene
//     as it was (empty);
//   - an accepted scene that scene::validate accepts can be posed (scene::evaluate) with its first
//     clip at two times without an exception; validate itself only throws std::invalid_argument.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "fuzz_inputs.hpp"
#include "softgi/io/gltf.hpp"
#include "softgi/scene/scene.hpp"

namespace {

const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() / ("softgi_fuzz_gltf_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

[[noreturn]] void violated(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz_gltf: %s: %s\n", what, detail.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string name = "fuzz" + softgi::fuzz::gltf_extension(data, size);
  const std::string path = (scratch_dir() / name).string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) violated("cannot write the scratch file", path);
  }
  softgi::scene::Scene scene;
  softgi::io::GltfImport imp;
  try {
    imp = softgi::io::load_gltf(path, scene);
  } catch (const std::exception& e) {
    if (std::string(e.what()).find(name) == std::string::npos) violated("error message does not name the file", e.what());
    if (!scene.meshes.empty() || !scene.nodes.empty() || !scene.materials.empty() || !scene.textures.empty() ||
        !scene.skins.empty() || !scene.clips.empty() || !scene.notices.empty()) {
      violated("a failed load changed the scene", e.what());
    }
    return 0;
  }
  try {
    softgi::scene::validate(scene);
  } catch (const std::invalid_argument&) {
    return 0;  // loaded but not renderable (e.g. coordinates beyond 1e6 m): the caller reports it
  } catch (const std::exception& e) {
    violated("scene::validate threw something other than std::invalid_argument", e.what());
  }
  if (!imp.clips.empty()) scene.active_clip = imp.clips.front();
  try {
    softgi::scene::evaluate(scene, 0.0);
    softgi::scene::evaluate(scene, 0.37);
  } catch (const std::exception& e) {
    violated("a validated scene failed to evaluate", e.what());
  }
  return 0;
}
