// Uncompressed OpenEXR and stored-deflate PNG, with no library beyond the C++ standard one.
// References: "OpenEXR File Layout" (openexr.com/en/latest/OpenEXRFileLayout.html); PNG
// (W3C Recommendation, 2nd edition = ISO/IEC 15948); zlib (RFC 1950); deflate (RFC 1951).
#include "image_codec_builtin.hpp"

#include "image_codec.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <new>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace softgi::io::builtin {
namespace {

namespace fs = std::filesystem;

// The OpenImageIO reader's limits (image_codec.hpp), so that both builds accept the same files.
using codec::fail;
using codec::kMaxPixels;
using codec::kMaxSide;

std::string errno_text(int e) { return std::generic_category().message(e); }

void check_size(const std::string& path, std::int64_t w, std::int64_t h) {
  if (w < 1 || h < 1 || w > kMaxSide || h > kMaxSide || w * h > kMaxPixels) {
    fail(path, "absurd image size " + std::to_string(w) + "x" + std::to_string(h) + " (each side must be in [1, " +
                   std::to_string(kMaxSide) + "], at most " + std::to_string(kMaxPixels) + " pixels)");
  }
}

// ---------------------------------------------------------------------------------------------
// Output

// A file being written. Unless close() succeeds, the destructor removes it, so that an error
// (a full disk, an exception between writes) never leaves a truncated image under `path`.
class OutFile {
 public:
  explicit OutFile(const std::string& path) : path_(path) {
    if (path.empty()) throw std::runtime_error("cannot write an image to an empty path");
    file_ = std::fopen(path.c_str(), "wb");
    if (!file_) fail(path, "cannot open for writing: " + errno_text(errno));
  }
  OutFile(const OutFile&) = delete;
  OutFile& operator=(const OutFile&) = delete;
  ~OutFile() {
    if (file_) {
      std::fclose(file_);
      std::remove(path_.c_str());
    }
  }

  void write(const std::uint8_t* data, std::size_t n) {
    if (n != 0 && std::fwrite(data, 1, n, file_) != n) abandon("write failed: " + errno_text(errno));
  }
  void write(const std::vector<std::uint8_t>& bytes) { write(bytes.data(), bytes.size()); }

  void close() {
    std::FILE* f = file_;
    file_ = nullptr;
    // Buffered data reaches the disk only here, so a full disk is often reported by fclose.
    if (std::fclose(f) != 0) {
      const int e = errno;
      std::remove(path_.c_str());
      fail(path_, "write failed: " + errno_text(e));
    }
  }

 private:
  [[noreturn]] void abandon(const std::string& reason) {
    std::fclose(file_);
    file_ = nullptr;
    std::remove(path_.c_str());
    fail(path_, reason);
  }

  std::string path_;
  std::FILE* file_ = nullptr;
};

// OpenEXR stores every number little-endian; PNG big-endian.
void put_u8(std::vector<std::uint8_t>& out, std::uint32_t v) { out.push_back(static_cast<std::uint8_t>(v & 0xffu)); }
void put_le16(std::vector<std::uint8_t>& out, std::uint32_t v) {
  put_u8(out, v);
  put_u8(out, v >> 8);
}
void put_le32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) put_u8(out, v >> (8 * i));
}
void put_le64(std::vector<std::uint8_t>& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) put_u8(out, static_cast<std::uint32_t>((v >> (8 * i)) & 0xffu));
}
void put_i32(std::vector<std::uint8_t>& out, std::int32_t v) { put_le32(out, static_cast<std::uint32_t>(v)); }
void put_f32(std::vector<std::uint8_t>& out, float v) { put_le32(out, std::bit_cast<std::uint32_t>(v)); }
void put_be32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 3; i >= 0; --i) put_u8(out, v >> (8 * i));
}
void put_text(std::vector<std::uint8_t>& out, const char* s) {
  for (; *s; ++s) put_u8(out, static_cast<unsigned char>(*s));
  put_u8(out, 0);
}

// ---------------------------------------------------------------------------------------------
// Half floats (IEEE 754 binary16: 1 sign, 5 exponent bits biased by 15, 10 significand bits)

