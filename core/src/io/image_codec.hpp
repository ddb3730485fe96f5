// The file formats behind io/image_io.hpp: OpenImageIO where the build has it (SOFTGI_WITH_OIIO,
// image_codec_oiio.cpp, the only translation unit that includes it), else the built-in codec
// (image_codec_builtin.cpp: uncompressed OpenEXR read and write, PNG write), which a build for a
// bare machine uses so that it does not carry OpenImageIO's dependency tree.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace softgi::io::codec {

// Larger sides are treated as corrupt headers rather than images: a 32768-wide lat-long map is
// already 8x the finest environment map in the asset set.
inline constexpr int kMaxSide = 32768;
// 2^28 pixels (3 GiB as float RGB) is the most one image may hold.
inline constexpr std::int64_t kMaxPixels = std::int64_t(1) << 28;

[[noreturn]] inline void fail(const std::string& path, const std::string& reason) { throw std::runtime_error(path + ": " + reason); }

inline void check_size(const std::string& path, int w, int h) {
  if (w < 1 || h < 1 || w > kMaxSide || h > kMaxSide || std::int64_t(w) * std::int64_t(h) > kMaxPixels)
    fail(path, "absurd image size " + std::to_string(w) + "x" + std::to_string(h) + " (each side must be in [1, " +
                   std::to_string(kMaxSide) + "], at most " + std::to_string(kMaxPixels) + " pixels)");
}

// A decoded file: the first min(channels, 3) channels of every pixel as float, row 0 at the top.
struct Decoded {
  int width = 0, height = 0, channels = 0;
  bool is_float = true;     // stored as floating point (linear unless tagged otherwise)
  std::string color_space;  // the file's colour-space tag, lower case ("" when untagged)
  float gamma = 0.0f;       // the file's gamma tag (0 when untagged)
  std::vector<float> data;
};

// Throws std::runtime_error "<path>: <reason>" (missing, unreadable, unsupported, absurd size).
Decoded read(const std::string& path);
// Writes exactly `path` (image_io.cpp writes PATH.tmp and renames). rgb: w*h*3 floats, finite, in
// the half range when `half`.
void write_exr(const std::string& path, int w, int h, const float* rgb, bool half);
// 8-bit sRGB RGB.
void write_png(const std::string& path, int w, int h, const std::uint8_t* rgb);
// What reads and writes the files, for messages and records.
const char* name();

}  // namespace softgi::io::codec
