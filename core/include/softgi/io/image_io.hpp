// Image files, through OpenImageIO (core/src/io/image_codec_oiio.cpp, the only translation unit that
// includes it), or in a build without it (SOFTGI_WITH_OIIO=OFF) through the built-in codec, which
// reads uncompressed OpenEXR only and writes uncompressed OpenEXR and PNG.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "softgi/image.hpp"

namespace softgi::io {

// Reads EXR, HDR, PNG, ... as linear float RGB (sRGB 8-bit files are linearised). Throws
// std::runtime_error naming the file and the reason (missing, unreadable, no RGB channels, absurd size).
Image read_image(const std::string& path);
// Raw read as width*height*3 floats, row 0 at the top, values as stored. Same errors.
void read_rgb_float(const std::string& path, int& width, int& height, std::vector<float>& rgb);

// A lat-long environment map read as radiance. Lossy HDR compression (DWAB/DWAA/PXR24 EXR, as in
// the Poly Haven maps of assets/hdri) rings slightly below zero next to bright sources; radiance cannot
// be negative, so such components are clamped to 0 and counted for the caller to report.
struct EnvironmentMap {
  int width = 0, height = 0;
  std::vector<float> rgb;            // width * height * 3, row 0 at the top
  std::size_t negative_clamped = 0;  // components that were < 0 and now are 0
  float lowest = 0.0f;               // the most negative component before clamping; 0 when none
  int lowest_x = -1, lowest_y = -1;  // its pixel; -1 when none
};
// Reads any format read_image reads. Throws std::runtime_error naming the file, the pixel and the
// channel for a NaN or infinite component, or one above max_radiance (a broken map, not a bright one),
// besides read_image's errors.
EnvironmentMap read_environment_map(const std::string& path, float max_radiance);

// Writes a float EXR (half when `half` is true). Writes to PATH.tmp and renames, so an existing file is
// never left truncated. Throws std::runtime_error naming the file on failure.
void write_exr(const std::string& path, const Image& img, bool half = false);
// Tone-mapped 8-bit PNG: exposure scale, Reinhard-free clamp, sRGB encoding. Same atomic write.
void write_png(const std::string& path, const Image& img, float exposure = 1.0f);
// The 8-bit values write_png stores (clamp(x * exposure) to [0, 1], sRGB-encoded when
// `encode_srgb`), `channels` per pixel (3: RGB; 4: RGBA with alpha 255): one rule for PNG files and
// the viewer's screen. NaN components become 0 (clamp), so check finiteness first where it matters.
std::vector<std::uint8_t> display_bytes(const Image& img, float exposure = 1.0f, bool encode_srgb = true, int channels = 3);
// 8-bit PNG of already display-referred RGB in [0, 1] (false-colour maps).
void write_png_display(const std::string& path, const Image& img);
// What reads and writes image files in this build ("OpenImageIO 2.4.x", or the built-in codec).
const char* image_codec_name();

}  // namespace softgi::io