// The largest finite half is 65504; values from 65520 (half-way to 2^16) upwards round to infinity.
constexpr float kHalfOverflow = 65520.0f;

// Round to nearest, ties to even. |f| < kHalfOverflow and finite (write_exr checks first).
std::uint16_t float_to_half(float f) {
  const std::uint32_t x = std::bit_cast<std::uint32_t>(f);
  const std::uint32_t sign = (x >> 16) & 0x8000u;
  const std::uint32_t ax = x & 0x7fffffffu;
  if (ax >= 0x38800000u) {  // >= 2^-14, the smallest normal half
    // Rebias the exponent from 127 to 15, then round away the 13 low significand bits; a carry
    // out of the significand correctly bumps the exponent.
    std::uint32_t m = ax - (112u << 23);
    m += 0x0fffu + ((m >> 13) & 1u);
    return static_cast<std::uint16_t>(sign | (m >> 13));
  }
  if (ax <= 0x33000000u) return static_cast<std::uint16_t>(sign);  // <= 2^-25: ties to the even 0
  // Subnormal half: a multiple of 2^-24. The float is (mant / 2^23) * 2^(e - 127).
  const std::uint32_t e = ax >> 23;
  const std::uint32_t mant = (ax & 0x7fffffu) | 0x800000u;
  const std::uint32_t shift = 126u - e;  // 14..24
  std::uint32_t q = mant >> shift;
  const std::uint32_t rem = mant & ((1u << shift) - 1u);
  const std::uint32_t halfway = 1u << (shift - 1u);
  if (rem > halfway || (rem == halfway && (q & 1u))) ++q;
  return static_cast<std::uint16_t>(sign | q);
}

float half_to_float(std::uint32_t h) {
  const std::uint32_t sign = (h & 0x8000u) << 16;
  const std::uint32_t e = (h >> 10) & 0x1fu;
  std::uint32_t m = h & 0x3ffu;
  if (e == 31) return std::bit_cast<float>(sign | 0x7f800000u | (m << 13));  // inf, NaN
  if (e != 0) return std::bit_cast<float>(sign | ((e + 112u) << 23) | (m << 13));
  if (m == 0) return std::bit_cast<float>(sign);
  // Subnormal half: normalise it, since every subnormal half is a normal float.
  std::uint32_t fe = 113;
  while ((m & 0x400u) == 0) {
    m <<= 1;
    --fe;
  }
  return std::bit_cast<float>(sign | (fe << 23) | ((m & 0x3ffu) << 13));
}

// ---------------------------------------------------------------------------------------------
// OpenEXR constants (OpenEXR File Layout)

constexpr std::uint32_t kExrMagic = 20000630;  // bytes 76 2f 31 01
constexpr std::uint32_t kExrVersion = 2;
// Version-field flags.
constexpr std::uint32_t kFlagTiled = 0x200;
constexpr std::uint32_t kFlagLongNames = 0x400;
constexpr std::uint32_t kFlagNonImage = 0x800;  // deep data
constexpr std::uint32_t kFlagMultiPart = 0x1000;
// Pixel types of the chlist attribute.
constexpr std::int32_t kPixelUint = 0;
constexpr std::int32_t kPixelHalf = 1;
constexpr std::int32_t kPixelFloat = 2;
// Attribute and channel names are at most 31 bytes, or 255 with the long-names flag.
constexpr std::size_t kMaxNameLength = 255;

const char* const kCompressionNames[] = {"no", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB"};

void put_attribute(std::vector<std::uint8_t>& out, const char* name, const char* type,
                   const std::vector<std::uint8_t>& value) {
  put_text(out, name);
  put_text(out, type);
  put_i32(out, static_cast<std::int32_t>(value.size()));
  out.insert(out.end(), value.begin(), value.end());
}

std::vector<std::uint8_t> box2i(int x0, int y0, int x1, int y1) {
  std::vector<std::uint8_t> v;
  for (int c : {x0, y0, x1, y1}) put_i32(v, c);
  return v;
}

}  // namespace

