// libFuzzer entry point for the environment-map image reader, io::read_rgb_float (OpenImageIO;
// scripts/fuzz.sh builds and runs it). The reader takes a path, so each input is written to a
// scratch file named fuzz.hdr, fuzz.exr or fuzz.png by its magic (fuzz_inputs.hpp).
//
// Properties checked on every input (a violation aborts, which libFuzzer reports as a crash):
//   - no crash, no sanitizer report;
//   - a rejected input throws a std::exception whose message names the file;
//   - an accepted image has sides in [1, 32768], exactly width * height * 3 floats, all finite.
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "fuzz_inputs.hpp"
#include "softgi/io/image_io.hpp"

namespace {

const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() / ("softgi_fuzz_env_image_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

[[noreturn]] void violated(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz_env_image: %s: %s\n", what, detail.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string name = "fuzz" + softgi::fuzz::image_extension(data, size);
  const std::string path = (scratch_dir() / name).string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) violated("cannot write the scratch file", path);
  }
  int width = -1, height = -1;
  std::vector<float> rgb;
  try {
    softgi::io::read_rgb_float(path, width, height, rgb);
  } catch (const std::exception& e) {
    if (std::string(e.what()).find(name) == std::string::npos) violated("error message does not name the file", e.what());
    return 0;
  }
  if (width < 1 || height < 1 || width > 32768 || height > 32768) {
    violated("accepted an image of absurd size", std::to_string(width) + "x" + std::to_string(height));
  }
  if (rgb.size() != std::size_t(width) * std::size_t(height) * 3) {
    violated("pixel count does not match the size", std::to_string(rgb.size()) + " floats for " + std::to_string(width) +
                                                        "x" + std::to_string(height));
  }
  for (std::size_t i = 0; i < rgb.size(); ++i) {
    if (!std::isfinite(rgb[i])) violated("accepted a non-finite pixel", "float " + std::to_string(i));
  }
  return 0;
}
