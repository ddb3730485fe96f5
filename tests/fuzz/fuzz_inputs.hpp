// What the file-based fuzz targets (fuzz_gltf.cpp, fuzz_env_image.cpp) and their corpus replay
// (tests/io/test_fuzz_corpus.cpp) share: the loaders take paths, so an input is written to a file
// whose extension follows its first bytes. The replay names files exactly as the fuzzer did, so a
// corpus input reaches the same reader in both.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

namespace softgi::fuzz {

inline bool starts_with(const std::uint8_t* data, std::size_t size, const char* magic, std::size_t n) {
  return size >= n && std::memcmp(data, magic, n) == 0;
}

// ".glb" for the GLB magic, else ".gltf". io::load_gltf itself tells them apart by the magic; the
// extension only keeps the messages readable.
inline std::string gltf_extension(const std::uint8_t* data, std::size_t size) {
  return starts_with(data, size, "glTF", 4) ? ".glb" : ".gltf";
}

// OpenImageIO picks its reader by extension (then tries the others when that one refuses the file),
// so an input goes to the reader its magic names: Radiance HDR, OpenEXR, PNG; anything else is
// offered as ".hdr", the usual environment-map format.
inline std::string image_extension(const std::uint8_t* data, std::size_t size) {
  if (starts_with(data, size, "\x76\x2f\x31\x01", 4)) return ".exr";
  if (starts_with(data, size, "\x89PNG", 4)) return ".png";
  return ".hdr";
}

}  // namespace softgi::fuzz