void write_exr(const std::string& path, int width, int height, const float* rgb, bool half) {
  check_size(path, width, height);
  if (!rgb) fail(path, "no pixels to write");
  const std::size_t w = static_cast<std::size_t>(width);
  const std::size_t h = static_cast<std::size_t>(height);
  if (half) {
    for (std::size_t i = 0; i < w * h * 3; ++i) {
      if (!(std::fabs(rgb[i]) < kHalfOverflow)) {
        std::ostringstream s;
        s << "pixel (" << (i / 3) % w << ", " << i / 3 / w << ") channel " << i % 3 << " is " << rgb[i]
          << ", beyond the largest half (65504); refusing to write it as half";
        fail(path, s.str());
      }
    }
  }

  std::vector<std::uint8_t> head;
  put_le32(head, kExrMagic);
  put_le32(head, kExrVersion);  // no flags: single-part scanline, short names
  std::vector<std::uint8_t> channels;
  const std::int32_t pixel_type = half ? kPixelHalf : kPixelFloat;
  for (const char* name : {"B", "G", "R"}) {  // the format requires alphabetical order
    put_text(channels, name);
    put_i32(channels, pixel_type);
    put_le32(channels, 0);  // pLinear (0) and three reserved bytes
    put_i32(channels, 1);   // xSampling
    put_i32(channels, 1);   // ySampling
  }
  put_u8(channels, 0);
  put_attribute(head, "channels", "chlist", channels);
  put_attribute(head, "compression", "compression", {0});  // NO_COMPRESSION
  put_attribute(head, "dataWindow", "box2i", box2i(0, 0, width - 1, height - 1));
  put_attribute(head, "displayWindow", "box2i", box2i(0, 0, width - 1, height - 1));
  put_attribute(head, "lineOrder", "lineOrder", {0});  // INCREASING_Y
  std::vector<std::uint8_t> value;
  put_f32(value, 1.0f);
  put_attribute(head, "pixelAspectRatio", "float", value);
  value.clear();
  put_f32(value, 0.0f);
  put_f32(value, 0.0f);
  put_attribute(head, "screenWindowCenter", "v2f", value);
  value.clear();
  put_f32(value, 1.0f);
  put_attribute(head, "screenWindowWidth", "float", value);
  put_u8(head, 0);  // end of header

  // Uncompressed files hold one scanline per chunk: y, byte count, then each channel's samples.
  const std::size_t sample_bytes = half ? 2 : 4;
  const std::size_t data_bytes = w * 3 * sample_bytes;
  const std::uint64_t first_chunk = head.size() + 8 * std::uint64_t(h);
  for (std::size_t y = 0; y < h; ++y) put_le64(head, first_chunk + std::uint64_t(y) * (8 + data_bytes));

  OutFile out(path);
  out.write(head);
  std::vector<std::uint8_t> row;
  row.reserve(8 + data_bytes);
  for (std::size_t y = 0; y < h; ++y) {
    row.clear();
    put_i32(row, static_cast<std::int32_t>(y));
    put_i32(row, static_cast<std::int32_t>(data_bytes));
    const float* line = rgb + y * w * 3;
    for (const std::size_t c : {std::size_t(2), std::size_t(1), std::size_t(0)}) {  // B, G, R
      for (std::size_t x = 0; x < w; ++x) {
        const float v = line[3 * x + c];
        if (half) {
          put_le16(row, float_to_half(v));
        } else {
          put_f32(row, v);
        }
      }
    }
    out.write(row);
  }
  out.close();
}

// ---------------------------------------------------------------------------------------------
// PNG

namespace {

// CRC-32 of PNG chunks (PNG spec, annex D): reflected polynomial 0xedb88320.
constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xedb88320u ^ (c >> 1) : c >> 1;
    t[n] = c;
  }
  return t;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = make_crc_table();

std::uint32_t crc_update(std::uint32_t crc, const std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) crc = kCrcTable[(crc ^ p[i]) & 0xffu] ^ (crc >> 8);
  return crc;
}

