// The dependency-free codec (core/src/io/image_codec_builtin.*), judged by OpenImageIO: its EXR
// and PNG files read back through read_image unchanged, half rounding matches a reference found by
// search, its reader agrees with OpenImageIO on layouts its writer never produces, and damaged or
// unsupported files fail naming the file and the reason, never reading out of bounds.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "../../core/src/io/image_codec_builtin.hpp"
#include "softgi/image.hpp"
#include "softgi/io/image_io.hpp"
#include "test_support.hpp"

namespace {

namespace builtin = softgi::io::builtin;
using softgi::Image;
using softgi::test::error_of;
using softgi::test::read_bytes;
using softgi::test::ScratchDir;
using softgi::test::write_bytes;
using Bytes = std::vector<unsigned char>;

// The sentence every refused compression carries.
const char* const kUncompressedOnly = "this build reads only uncompressed OpenEXR files (built without OpenImageIO)";

// Compares bit patterns, so that -0 and 0 differ.
std::uint32_t bits(float v) { return std::bit_cast<std::uint32_t>(v); }

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// ---- half-float reference, by arithmetic and search rather than bit manipulation ----------------

float half_value(std::uint32_t h) {
  const int e = static_cast<int>((h >> 10) & 31u);
  const double m = double(h & 1023u);
  const double v = e == 0 ? std::ldexp(m, -24) : std::ldexp(1024.0 + m, e - 25);
  return static_cast<float>((h & 0x8000u) ? -v : v);
}

// The finite non-negative halves, increasing: bit patterns 0x0000 to 0x7bff.
const std::vector<float>& positive_halves() {
  static const std::vector<float> table = [] {
    std::vector<float> t;
    for (std::uint32_t h = 0; h <= 0x7bffu; ++h) t.push_back(half_value(h));
    return t;
  }();
  return table;
}

// The half nearest to v (|v| < 65520), ties going to the even bit pattern.
float reference_half(float v) {
  const std::vector<float>& t = positive_halves();
  const float a = std::fabs(v);
  const auto hi = static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), a) - t.begin());
  if (hi == t.size()) return std::copysign(t.back(), v);
  if (t[hi] == a) return std::copysign(t[hi], v);
  const std::size_t lo = hi - 1;
  const double below = double(a) - double(t[lo]), above = double(t[hi]) - double(a);
  const std::size_t pick = below < above ? lo : above < below ? hi : (lo % 2 == 0 ? lo : hi);
  return std::copysign(t[pick], v);
}

// ---- images ------------------------------------------------------------------------------------

// Interleaved RGB with negatives, large values, fractions and the extremes of float.
std::vector<float> varied_rgb(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> fraction(-1.0f, 1.0f);
  std::uniform_int_distribution<int> exponent(-30, 30);
  std::vector<float> v(std::size_t(w) * std::size_t(h) * 3);
  for (float& x : v) x = std::ldexp(fraction(rng), exponent(rng));
  const float specials[] = {0.0f, -0.0f, 0.1f, -12345.678f, 3.4e38f, -3.4e38f, 1e-30f, 1e-40f, 0.5f, 1.0f / 3.0f};
  for (std::size_t i = 0; i < std::size(specials); ++i) v[(7 * i) % v.size()] = specials[i];
  return v;
}

// varied_rgb within the half range, as write_exr(half) requires.
std::vector<float> varied_half_rgb(int w, int h, unsigned seed) {
  std::vector<float> v = varied_rgb(w, h, seed);
  for (float& x : v) x = std::clamp(x, -65504.0f, 65504.0f);
  return v;
}

std::vector<float> rgb_of(const Image& img) {
  std::vector<float> v;
  for (const glm::vec3& c : img.rgb) v.insert(v.end(), {c.x, c.y, c.z});
  return v;
}

std::size_t find_bytes(const Bytes& file, const std::string& needle) {
  const auto it = std::search(file.begin(), file.end(), needle.begin(), needle.end());
  return it == file.end() ? std::string::npos : static_cast<std::size_t>(it - file.begin());
}

// Byte position of the compression attribute's value in a file write_exr wrote.
std::size_t compression_byte(const Bytes& file) {
  const std::string attr("compression\0compression\0\1\0\0\0", 28);
  const std::size_t at = find_bytes(file, attr);
  return at == std::string::npos ? at : at + attr.size();
}

void put32(Bytes& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + std::size_t(i)] = static_cast<unsigned char>(v >> (8 * i));
}
void put64(Bytes& b, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + std::size_t(i)] = static_cast<unsigned char>(v >> (8 * i));
}

// ---- an independent OpenEXR writer for layouts write_exr never produces -----------------------

struct ExrChannel {
  std::string name;
  int type = 2;                        // 0 UINT, 1 HALF, 2 FLOAT
  std::vector<std::uint32_t> samples;  // per pixel: the value's bit pattern (UINT: the value)
};

