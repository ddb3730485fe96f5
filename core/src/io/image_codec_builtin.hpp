// A dependency-free image codec for builds without OpenImageIO: uncompressed scanline OpenEXR
// (write and read) and 8-bit PNG (write only). Every function throws std::runtime_error whose
// message is "<path>: <reason>".
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace softgi::io::builtin {

// Writes a single-part scanline OpenEXR 2.0 file without compression: channels B, G, R (the
// format stores channels in alphabetical order), FLOAT or, when `half`, HALF samples rounded to
// nearest even. `rgb` holds width * height interleaved RGB triples, row 0 at the top. In half mode
// a value that would round beyond the largest finite half (65504), or a NaN or infinity, is
// refused before anything is written: the caller clamps first. Writes `path` itself; a failed
// write removes what it had written.
void write_exr(const std::string& path, int width, int height, const float* rgb, bool half);

// Writes an 8-bit PNG: RGB when channels == 3, RGBA when channels == 4, tagged sRGB. The image
// data is a zlib stream of stored (uncompressed) deflate blocks, so the file is about as large as
// the pixels. `bytes` holds width * height * channels values, row 0 at the top.
void write_png(const std::string& path, int width, int height, int channels, const std::uint8_t* bytes);

struct Decoded {
  // channels: how many of R, G, B, A the file has (1..4); a file without R, G and B counts Y
  // (luminance) in their place.
  int width = 0, height = 0, channels = 0;
  bool is_float = true;  // always true for OpenEXR
  // width * height * min(channels, 3) values per pixel, interleaved, row 0 at the top: the first
  // of R, G, B, A (or Y, A) the file has, in that order. Read as OpenImageIO orders channels, so a
  // caller treats 1 or 2 values per pixel as grey (plus alpha) and 3 as RGB.
  std::vector<float> data;
};

// Reads a single-part scanline OpenEXR file without compression whose channels (HALF, FLOAT or
// UINT, the last converted numerically to float) include R, G, B or Y; channels with other names
// (layers such as "diffuse.R", depth, ...) are skipped. Files that are multi-part, tiled, deep,
// compressed or have subsampled channels are refused with a message naming why. Every length and
// offset is checked against the file size before use, so any byte sequence either decodes or
// throws.
Decoded read_exr(const std::string& path);

}  // namespace softgi::io::builtin