// Adler-32 (RFC 1950, section 9). 5552 is the most bytes whose sums cannot overflow 32 bits
// before the modulo.
class Adler32 {
 public:
  void update(const std::uint8_t* p, std::size_t n) {
    while (n > 0) {
      const std::size_t k = std::min<std::size_t>(n, 5552);
      for (std::size_t i = 0; i < k; ++i) {
        a_ += p[i];
        b_ += a_;
      }
      a_ %= kMod;
      b_ %= kMod;
      p += k;
      n -= k;
    }
  }
  std::uint32_t value() const { return (b_ << 16) | a_; }

 private:
  static constexpr std::uint32_t kMod = 65521;
  std::uint32_t a_ = 1, b_ = 0;
};

void write_chunk(OutFile& out, const char* type, const std::vector<std::uint8_t>& data) {
  std::vector<std::uint8_t> head;
  put_be32(head, static_cast<std::uint32_t>(data.size()));
  for (int i = 0; i < 4; ++i) put_u8(head, static_cast<unsigned char>(type[i]));
  std::uint32_t crc = crc_update(0xffffffffu, head.data() + 4, 4);
  crc = crc_update(crc, data.data(), data.size());
  std::vector<std::uint8_t> tail;
  put_be32(tail, crc ^ 0xffffffffu);
  out.write(head);
  out.write(data);
  out.write(tail);
}

// The zlib stream of the image data, cut into IDAT chunks as it grows.
class StoredDeflate {
 public:
  StoredDeflate(OutFile& out, std::uint64_t total) : out_(out), left_(total) {
    // zlib header (RFC 1950): CM 8 (deflate) with a 32 KiB window, FLEVEL 0, and FCHECK making
    // 0x7801 a multiple of 31.
    idat_ = {0x78, 0x01};
    block_.reserve(kMaxBlock);
  }

  void push(const std::uint8_t* p, std::size_t n) {
    adler_.update(p, n);
    while (n > 0) {
      const std::size_t k = std::min(n, kMaxBlock - block_.size());
      block_.insert(block_.end(), p, p + k);
      p += k;
      n -= k;
      left_ -= k;
      if (block_.size() == kMaxBlock) emit_block();
    }
  }

  void finish() {
    if (!block_.empty()) emit_block();
    put_be32(idat_, adler_.value());
    write_chunk(out_, "IDAT", idat_);
  }

 private:
  // A stored block's LEN is 16 bits (RFC 1951, section 3.2.4).
  static constexpr std::size_t kMaxBlock = 65535;
  // IDAT chunks of about 1 MiB: a chunk's length must stay below 2^31, and a chunk is held in
  // memory until its CRC is known.
  static constexpr std::size_t kIdatBytes = std::size_t(1) << 20;

  void emit_block() {
    // Block header: BFINAL in bit 0, BTYPE 00 (stored) in bits 1-2; the rest of the byte pads to
    // the byte boundary that LEN and NLEN start on.
    put_u8(idat_, left_ == 0 ? 1u : 0u);
    const auto len = static_cast<std::uint32_t>(block_.size());
    put_le16(idat_, len);
    put_le16(idat_, ~len & 0xffffu);
    idat_.insert(idat_.end(), block_.begin(), block_.end());
    block_.clear();
    if (idat_.size() >= kIdatBytes) {
      write_chunk(out_, "IDAT", idat_);
      idat_.clear();
    }
  }

  OutFile& out_;
  std::uint64_t left_;  // raw bytes not yet pushed: zero when the block being emitted is the last
  Adler32 adler_;
  std::vector<std::uint8_t> block_;
  std::vector<std::uint8_t> idat_;
};

}  // namespace

