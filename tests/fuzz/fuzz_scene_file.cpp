// libFuzzer entry point for the JSON scene-file parser (scripts/fuzz.sh builds and runs it).
// Relative paths in the input resolve against tests/fuzz/data, so mutated scenes can reach the
// glTF, proxy-file and environment-map loaders through the small fixtures kept there.
//
// Properties checked on every input (a violation aborts, which libFuzzer reports as a crash):
//   - no crash, no sanitizer report;
//   - a rejected input throws a std::exception whose message names the file ("fuzz.json");
//   - an accepted scene can be posed (scene::evaluate) at two times without an exception.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "softgi/io/scene_file.hpp"
#include "softgi/scene/scene.hpp"

#ifndef SOFTGI_FUZZ_DATA_DIR
#error "build with -DSOFTGI_FUZZ_DATA_DIR=\"<repo>/tests/fuzz/data\" (scripts/fuzz.sh does)"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  softgi::scene::Scene scene;
  try {
    // No proxy fits (seconds each, and a disk cache): the parser, not the fitter, is under test.
    softgi::io::LoadOptions opt;
    opt.fit_proxies = false;
    opt.cache_dir = "";
    scene = softgi::io::parse_scene_json(text, SOFTGI_FUZZ_DATA_DIR, "fuzz.json", opt);
  } catch (const std::exception& e) {
    if (std::string(e.what()).find("fuzz.json") == std::string::npos) {
      std::fprintf(stderr, "error message does not name the file: %s\n", e.what());
      std::abort();
    }
    return 0;
  }
  try {
    softgi::scene::evaluate(scene, 0.0);
    softgi::scene::evaluate(scene, 0.37);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "a validated scene failed to evaluate: %s\n", e.what());
    std::abort();
  }
  return 0;
}