struct ExrLayout {
  int x0 = 0, y0 = 0, width = 1, height = 1;
  bool decreasing_y = false;  // chunks stored bottom to top (the offset table stays top to bottom)
  std::vector<ExrChannel> channels;  // any order: sorted by name when written
};

void append(Bytes& b, const void* p, std::size_t n) {
  const auto* c = static_cast<const unsigned char*>(p);
  b.insert(b.end(), c, c + n);
}
void append32(Bytes& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<unsigned char>(v >> (8 * i)));
}
void append_attr(Bytes& b, const std::string& name, const std::string& type, const Bytes& value) {
  append(b, name.c_str(), name.size() + 1);
  append(b, type.c_str(), type.size() + 1);
  append32(b, std::uint32_t(value.size()));
  b.insert(b.end(), value.begin(), value.end());
}

Bytes build_exr(ExrLayout l) {
  std::sort(l.channels.begin(), l.channels.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  Bytes f;
  append32(f, 20000630);
  append32(f, 2);
  Bytes chlist;
  for (const ExrChannel& c : l.channels) {
    append(chlist, c.name.c_str(), c.name.size() + 1);
    append32(chlist, std::uint32_t(c.type));
    append32(chlist, 0);
    append32(chlist, 1);
    append32(chlist, 1);
  }
  chlist.push_back(0);
  append_attr(f, "channels", "chlist", chlist);
  append_attr(f, "comments", "string", Bytes{'h', 'i'});
  append_attr(f, "compression", "compression", Bytes{0});
  Bytes box;
  for (int v : {l.x0, l.y0, l.x0 + l.width - 1, l.y0 + l.height - 1}) append32(box, std::uint32_t(v));
  append_attr(f, "dataWindow", "box2i", box);
  append_attr(f, "displayWindow", "box2i", box);
  append_attr(f, "lineOrder", "lineOrder", Bytes{static_cast<unsigned char>(l.decreasing_y ? 1 : 0)});
  Bytes one, two_zeros(8, 0);
  append32(one, bits(1.0f));
  append_attr(f, "pixelAspectRatio", "float", one);
  append_attr(f, "screenWindowCenter", "v2f", two_zeros);
  append_attr(f, "screenWindowWidth", "float", one);
  f.push_back(0);
  const std::size_t table = f.size();
  f.resize(f.size() + 8 * std::size_t(l.height));
  for (int k = 0; k < l.height; ++k) {
    const int row = l.decreasing_y ? l.height - 1 - k : k;
    put64(f, table + 8 * std::size_t(row), f.size());
    Bytes data;
    for (const ExrChannel& c : l.channels) {
      for (int x = 0; x < l.width; ++x) {
        const std::uint32_t s = c.samples[std::size_t(row) * std::size_t(l.width) + std::size_t(x)];
        data.push_back(static_cast<unsigned char>(s));
        data.push_back(static_cast<unsigned char>(s >> 8));
        if (c.type != 1) {
          data.push_back(static_cast<unsigned char>(s >> 16));
          data.push_back(static_cast<unsigned char>(s >> 24));
        }
      }
    }
    append32(f, std::uint32_t(l.y0 + row));
    append32(f, std::uint32_t(data.size()));
    f.insert(f.end(), data.begin(), data.end());
  }
  return f;
}

// A channel of random finite samples: halves drawn as bit patterns, floats over a wide range.
ExrChannel random_channel(const std::string& name, int type, int pixels, std::mt19937& rng) {
  ExrChannel c{name, type, {}};
  std::uniform_int_distribution<std::uint32_t> any;
  std::uniform_real_distribution<float> fraction(-1.0f, 1.0f);
  std::uniform_int_distribution<int> exponent(-20, 20);
  for (int i = 0; i < pixels; ++i) {
    if (type == 1) {
      std::uint32_t h = any(rng) & 0xffffu;
      if (((h >> 10) & 31u) == 31u) h &= 0x83ffu;  // no inf or NaN
      c.samples.push_back(h);
    } else if (type == 2) {
      c.samples.push_back(bits(std::ldexp(fraction(rng), exponent(rng))));
    } else {
      c.samples.push_back(any(rng));
    }
  }
  return c;
}

float sample_value(const ExrChannel& c, std::size_t i) {
  const std::uint32_t s = c.samples[i];
  if (c.type == 1) return half_value(s);
  if (c.type == 2) return std::bit_cast<float>(s);
  return static_cast<float>(s);
}

// ---- an independent PNG parser ------------------------------------------------------------------

std::uint32_t be32(const Bytes& b, std::size_t at) {
  return std::uint32_t(b[at]) << 24 | std::uint32_t(b[at + 1]) << 16 | std::uint32_t(b[at + 2]) << 8 | b[at + 3];
}

std::uint32_t crc32_bitwise(const unsigned char* p, std::size_t n) {
  std::uint32_t c = 0xffffffffu;
  for (std::size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

struct ParsedPng {
  std::uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = 0, interlace = -1;
  std::vector<std::string> chunks;
  Bytes srgb;
  Bytes raw;  // the inflated image data: rows with their filter byte
  int stored_blocks = 0;
};

void parse_png(const Bytes& f, ParsedPng& png) {
  const Bytes signature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  ASSERT_GE(f.size(), 8u);
  ASSERT_TRUE(std::equal(signature.begin(), signature.end(), f.begin()));
  Bytes z;
  std::size_t p = 8;
  while (p < f.size()) {
    ASSERT_LE(p + 12, f.size());
    const std::uint32_t len = be32(f, p);
    ASSERT_LE(p + 12 + len, f.size());
    const std::string type(f.begin() + std::ptrdiff_t(p + 4), f.begin() + std::ptrdiff_t(p + 8));
    EXPECT_EQ(be32(f, p + 8 + len), crc32_bitwise(&f[p + 4], 4 + len)) << "CRC of chunk " << type;
    const Bytes data(f.begin() + std::ptrdiff_t(p + 8), f.begin() + std::ptrdiff_t(p + 8 + len));
    png.chunks.push_back(type);
    if (type == "IHDR") {
      ASSERT_EQ(len, 13u);
      png.width = be32(data, 0);
      png.height = be32(data, 4);
      png.bit_depth = data[8];
      png.colour_type = data[9];
      EXPECT_EQ(data[10], 0) << "compression method";
      EXPECT_EQ(data[11], 0) << "filter method";
      png.interlace = data[12];
    } else if (type == "sRGB") {
      png.srgb = data;
    } else if (type == "IDAT") {
      z.insert(z.end(), data.begin(), data.end());
    }
    p += 12 + len;
  }
  ASSERT_EQ(p, f.size());
  // zlib (RFC 1950): deflate, no preset dictionary, header check; then stored blocks (RFC 1951).
  ASSERT_GE(z.size(), 2u + 5u + 4u);
  EXPECT_EQ(z[0] & 0x0f, 8);
  EXPECT_EQ(z[1] & 0x20, 0);
  EXPECT_EQ((z[0] * 256 + z[1]) % 31, 0);
  std::size_t q = 2;
  for (bool last = false; !last;) {
    ASSERT_LE(q + 5, z.size());
    last = (z[q] & 1) != 0;
    EXPECT_EQ((z[q] >> 1) & 3, 0) << "block " << png.stored_blocks << " is not stored";
    const std::uint32_t len = z[q + 1] | std::uint32_t(z[q + 2]) << 8;
    const std::uint32_t nlen = z[q + 3] | std::uint32_t(z[q + 4]) << 8;
    EXPECT_EQ(nlen, ~len & 0xffffu);
    q += 5;
    ASSERT_LE(q + len, z.size());
    png.raw.insert(png.raw.end(), z.begin() + std::ptrdiff_t(q), z.begin() + std::ptrdiff_t(q + len));
    q += len;
    ++png.stored_blocks;
  }
  ASSERT_EQ(q + 4, z.size()) << "bytes after the final block";
  std::uint32_t a = 1, b = 0;
  for (unsigned char c : png.raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  EXPECT_EQ(be32(z, q), (b << 16) | a) << "Adler-32";
}

Bytes pattern_bytes(int w, int h, int channels, unsigned seed) {
  std::mt19937 rng(seed);
  Bytes v(std::size_t(w) * std::size_t(h) * std::size_t(channels));
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<unsigned char>(i % 3 == 0 ? i % 256 : rng() % 256);
  return v;
}

float srgb_encode(float v) { return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f; }

// read_image linearises 8-bit sRGB PNGs; encoding its floats again must give the bytes back.
void expect_png_bytes(const Image& back, const Bytes& bytes, int channels) {
  ASSERT_EQ(back.rgb.size() * std::size_t(channels), bytes.size());
  int wrong = 0;
  for (std::size_t i = 0; i < back.rgb.size() && wrong < 10; ++i) {
    for (int k = 0; k < 3; ++k) {
      const long byte = std::lround(srgb_encode(back.rgb[i][k]) * 255.0f);
      const int want = bytes[i * std::size_t(channels) + std::size_t(k)];
      if (byte != want) {
        ADD_FAILURE() << "pixel " << i << " channel " << k << ": " << byte << " != " << want;
        ++wrong;
      }
    }
  }
}

// ---- tests -------------------------------------------------------------------------------------

TEST(BuiltinCodec, ExrFloatRoundTripIsBitExact) {
  ScratchDir dir;
  const int w = 37, h = 23;
  const std::vector<float> rgb = varied_rgb(w, h, 11);
  const std::string path = dir.file("f.exr");
  builtin::write_exr(path, w, h, rgb.data(), false);

  const Bytes file = read_bytes(path);
  ASSERT_GE(file.size(), 8u);
  EXPECT_EQ(Bytes(file.begin(), file.begin() + 8), (Bytes{0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0}));
  // Uncompressed, one scanline per chunk: each chunk is 8 bytes plus 3 channels of float samples.
  EXPECT_EQ(file.size() - find_bytes(file, std::string("screenWindowWidth")),
            std::string("screenWindowWidth").size() + 1 + 6 + 4 + 4 + 1 + 8u * h + h * (8u + 12u * w));

  const Image oiio = softgi::io::read_image(path);
  ASSERT_EQ(oiio.width, w);
  ASSERT_EQ(oiio.height, h);
  const std::vector<float> back = rgb_of(oiio);
  for (std::size_t i = 0; i < rgb.size(); ++i) ASSERT_EQ(bits(back[i]), bits(rgb[i])) << "OpenImageIO, value " << i;

  const builtin::Decoded d = builtin::read_exr(path);
  EXPECT_EQ(d.width, w);
  EXPECT_EQ(d.height, h);
  EXPECT_EQ(d.channels, 3);
  EXPECT_TRUE(d.is_float);
  ASSERT_EQ(d.data.size(), rgb.size());
  for (std::size_t i = 0; i < rgb.size(); ++i) ASSERT_EQ(bits(d.data[i]), bits(rgb[i])) << "builtin, value " << i;
}

TEST(BuiltinCodec, ExrHalfRoundsToNearestEven) {
  // Every finite half, the midpoints between neighbours (ties) and the floats either side of them,
  // both signs, plus values exactly representable in half.
  const std::vector<float>& t = positive_halves();
  std::vector<float> values = {0.5f, 1.25f, -3.0f, 1024.0f, 65504.0f, -65504.0f, 65519.0f, -65519.99f,
                               std::ldexp(1.0f, -24), std::ldexp(1.0f, -25), std::ldexp(1.5f, -25), 1e-8f, -0.0f};
  for (std::size_t k = 0; k + 1 < t.size(); ++k) {
    const float mid = 0.5f * (t[k] + t[k + 1]);  // exact: halves have 11-bit significands
    for (float v : {t[k], std::nextafter(mid, 0.0f), mid, std::nextafter(mid, 1e9f)}) {
      values.push_back(v);
      values.push_back(-v);
    }
  }
  const int w = 512;
  const int h = int((values.size() + 3 * w - 1) / (3 * w));
  values.resize(std::size_t(w) * std::size_t(h) * 3, 0.75f);

  ScratchDir dir;
  const std::string path = dir.file("h.exr");
  builtin::write_exr(path, w, h, values.data(), true);
  const Image oiio = softgi::io::read_image(path);
  ASSERT_EQ(oiio.width, w);
  ASSERT_EQ(oiio.height, h);
  const std::vector<float> back = rgb_of(oiio);
  const builtin::Decoded d = builtin::read_exr(path);
  ASSERT_EQ(d.data.size(), values.size());
  int wrong = 0;
  for (std::size_t i = 0; i < values.size() && wrong < 10; ++i) {
    const float want = reference_half(values[i]);
    if (bits(back[i]) != bits(want) || bits(d.data[i]) != bits(want)) {
      ADD_FAILURE() << "value " << i << " = " << values[i] << " (0x" << std::hex << bits(values[i]) << std::dec
                    << "): OpenImageIO " << back[i] << ", builtin " << d.data[i] << ", want " << want;
      ++wrong;
    }
  }
  // Spot checks that do not depend on the reference.
  EXPECT_EQ(back[0], 0.5f);
  EXPECT_EQ(back[1], 1.25f);
  EXPECT_EQ(back[2], -3.0f);
  EXPECT_EQ(back[3], 1024.0f);
  EXPECT_EQ(back[6], 65504.0f);
  EXPECT_EQ(back[9], 0.0f);  // 2^-25 is half-way between 0 and 2^-24: ties to the even 0
  EXPECT_EQ(back[10], std::ldexp(1.0f, -24));
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (std::fabs(values[i]) >= std::ldexp(1.0f, -14)) {
      ASSERT_LE(std::fabs(back[i] - values[i]), std::ldexp(std::fabs(values[i]), -11)) << "value " << i;
    }
  }
}

TEST(BuiltinCodec, ExrHalfRefusesValuesBeyondHalfRange) {
  ScratchDir dir;
  for (float bad : {65520.0f, -1e6f, std::numeric_limits<float>::infinity(), std::nanf("")}) {
    std::vector<float> rgb(2 * 2 * 3, 1.0f);
    rgb[4] = bad;
    const std::string path = dir.file("bad.exr");
    const std::string e = error_of([&] { builtin::write_exr(path, 2, 2, rgb.data(), true); });
    EXPECT_EQ(e.rfind(path + ": pixel (1, 0) channel 1 is ", 0), 0u) << e;
    EXPECT_TRUE(contains(e, "65504")) << e;
    EXPECT_FALSE(std::filesystem::exists(path));
  }
  // The float format takes them.
  std::vector<float> rgb(3, 1e6f);
  EXPECT_NO_THROW(builtin::write_exr(dir.file("ok.exr"), 1, 1, rgb.data(), false));
}

TEST(BuiltinCodec, WriteErrorsNameTheFile) {
  ScratchDir dir;
  const std::vector<float> rgb(3, 1.0f);
  const std::uint8_t bytes[4] = {1, 2, 3, 4};
  const std::string missing = dir.file("no_dir/x.exr");
  std::string e = error_of([&] { builtin::write_exr(missing, 1, 1, rgb.data(), false); });
  EXPECT_EQ(e.rfind(missing + ": cannot open for writing", 0), 0u) << e;
  e = error_of([&] { builtin::write_png(dir.file("no_dir/x.png"), 1, 1, 3, bytes); });
  EXPECT_EQ(e.rfind(dir.file("no_dir/x.png") + ": cannot open for writing", 0), 0u) << e;
  e = error_of([&] { builtin::write_png(dir.file("two.png"), 1, 1, 2, bytes); });
  EXPECT_EQ(e.rfind(dir.file("two.png") + ": PNG images are written with 3 or 4 channels", 0), 0u) << e;
  e = error_of([&] { builtin::write_exr(dir.file("big.exr"), 40000, 1, rgb.data(), false); });
  EXPECT_EQ(e.rfind(dir.file("big.exr") + ": absurd image size 40000x1", 0), 0u) << e;
  EXPECT_FALSE(std::filesystem::exists(dir.file("two.png")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("big.exr")));
}

TEST(BuiltinCodec, PngReadsBackThroughOpenImageIO) {
  ScratchDir dir;
  // 200x150 RGB: 90150 bytes of rows, so the zlib stream needs two stored blocks.
  const Bytes rgb = pattern_bytes(200, 150, 3, 5);
  builtin::write_png(dir.file("rgb.png"), 200, 150, 3, rgb.data());
  const Image back = softgi::io::read_image(dir.file("rgb.png"));
  ASSERT_EQ(back.width, 200);
  ASSERT_EQ(back.height, 150);
  expect_png_bytes(back, rgb, 3);

  // RGBA, opaque (OpenImageIO would premultiply a partial alpha), over 1 MiB: several IDAT chunks.
  Bytes rgba = pattern_bytes(700, 400, 4, 6);
  for (std::size_t i = 3; i < rgba.size(); i += 4) rgba[i] = 255;
  builtin::write_png(dir.file("rgba.png"), 700, 400, 4, rgba.data());
  const Image back4 = softgi::io::read_image(dir.file("rgba.png"));
  ASSERT_EQ(back4.width, 700);
  ASSERT_EQ(back4.height, 400);
  expect_png_bytes(back4, rgba, 4);
  ParsedPng png;
  ASSERT_NO_FATAL_FAILURE(parse_png(read_bytes(dir.file("rgba.png")), png));
  EXPECT_GE(std::count(png.chunks.begin(), png.chunks.end(), "IDAT"), 2);
}

TEST(BuiltinCodec, PngLayoutFollowsTheSpecification) {
  ScratchDir dir;
  struct Case {
    int w, h, channels;
  };
  // 1x1; rows exactly filling one and two stored blocks (15 rows of 1 + 1456 * 3 bytes = 65535);
  // 200x150 (two blocks, the last partial); RGBA.
  for (const Case c : {Case{1, 1, 3}, Case{1456, 15, 3}, Case{1456, 30, 3}, Case{200, 150, 3}, Case{61, 47, 4}}) {
    SCOPED_TRACE(std::to_string(c.w) + "x" + std::to_string(c.h) + "x" + std::to_string(c.channels));
    const Bytes bytes = pattern_bytes(c.w, c.h, c.channels, 7);
    const std::string path = dir.file("p.png");
    builtin::write_png(path, c.w, c.h, c.channels, bytes.data());
    ParsedPng png;
    ASSERT_NO_FATAL_FAILURE(parse_png(read_bytes(path), png));
    ASSERT_GE(png.chunks.size(), 4u);
    EXPECT_EQ(png.chunks.front(), "IHDR");
    EXPECT_EQ(png.chunks[1], "sRGB");
    EXPECT_EQ(png.chunks.back(), "IEND");
    EXPECT_EQ(std::count(png.chunks.begin(), png.chunks.end(), "sRGB"), 1);
    EXPECT_EQ(png.srgb, Bytes{0});
    EXPECT_EQ(png.width, std::uint32_t(c.w));
    EXPECT_EQ(png.height, std::uint32_t(c.h));
    EXPECT_EQ(png.bit_depth, 8);
    EXPECT_EQ(png.colour_type, c.channels == 4 ? 6 : 2);
    EXPECT_EQ(png.interlace, 0);
    const std::size_t row = std::size_t(c.w) * std::size_t(c.channels);
    EXPECT_EQ(png.stored_blocks, int((c.h * (row + 1) + 65534) / 65535));
    ASSERT_EQ(png.raw.size(), std::size_t(c.h) * (row + 1));
    for (int y = 0; y < c.h; ++y) {
      const auto* r = &png.raw[std::size_t(y) * (row + 1)];
      ASSERT_EQ(r[0], 0) << "filter type of row " << y;
      ASSERT_TRUE(std::equal(r + 1, r + 1 + row, &bytes[std::size_t(y) * row])) << "row " << y;
    }
  }
}

TEST(BuiltinCodec, ReadExrMatchesOpenImageIOOnOtherLayouts) {
  ScratchDir dir;
  std::mt19937 rng(3);
  // Mixed types, extra channels (A, Z), a data window away from the origin, chunks bottom to top.
  ExrLayout l;
  l.x0 = -5;
  l.y0 = 7;
  l.width = 19;
  l.height = 6;
  l.decreasing_y = true;
  const int n = l.width * l.height;
  l.channels = {random_channel("Z", 2, n, rng), random_channel("R", 2, n, rng), random_channel("G", 1, n, rng),
                random_channel("A", 1, n, rng), random_channel("B", 2, n, rng)};
  const std::string path = dir.file("rgbaz.exr");
  write_bytes(path, build_exr(l));
  const builtin::Decoded d = builtin::read_exr(path);
  EXPECT_EQ(d.width, 19);
  EXPECT_EQ(d.height, 6);
  EXPECT_EQ(d.channels, 4);
  ASSERT_EQ(d.data.size(), std::size_t(n) * 3);
  for (std::size_t i = 0; i < std::size_t(n); ++i) {
    EXPECT_EQ(bits(d.data[3 * i + 0]), bits(sample_value(l.channels[1], i))) << i;
    EXPECT_EQ(bits(d.data[3 * i + 1]), bits(sample_value(l.channels[2], i))) << i;
    EXPECT_EQ(bits(d.data[3 * i + 2]), bits(sample_value(l.channels[4], i))) << i;
  }
  const Image oiio = softgi::io::read_image(path);  // the layout is valid OpenEXR
  ASSERT_EQ(oiio.width, 19);
  ASSERT_EQ(oiio.height, 6);
  const std::vector<float> back = rgb_of(oiio);
  for (std::size_t i = 0; i < back.size(); ++i) EXPECT_EQ(bits(back[i]), bits(d.data[i])) << i;

  // Luminance alone, then with alpha.
  ExrLayout y;
  y.x0 = 3;
  y.y0 = -2;
  y.width = 5;
  y.height = 4;
  y.channels = {random_channel("Y", 1, 20, rng)};
  write_bytes(dir.file("y.exr"), build_exr(y));
  const builtin::Decoded dy = builtin::read_exr(dir.file("y.exr"));
  EXPECT_EQ(dy.channels, 1);
  ASSERT_EQ(dy.data.size(), 20u);
  const Image oy = softgi::io::read_image(dir.file("y.exr"));
  ASSERT_EQ(oy.rgb.size(), 20u);
  for (std::size_t i = 0; i < 20; ++i) {
    EXPECT_EQ(bits(dy.data[i]), bits(sample_value(y.channels[0], i))) << i;
    EXPECT_EQ(bits(oy.rgb[i].x), bits(dy.data[i])) << i;
  }
  y.channels.push_back(random_channel("A", 2, 20, rng));
  write_bytes(dir.file("ya.exr"), build_exr(y));
  const builtin::Decoded dya = builtin::read_exr(dir.file("ya.exr"));
  EXPECT_EQ(dya.channels, 2);
  ASSERT_EQ(dya.data.size(), 40u);
  for (std::size_t i = 0; i < 20; ++i) {
    EXPECT_EQ(bits(dya.data[2 * i]), bits(sample_value(y.channels[0], i))) << i;
    EXPECT_EQ(bits(dya.data[2 * i + 1]), bits(sample_value(y.channels[1], i))) << i;
  }

  // UINT samples become their numeric value (OpenImageIO would normalise them, so no comparison).
  ExrLayout u;
  u.width = 4;
  u.height = 3;
  u.channels = {random_channel("R", 0, 12, rng), random_channel("G", 0, 12, rng), random_channel("B", 0, 12, rng)};
  u.channels[0].samples[0] = 0;
  u.channels[0].samples[1] = 16777217;  // 2^24 + 1: rounds to 2^24 in float
  write_bytes(dir.file("u.exr"), build_exr(u));
  const builtin::Decoded du = builtin::read_exr(dir.file("u.exr"));
  ASSERT_EQ(du.data.size(), 36u);
  EXPECT_EQ(du.data[0], 0.0f);
  EXPECT_EQ(du.data[3], 16777216.0f);
  for (std::size_t i = 0; i < 12; ++i) {
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(du.data[3 * i + k], float(u.channels[k].samples[i])) << i;
  }
}

TEST(BuiltinCodec, ReadExrErrorsNameFileAndReason) {
  ScratchDir dir;
  const std::vector<float> rgb = varied_rgb(5, 4, 1);
  const std::string good = dir.file("good.exr");
  builtin::write_exr(good, 5, 4, rgb.data(), false);
  const Bytes file = read_bytes(good);
  auto read_error = [&](const std::string& name, const Bytes& bytes) {
    const std::string path = dir.file(name);
    write_bytes(path, bytes);
    const std::string e = error_of([&] { builtin::read_exr(path); });
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << e;
    return e;
  };

  const std::string missing = dir.file("missing.exr");
  EXPECT_EQ(error_of([&] { builtin::read_exr(missing); }), missing + ": no such file");

  const std::uint8_t px[3] = {1, 2, 3};
  builtin::write_png(dir.file("p.png"), 1, 1, 3, px);
  std::string e = error_of([&] { builtin::read_exr(dir.file("p.png")); });
  EXPECT_EQ(e.rfind(dir.file("p.png") + ": not an OpenEXR file", 0), 0u) << e;

  const std::size_t cb = compression_byte(file);
  ASSERT_NE(cb, std::string::npos);
  const char* names[] = {"", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB"};
  for (int c = 1; c <= 9; ++c) {
    Bytes b = file;
    b[cb] = static_cast<unsigned char>(c);
    e = read_error("c.exr", b);
    EXPECT_TRUE(contains(e, std::string(names[c]) + " compression")) << e;
    EXPECT_TRUE(contains(e, kUncompressedOnly)) << e;
  }
  Bytes b = file;
  b[cb] = 200;
  e = read_error("c.exr", b);
  EXPECT_TRUE(contains(e, "unknown compression 200")) << e;
  EXPECT_TRUE(contains(e, kUncompressedOnly)) << e;

  const std::pair<unsigned char, const char*> flags[] = {
      {0x02, "tiled"}, {0x08, "deep"}, {0x10, "multi-part"}, {0x12, "multi-part"}, {0x80, "unknown OpenEXR version flags 0x8000"}};
  for (const auto& [flag, word] : flags) {
    b = file;
    b[5] = flag;
    e = read_error("v.exr", b);
    EXPECT_TRUE(contains(e, word)) << e;
  }
  b = file;
  b[5] = 0x04;  // long names: allowed
  write_bytes(dir.file("long.exr"), b);
  EXPECT_NO_THROW(builtin::read_exr(dir.file("long.exr")));

  // Offset table: after the header, before 4 chunks of 8 + 5 * 12 bytes.
  const std::size_t table = file.size() - 4 * 68 - 4 * 8;
  for (const std::uint64_t bad : {std::uint64_t(file.size()) + 100, std::uint64_t(file.size()) - 67, std::uint64_t(0),
                                  std::uint64_t(table), std::uint64_t(1) << 63, ~std::uint64_t(0)}) {
    b = file;
    put64(b, table + 16, bad);
    e = read_error("o.exr", b);
    EXPECT_TRUE(contains(e, "offset table entry 2 (scanline 2) points to " + std::to_string(bad) + ", outside the file"))
        << e;
  }
  b = file;
  put64(b, table + 16, std::uint64_t(file.size()) - 3 * 68);  // entry 2 pointing at scanline 1's chunk
  e = read_error("o.exr", b);
  EXPECT_TRUE(contains(e, "holds scanline 1, expected 2")) << e;

  // dataWindow: absurd sizes, and sizes the file is too short for.
  const std::size_t window = find_bytes(file, std::string("dataWindow\0box2i\0", 17)) + 17 + 4;
  b = file;
  put32(b, window + 8, 40000);
  e = read_error("w.exr", b);
  EXPECT_TRUE(contains(e, "absurd image size 40001x4")) << e;
  b = file;
  put32(b, window + 8, 0x7fffffff);
  put32(b, window, 0x80000000u);
  e = read_error("w.exr", b);
  EXPECT_TRUE(contains(e, "absurd image size 4294967296x4")) << e;
  b = file;
  put32(b, window + 12, 8191);
  e = read_error("w.exr", b);
  EXPECT_TRUE(contains(e, "truncated file")) << e;

  // Channels: none named R, G, B or Y; unknown pixel type; subsampled.
  ExrLayout l;
  l.width = 2;
  l.height = 2;
  std::mt19937 rng(9);
  l.channels = {random_channel("diffuse.R", 2, 4, rng), random_channel("Z", 2, 4, rng)};
  e = read_error("n.exr", build_exr(l));
  EXPECT_TRUE(contains(e, "no R, G, B or Y channel (channels: Z, diffuse.R)")) << e;
  l.channels = {random_channel("R", 2, 4, rng)};
  Bytes layered = build_exr(l);
  const std::size_t chan = find_bytes(layered, std::string("R\0", 2));
  put32(layered, chan + 2, 7);
  e = read_error("t.exr", layered);
  EXPECT_TRUE(contains(e, "channel 'R' has unknown pixel type 7")) << e;
  layered = build_exr(l);
  put32(layered, chan + 2 + 8, 2);
  e = read_error("s.exr", layered);
  EXPECT_TRUE(contains(e, "subsampled")) << e;
}

TEST(BuiltinCodec, ReadExrTruncatedAtAnyLengthThrows) {
  ScratchDir dir;
  const std::vector<float> rgb = varied_half_rgb(5, 4, 2);
  builtin::write_exr(dir.file("good.exr"), 5, 4, rgb.data(), true);
  const Bytes file = read_bytes(dir.file("good.exr"));
  ASSERT_NO_THROW(builtin::read_exr(dir.file("good.exr")));
  for (std::size_t n = 0; n < file.size(); ++n) {
    // A new file each time: rewriting one in place makes ext4 flush it to disk on every close.
    const std::string path = dir.file("cut" + std::to_string(n) + ".exr");
    write_bytes(path, Bytes(file.begin(), file.begin() + std::ptrdiff_t(n)));
    try {
      builtin::read_exr(path);
      ADD_FAILURE() << "no error for the first " << n << " bytes";
    } catch (const std::runtime_error& ex) {
      const std::string e = ex.what();
      EXPECT_EQ(e.rfind(path + (n < 4 ? ": not an OpenEXR file" : ": truncated file"), 0), 0u) << n << ": " << e;
    }
    std::filesystem::remove(path);
  }
}

// Random damage to valid files: each read either decodes a consistent image or throws
// std::runtime_error. Run under the sanitizers this also checks that nothing is read out of bounds.
TEST(BuiltinCodec, ReadExrSurvivesCorruption) {
  ScratchDir dir;
  std::mt19937 rng(17);
  std::vector<Bytes> seeds;
  const std::vector<float> rgb = varied_half_rgb(6, 3, 4);
  builtin::write_exr(dir.file("s.exr"), 6, 3, rgb.data(), true);
  seeds.push_back(read_bytes(dir.file("s.exr")));
  ExrLayout l;
  l.x0 = 2;
  l.y0 = -1;
  l.width = 4;
  l.height = 3;
  l.channels = {random_channel("Y", 1, 12, rng), random_channel("A", 2, 12, rng), random_channel("q", 0, 12, rng)};
  seeds.push_back(build_exr(l));
  const unsigned char special[] = {0x00, 0x01, 0x7f, 0x80, 0xff};
  int decoded = 0, refused = 0;
  for (int iter = 0; iter < 4000; ++iter) {
    Bytes b = seeds[std::size_t(iter) % seeds.size()];
    const int edits = 1 + int(rng() % 4);
    for (int k = 0; k < edits; ++k) {
      const std::size_t at = rng() % b.size();
      b[at] = rng() % 2 ? special[rng() % std::size(special)] : static_cast<unsigned char>(rng());
    }
    if (rng() % 8 == 0) b.resize(rng() % b.size());
    const std::string path = dir.file("fuzz" + std::to_string(iter) + ".exr");  // new: see above
    write_bytes(path, b);
    try {
      const builtin::Decoded d = builtin::read_exr(path);
      ASSERT_GE(d.channels, 1);
      ASSERT_LE(d.channels, 4);
      ASSERT_EQ(d.data.size(),
                std::size_t(d.width) * std::size_t(d.height) * std::size_t(std::min(d.channels, 3)));
      ++decoded;
    } catch (const std::runtime_error& e) {
      ASSERT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
      ++refused;
    }
    std::filesystem::remove(path);
  }
  // Both outcomes occur, or the damage was too mild or too severe to test anything.
  EXPECT_GT(decoded, 100);
  EXPECT_GT(refused, 100);
}

}  // namespace