void write_png(const std::string& path, int width, int height, int channels, const std::uint8_t* bytes) {
  check_size(path, width, height);
  if (channels != 3 && channels != 4) {
    fail(path, "PNG images are written with 3 or 4 channels, not " + std::to_string(channels));
  }
  if (!bytes) fail(path, "no pixels to write");
  const std::size_t row_bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(channels);

  OutFile out(path);
  const std::uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  out.write(signature, sizeof signature);
  std::vector<std::uint8_t> ihdr;
  put_be32(ihdr, static_cast<std::uint32_t>(width));
  put_be32(ihdr, static_cast<std::uint32_t>(height));
  put_u8(ihdr, 8);                     // bit depth
  put_u8(ihdr, channels == 4 ? 6 : 2);  // colour type: truecolour with alpha, truecolour
  put_u8(ihdr, 0);                     // compression method: deflate
  put_u8(ihdr, 0);                     // filter method: adaptive, five types
  put_u8(ihdr, 0);                     // no interlace
  write_chunk(out, "IHDR", ihdr);
  write_chunk(out, "sRGB", {0});  // rendering intent: perceptual

  StoredDeflate z(out, std::uint64_t(height) * (1 + row_bytes));
  const std::uint8_t filter_none = 0;
  for (std::size_t y = 0; y < static_cast<std::size_t>(height); ++y) {
    z.push(&filter_none, 1);
    z.push(bytes + y * row_bytes, row_bytes);
  }
  z.finish();
  write_chunk(out, "IEND", {});
  out.close();
}

// ---------------------------------------------------------------------------------------------
// OpenEXR reader

namespace {

// A file read with every access checked against its size, so that lengths and offsets taken
// from the file can never reach past its end.
class InFile {
 public:
  explicit InFile(const std::string& path) : path_(path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) fail(path, "no such file");
    if (fs::is_directory(path, ec)) fail(path, "is a directory, not an image");
    file_ = std::fopen(path.c_str(), "rb");
    if (!file_) fail(path, "cannot open: " + errno_text(errno));
    const std::uintmax_t size = fs::file_size(path, ec);
    if (ec) {
      std::fclose(file_);
      fail(path, "cannot read its size: " + ec.message());
    }
    if (size > static_cast<std::uintmax_t>(std::numeric_limits<long>::max())) {
      std::fclose(file_);
      fail(path, "file too large to be an image (" + std::to_string(size) + " bytes)");
    }
    size_ = size;
  }
  InFile(const InFile&) = delete;
  InFile& operator=(const InFile&) = delete;
  ~InFile() { std::fclose(file_); }

  std::uint64_t size() const { return size_; }
  std::uint64_t pos() const { return pos_; }
  std::uint64_t left() const { return size_ - pos_; }

  void read(std::uint8_t* dst, std::uint64_t n, const char* what) {
    if (n > left()) {
      fail(path_, std::string("truncated file: ") + what + " needs " + std::to_string(n) + " bytes at offset " +
                      std::to_string(pos_) + ", the file has " + std::to_string(size_));
    }
    if (n != 0 && std::fread(dst, 1, static_cast<std::size_t>(n), file_) != n) {
      fail(path_, std::string("read error in ") + what + " at offset " + std::to_string(pos_) +
                      (std::ferror(file_) ? ": " + errno_text(errno) : std::string(" (file shrank while read)")));
    }
    pos_ += n;
  }
  std::vector<std::uint8_t> bytes(std::uint64_t n, const char* what) {
    if (n > left()) read(nullptr, n, what);  // reports the truncation before allocating
    std::vector<std::uint8_t> v(static_cast<std::size_t>(n));
    read(v.data(), n, what);
    return v;
  }
  std::uint32_t u8(const char* what) {
    std::uint8_t b = 0;
    read(&b, 1, what);
    return b;
  }
  std::uint32_t u32(const char* what) {
    std::uint8_t b[4];
    read(b, 4, what);
    return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
  }
  std::int32_t i32(const char* what) { return static_cast<std::int32_t>(u32(what)); }

  void seek(std::uint64_t p) {
    if (p > size_) fail(path_, "offset " + std::to_string(p) + " is past the end of the file");
    if (std::fseek(file_, static_cast<long>(p), SEEK_SET) != 0) {
      fail(path_, "cannot seek to offset " + std::to_string(p) + ": " + errno_text(errno));
    }
    pos_ = p;
  }
  void skip(std::uint64_t n, const char* what) {
    if (n > left()) read(nullptr, n, what);
    seek(pos_ + n);
  }

