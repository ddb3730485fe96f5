// Image files through OpenImageIO (the only translation unit that includes OIIO: core/src/io/image_io.cpp).
#pragma once

#include <string>

#include "softgi/image.hpp"

namespace softgi::io {

// Reads EXR, HDR, PNG, ... as linear float RGB (sRGB 8-bit files are linearised). Throws
// std::runtime_error naming the file and the reason (missing, unreadable, no RGB channels, absurd size).
Image read_image(const std::string& path);
// Raw lat-long read for environment maps: width*height*3 floats. Same errors.
void read_rgb_float(const std::string& path, int& width, int& height, std::vector<float>& rgb);

// Writes a float EXR (half when `half` is true). Writes to PATH.tmp and renames, so an existing file is
// never left truncated. Throws std::runtime_error naming the file on failure.
void write_exr(const std::string& path, const Image& img, bool half = false);
// Tone-mapped 8-bit PNG: exposure scale, Reinhard-free clamp, sRGB encoding. Same atomic write.
void write_png(const std::string& path, const Image& img, float exposure = 1.0f);
// 8-bit PNG of already display-referred RGB in [0, 1] (false-colour maps).
void write_png_display(const std::string& path, const Image& img);

}  // namespace softgi::io
