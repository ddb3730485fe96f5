// Writers for tiny HDR files with exactly chosen pixels, independent of OpenImageIO and of
// io::write_exr (which refuses NaN and infinity): an uncompressed scanline float EXR and a flat
// Radiance RGBE (.hdr).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace softgi::test {

// Float RGB EXR (OpenEXR 2 file layout: magic, version, header attributes, offset table, one
// uncompressed scanline per chunk, channels in name order B, G, R). rgb: w * h * 3, row 0 at the top.
inline void write_raw_exr(const std::string& path, int w, int h, const std::vector<float>& rgb) {
  std::vector<unsigned char> out;
  auto bytes = [&out](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    out.insert(out.end(), b, b + n);
  };
  auto i32 = [&](std::int32_t v) {
    for (int k = 0; k < 4; ++k) out.push_back(static_cast<unsigned char>(std::uint32_t(v) >> (8 * k)));
  };
  auto u64 = [&](std::uint64_t v) {
    for (int k = 0; k < 8; ++k) out.push_back(static_cast<unsigned char>(v >> (8 * k)));
  };
  auto f32 = [&](float v) {
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    i32(std::int32_t(u));
  };
  auto str = [&](const char* s) { bytes(s, std::strlen(s) + 1); };
  auto attr = [&](const char* name, const char* type, std::int32_t size) {
    str(name);
    str(type);
    i32(size);
  };
  i32(20000630);  // magic 0x762f3101
  i32(2);         // version 2, single-part scanline
  attr("channels", "chlist", 3 * (2 + 16) + 1);
  for (const char* c : {"B", "G", "R"}) {
    str(c);
    i32(2);  // FLOAT
    i32(0);  // pLinear + reserved
    i32(1);  // x sampling
    i32(1);  // y sampling
  }
  out.push_back(0);
  attr("compression", "compression", 1);
  out.push_back(0);  // NO_COMPRESSION
  for (const char* window : {"dataWindow", "displayWindow"}) {
    attr(window, "box2i", 16);
    i32(0);
    i32(0);
    i32(w - 1);
    i32(h - 1);
  }
  attr("lineOrder", "lineOrder", 1);
  out.push_back(0);  // INCREASING_Y
  attr("pixelAspectRatio", "float", 4);
  f32(1.0f);
  attr("screenWindowCenter", "v2f", 8);
  f32(0.0f);
  f32(0.0f);
  attr("screenWindowWidth", "float", 4);
  f32(1.0f);
  out.push_back(0);  // end of header
  const std::size_t table = out.size();
  const std::size_t chunk = 8 + std::size_t(w) * 3 * 4;
  for (int y = 0; y < h; ++y) u64(table + std::size_t(h) * 8 + std::size_t(y) * chunk);
  for (int y = 0; y < h; ++y) {
    i32(y);
    i32(w * 3 * 4);
    for (int c : {2, 1, 0})
      for (int x = 0; x < w; ++x) f32(rgb[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 3 + std::size_t(c)]);
  }
  write_bytes(path, out);
}

// Radiance RGBE with flat (non-RLE) scanlines; w < 8 keeps every reader on the flat path. Values
// must be >= 0 (RGBE has no sign); a shared exponent per pixel, so choose powers of two times small
// integers to have them read back exactly.
inline void write_rgbe_hdr(const std::string& path, int w, int h, const std::vector<float>& rgb) {
  std::string head = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(h) + " +X " + std::to_string(w) + "\n";
  std::vector<unsigned char> out(head.begin(), head.end());
  for (std::size_t p = 0; p < std::size_t(w) * std::size_t(h); ++p) {
    const float r = rgb[3 * p], g = rgb[3 * p + 1], b = rgb[3 * p + 2];
    const float v = std::fmax(r, std::fmax(g, b));
    if (v < 1e-32f) {
      out.insert(out.end(), {0, 0, 0, 0});
      continue;
    }
    int e = 0;
    const float m = std::frexp(v, &e) * 256.0f / v;
    out.insert(out.end(), {static_cast<unsigned char>(r * m), static_cast<unsigned char>(g * m), static_cast<unsigned char>(b * m),
                           static_cast<unsigned char>(e + 128)});
  }
  write_bytes(path, out);
}

}  // namespace softgi::test