  // A null-terminated name of at most kMaxNameLength bytes; empty at the null byte that ends a list.
  std::string name(const char* what) {
    std::string s;
    for (;;) {
      const std::uint32_t c = u8(what);
      if (c == 0) return s;
      if (s.size() == kMaxNameLength) {
        fail(path_, std::string(what) + " at offset " + std::to_string(pos_ - s.size() - 1) + " is longer than " +
                        std::to_string(kMaxNameLength) + " bytes");
      }
      s.push_back(static_cast<char>(c));
    }
  }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::uint64_t size_ = 0, pos_ = 0;
};

std::uint32_t le32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t le64(const std::uint8_t* p) { return std::uint64_t(le32(p)) | std::uint64_t(le32(p + 4)) << 32; }

// Names shown in messages: printable ASCII, the rest escaped, cut short.
std::string printable(const std::string& s) {
  std::string out;
  for (char ch : s.substr(0, 64)) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f) {
      out.push_back(ch);
    } else {
      const char* hex = "0123456789abcdef";
      out += "\\x";
      out.push_back(hex[c >> 4]);
      out.push_back(hex[c & 15u]);
    }
  }
  if (s.size() > 64) out += "...";
  return out;
}

struct Channel {
  std::string name;
  std::int32_t type = 0;
  std::uint64_t bytes = 0;  // per sample
};

std::vector<Channel> parse_channels(const std::string& path, const std::vector<std::uint8_t>& v) {
  std::vector<Channel> channels;
  std::size_t p = 0;
  for (;;) {
    if (p >= v.size()) fail(path, "the channel list is not terminated");
    if (v[p] == 0) break;
    const std::size_t start = p;
    while (p < v.size() && v[p] != 0) ++p;
    if (p == v.size()) fail(path, "the channel list is not terminated");
    Channel c;
    c.name.assign(reinterpret_cast<const char*>(v.data()) + start, p - start);
    if (c.name.size() > kMaxNameLength) fail(path, "a channel name is longer than 255 bytes");
    ++p;
    // pixel type (int32), pLinear (uint8), three reserved bytes, xSampling, ySampling (int32)
    if (v.size() - p < 16) fail(path, "channel '" + printable(c.name) + "' is cut short in the channel list");
    c.type = static_cast<std::int32_t>(le32(&v[p]));
    const auto xs = static_cast<std::int32_t>(le32(&v[p + 8]));
    const auto ys = static_cast<std::int32_t>(le32(&v[p + 12]));
    p += 16;
    if (c.type == kPixelHalf) {
      c.bytes = 2;
    } else if (c.type == kPixelFloat || c.type == kPixelUint) {
      c.bytes = 4;
    } else {
      fail(path, "channel '" + printable(c.name) + "' has unknown pixel type " + std::to_string(c.type));
    }
    if (xs != 1 || ys != 1) {
      fail(path, "channel '" + printable(c.name) + "' is subsampled (" + std::to_string(xs) + ", " +
                     std::to_string(ys) + "); subsampled channels are not supported");
    }
    channels.push_back(std::move(c));
  }
  if (channels.empty()) fail(path, "the channel list is empty");
  return channels;
}

std::string compression_name(std::uint32_t c) {
  if (c < std::size(kCompressionNames)) return std::string(kCompressionNames[c]) + " compression";
  return "unknown compression " + std::to_string(c);
}

float decode_sample(const std::uint8_t* p, std::int32_t type) {
  if (type == kPixelHalf) return half_to_float(std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8);
  const std::uint32_t u = le32(p);
  if (type == kPixelFloat) return std::bit_cast<float>(u);
  return static_cast<float>(u);  // UINT, as OpenEXR's own conversion does
}

}  // namespace

Decoded read_exr(const std::string& path) {
  InFile in(path);
  if (in.size() < 4) fail(path, "not an OpenEXR file (" + std::to_string(in.size()) + " bytes, too short)");
  if (in.u32("magic number") != kExrMagic) fail(path, "not an OpenEXR file (no magic number 76 2f 31 01)");
  const std::uint32_t version = in.u32("version field");
  if ((version & 0xffu) != kExrVersion) {
    fail(path, "unsupported OpenEXR version " + std::to_string(version & 0xffu) + " (only version 2 is read)");
  }
  if (version & kFlagMultiPart) fail(path, "multi-part OpenEXR files are not supported");
  if (version & kFlagNonImage) fail(path, "deep OpenEXR files are not supported");
  if (version & kFlagTiled) fail(path, "tiled OpenEXR files are not supported");
  const std::uint32_t unknown = version & ~(0xffu | kFlagTiled | kFlagLongNames | kFlagNonImage | kFlagMultiPart);
  if (unknown != 0) {
    std::ostringstream s;
    s << "unknown OpenEXR version flags 0x" << std::hex << unknown;
    fail(path, s.str());
  }

  std::vector<Channel> channels;
  bool have_channels = false, have_compression = false, have_window = false;
  std::uint32_t compression = 0;
  std::int32_t box[4] = {0, 0, 0, 0};
  for (;;) {
    const std::string name = in.name("attribute name");
    if (name.empty()) break;  // end of header
    const std::string type = in.name("attribute type");
    const std::int32_t size = in.i32("attribute size");
    if (size < 0) fail(path, "attribute '" + printable(name) + "' has negative size " + std::to_string(size));
    const auto n = static_cast<std::uint64_t>(size);
    auto expect = [&](const char* want_type, std::int64_t want_size) {
      if (type != want_type || (want_size >= 0 && size != want_size)) {
        fail(path, "attribute '" + printable(name) + "' is " + printable(type) + " of " + std::to_string(size) +
                       " bytes, expected " + want_type);
      }
    };
    if (name == "channels") {
      expect("chlist", -1);
      channels = parse_channels(path, in.bytes(n, "channel list"));
      have_channels = true;
    } else if (name == "compression") {
      expect("compression", 1);
      compression = in.u8("compression");
      have_compression = true;
    } else if (name == "dataWindow") {
      expect("box2i", 16);
      for (auto& b : box) b = in.i32("dataWindow");
      have_window = true;
    } else if (name == "type") {
      // Only multi-part and deep files need it, but a scanline file may carry it too.
      const std::vector<std::uint8_t> v = in.bytes(n, "type attribute");
      const std::string t(v.begin(), v.end());
      if (t != "scanlineimage") fail(path, "part type '" + printable(t) + "' is not supported (only scanlineimage)");
    } else {
      in.skip(n, "attribute value");
    }
  }
  if (!have_channels) fail(path, "the header has no channels attribute");
  if (!have_compression) fail(path, "the header has no compression attribute");
  if (!have_window) fail(path, "the header has no dataWindow attribute");
  if (compression != 0) {
    fail(path, compression_name(compression) +
                   ": this build reads only uncompressed OpenEXR files (built without OpenImageIO)");
  }
  const std::int64_t x_min = box[0], y_min = box[1];
  const std::int64_t width = std::int64_t(box[2]) - x_min + 1;
  const std::int64_t height = std::int64_t(box[3]) - y_min + 1;
  check_size(path, width, height);

  // The channels returned, in the order OpenImageIO gives them: R, G, B, A, else Y, A.
  auto find = [&](const char* want) -> int {
    for (std::size_t i = 0; i < channels.size(); ++i) {
      if (channels[i].name == want) return static_cast<int>(i);
    }
    return -1;
  };
  std::vector<int> picked;
  for (const char* want : {"R", "G", "B"}) {
    if (const int i = find(want); i >= 0) picked.push_back(i);
  }
  if (picked.empty()) {
    if (find("RY") >= 0 || find("BY") >= 0) {
      fail(path, "luminance/chroma (Y, RY, BY) OpenEXR files are not supported");
    }
    if (const int i = find("Y"); i >= 0) picked.push_back(i);
  }
  if (picked.empty()) {
    std::string names;
    for (std::size_t i = 0; i < channels.size() && i < 8; ++i) names += (i ? ", " : "") + printable(channels[i].name);
    if (channels.size() > 8) names += ", ...";
    fail(path, "no R, G, B or Y channel (channels: " + names + ")");
  }
  if (const int a = find("A"); a >= 0) picked.push_back(a);

  // Uncompressed chunks hold one scanline: int32 y, int32 byte count, then for each channel in
  // header order `width` samples.
  const auto w = static_cast<std::uint64_t>(width);
  const auto h = static_cast<std::uint64_t>(height);
  std::vector<std::uint64_t> channel_start(channels.size());
  std::uint64_t row_bytes = 0;
  for (std::size_t i = 0; i < channels.size(); ++i) {
    channel_start[i] = row_bytes;
    row_bytes += w * channels[i].bytes;
  }
  if (row_bytes > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max())) {
    fail(path, "a scanline of " + std::to_string(row_bytes) + " bytes is more than a chunk can hold");
  }
  const std::uint64_t table_start = in.pos();
  const std::uint64_t table_end = table_start + 8 * h;
  // Chunks cannot overlap, so a file shorter than this is cut short; checking it first bounds
  // what is allocated below by the file's own size.
  const std::uint64_t needed = table_end + h * (8 + row_bytes);
  if (needed > in.size()) {
    fail(path, "truncated file: " + std::to_string(in.size()) + " bytes, but a " + std::to_string(width) + "x" +
                   std::to_string(height) + " image with these channels needs at least " + std::to_string(needed));
  }
  const std::vector<std::uint8_t> table = in.bytes(8 * h, "offset table");

  Decoded out;
  out.width = static_cast<int>(width);
  out.height = static_cast<int>(height);
  out.channels = static_cast<int>(picked.size());
  out.is_float = true;
  const std::size_t nout = std::min<std::size_t>(picked.size(), 3);
  try {
    out.data.resize(static_cast<std::size_t>(w * h) * nout);
  } catch (const std::bad_alloc&) {
    fail(path, "cannot allocate " + std::to_string(w * h * nout * sizeof(float)) + " bytes for its pixels");
  }
  std::vector<std::uint8_t> row(static_cast<std::size_t>(row_bytes));
  for (std::uint64_t i = 0; i < h; ++i) {
    const std::int64_t y = y_min + static_cast<std::int64_t>(i);
    const std::uint64_t offset = le64(&table[static_cast<std::size_t>(8 * i)]);
    if (offset < table_end || offset > in.size() || in.size() - offset < 8 + row_bytes) {
      fail(path, "offset table entry " + std::to_string(i) + " (scanline " + std::to_string(y) + ") points to " +
                     std::to_string(offset) + ", outside the file's " + std::to_string(table_end) + ".." +
                     std::to_string(in.size()) + " bytes of chunks");
    }
    in.seek(offset);
    const std::int32_t chunk_y = in.i32("chunk scanline");
    const std::int32_t chunk_bytes = in.i32("chunk size");
    if (chunk_y != y) {
      fail(path, "the chunk at offset " + std::to_string(offset) + " holds scanline " + std::to_string(chunk_y) +
                     ", expected " + std::to_string(y));
    }
    if (chunk_bytes < 0 || static_cast<std::uint64_t>(chunk_bytes) != row_bytes) {
      fail(path, "scanline " + std::to_string(y) + " holds " + std::to_string(chunk_bytes) + " bytes, expected " +
                     std::to_string(row_bytes) + " for uncompressed samples");
    }
    in.read(row.data(), row_bytes, "scanline");
    float* dst = out.data.data() + static_cast<std::size_t>(i * w) * nout;
    for (std::size_t k = 0; k < nout; ++k) {
      const Channel& c = channels[static_cast<std::size_t>(picked[k])];
      const std::uint8_t* src = row.data() + channel_start[static_cast<std::size_t>(picked[k])];
      for (std::uint64_t x = 0; x < w; ++x) {
        dst[static_cast<std::size_t>(x) * nout + k] = decode_sample(src + x * c.bytes, c.type);
      }
    }
  }
  return out;
}

}  // namespace softgi::io::builtin
