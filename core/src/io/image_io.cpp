// Image files through OpenImageIO 2.4. The only translation unit that includes OIIO.
#include "softgi/io/image_io.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <new>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace softgi::io {
namespace {

namespace fs = std::filesystem;

// Larger sides are treated as corrupt headers rather than images: a 32768-wide lat-long map is
// already 8x the finest environment map in the asset set.
constexpr int kMaxSide = 32768;
// 2^28 pixels (3 GiB as float RGB) is the most one image may hold.
constexpr std::int64_t kMaxPixels = std::int64_t(1) << 28;
// Largest finite half; larger values would become +inf in a half EXR.
constexpr float kHalfMax = 65504.0f;

[[noreturn]] void fail(const std::string& path, const std::string& reason) {
  throw std::runtime_error(path + ": " + reason);
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  return s.empty() ? std::string("unknown error") : s;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

void check_size(const std::string& path, int w, int h) {
  if (w < 1 || h < 1 || w > kMaxSide || h > kMaxSide ||
      std::int64_t(w) * std::int64_t(h) > kMaxPixels) {
    fail(path, "absurd image size " + std::to_string(w) + "x" + std::to_string(h) + " (each side must be in [1, " +
                   std::to_string(kMaxSide) + "], at most " + std::to_string(kMaxPixels) + " pixels)");
  }
}

void check_image(const std::string& path, const Image& img) {
  check_size(path, img.width, img.height);
  if (img.rgb.size() != std::size_t(img.width) * std::size_t(img.height)) {
    fail(path, "image holds " + std::to_string(img.rgb.size()) + " pixels but claims " + std::to_string(img.width) +
                   "x" + std::to_string(img.height));
  }
}

std::string describe(float v) {
  if (std::isnan(v)) return "nan";
  return v > 0 ? "inf" : "-inf";
}

// Refuses to write non-finite pixels: a NaN in an output file would otherwise pass unseen into
// metrics and reports.
void check_finite(const std::string& path, const Image& img) {
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const glm::vec3& c = img.at(x, y);
      for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(c[k])) {
          fail(path, "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") channel " + std::to_string(k) +
                         " is " + describe(c[k]) + "; refusing to write a non-finite image");
        }
      }
    }
  }
}

float srgb_to_linear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float v) {
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

std::uint8_t to_byte(float v) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

// Writes `pixels` (one row after another, `channels` values of `type` each) to PATH.tmp in the
// given format, then renames over PATH, so an existing file is never left half-written.
// `buffer_type` is the type of `pixels`; OIIO converts to spec.format (float -> half) while writing.
void write_atomic(const std::string& path, const char* format, const OIIO::ImageSpec& spec, OIIO::TypeDesc buffer_type,
                  const void* pixels) {
  if (path.empty()) throw std::runtime_error("cannot write an image to an empty path");
  const std::string tmp = path + ".tmp";
  auto out = OIIO::ImageOutput::create(format);
  if (!out) fail(path, std::string("OpenImageIO has no '") + format + "' writer: " + trim(OIIO::geterror()));
  if (!out->open(tmp, spec)) {
    std::string reason = trim(out->geterror());
    std::error_code ec;
    fs::remove(tmp, ec);
    fail(path, "cannot open for writing (" + tmp + "): " + reason);
  }
  const bool ok = out->write_image(buffer_type, pixels);
  std::string reason = ok ? std::string() : trim(out->geterror());
  const bool closed = out->close();
  if (ok && !closed) reason = trim(out->geterror());
  out.reset();
  if (!ok || !closed) {
    std::error_code ec;
    fs::remove(tmp, ec);
    fail(path, "write failed: " + reason);
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    fail(path, "cannot rename " + tmp + " into place: " + ec.message());
  }
}

void write_png8(const std::string& path, const Image& img, float exposure, bool encode_srgb) {
  check_image(path, img);
  check_finite(path, img);
  const std::vector<std::uint8_t> bytes = display_bytes(img, exposure, encode_srgb);
  OIIO::ImageSpec spec(img.width, img.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  write_atomic(path, "png", spec, OIIO::TypeDesc::UINT8, bytes.data());
}

}  // namespace

std::vector<std::uint8_t> display_bytes(const Image& img, float exposure, bool encode_srgb, int channels) {
  std::vector<std::uint8_t> bytes(img.rgb.size() * std::size_t(channels), 255);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      float v = img.rgb[i][k] * exposure;
      v = v > 0.0f ? std::min(v, 1.0f) : 0.0f;  // NaN -> 0
      if (encode_srgb) v = linear_to_srgb(v);
      bytes[std::size_t(channels) * i + std::size_t(k)] = to_byte(v);
    }
  }
  return bytes;
}

Image read_image(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(path, "no such file");
  if (fs::is_directory(path, ec)) fail(path, "is a directory, not an image");
  auto in = OIIO::ImageInput::open(path);
  if (!in) fail(path, "cannot read image: " + trim(OIIO::geterror()));
  const OIIO::ImageSpec spec = in->spec();
  if (spec.depth > 1) fail(path, "volume images (depth " + std::to_string(spec.depth) + ") are not supported");
  if (spec.deep) fail(path, "deep images are not supported");
  check_size(path, spec.width, spec.height);
  if (spec.nchannels < 1 || spec.nchannels > 64) {
    fail(path, "unsupported channel count " + std::to_string(spec.nchannels));
  }
  // Only the channels used below are decoded, so a header declaring 64 channels costs no more than
  // RGB; the buffer is left uninitialised (read_image writes every pixel it reports read), so a
  // few-byte file declaring the largest size allowed does not touch gigabytes before it fails.
  const int nch = std::min(spec.nchannels, 3);
  const std::size_t count = std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(nch);
  std::unique_ptr<float[]> data(new (std::nothrow) float[count]);
  if (!data) fail(path, "cannot allocate " + std::to_string(count * sizeof(float)) + " bytes for its pixels");
  if (!in->read_image(0, 0, 0, nch, OIIO::TypeDesc::FLOAT, data.get())) {
    fail(path, "cannot decode pixels: " + trim(in->geterror()));
  }
  // Decides how stored values map to linear radiance. 8/16-bit files without a colour-space tag are
  // assumed sRGB (PNG, JPEG convention); float files are linear.
  const std::string cs = lower(spec.get_string_attribute("oiio:ColorSpace"));
  const float gamma = spec.get_float_attribute("oiio:Gamma", 0.0f);
  const bool is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT || spec.format.basetype == OIIO::TypeDesc::HALF ||
                        spec.format.basetype == OIIO::TypeDesc::DOUBLE;
  enum class Transfer { Linear, Srgb, Gamma } transfer = is_float ? Transfer::Linear : Transfer::Srgb;
  if (cs.find("linear") != std::string::npos || cs == "scene_linear" || cs == "acescg") {
    transfer = Transfer::Linear;
  } else if (cs == "srgb") {
    transfer = Transfer::Srgb;
  } else if (gamma > 0.0f && std::isfinite(gamma) && std::fabs(gamma - 1.0f) > 1e-6f) {
    transfer = Transfer::Gamma;
  } else if (gamma > 0.0f) {
    transfer = Transfer::Linear;
  }

  Image img(spec.width, spec.height);
  for (int y = 0; y < spec.height; ++y) {
    for (int x = 0; x < spec.width; ++x) {
      const float* p = &data[(std::size_t(y) * std::size_t(spec.width) + std::size_t(x)) * std::size_t(nch)];
      // One or two channels (grey, grey + alpha) replicate the first; more take the first three.
      glm::vec3 c = nch >= 3 ? glm::vec3(p[0], p[1], p[2]) : glm::vec3(p[0]);
      for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(c[k])) {
          fail(path, "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") channel " + std::to_string(k) +
                         " is " + describe(c[k]));
        }
        if (transfer == Transfer::Srgb) {
          c[k] = srgb_to_linear(c[k]);
        } else if (transfer == Transfer::Gamma) {
          c[k] = std::pow(std::max(c[k], 0.0f), gamma);
        }
      }
      img.at(x, y) = c;
    }
  }
  in->close();
  return img;
}

void read_rgb_float(const std::string& path, int& width, int& height, std::vector<float>& rgb) {
  Image img = read_image(path);
  width = img.width;
  height = img.height;
  rgb.resize(img.rgb.size() * 3);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    rgb[3 * i + 0] = img.rgb[i].x;
    rgb[3 * i + 1] = img.rgb[i].y;
    rgb[3 * i + 2] = img.rgb[i].z;
  }
}

EnvironmentMap read_environment_map(const std::string& path, float max_radiance) {
  if (!(max_radiance > 0.0f) || !std::isfinite(max_radiance)) {
    std::ostringstream s;
    s << "the radiance limit must be finite and positive, got " << max_radiance;
    fail(path, s.str());
  }
  // read_image has already refused NaN and infinity, naming the pixel.
  const Image img = read_image(path);
  EnvironmentMap map;
  map.width = img.width;
  map.height = img.height;
  map.rgb.resize(img.rgb.size() * 3);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const glm::vec3& c = img.at(x, y);
      for (int k = 0; k < 3; ++k) {
        float v = c[k];
        if (v > max_radiance) {
          std::ostringstream s;
          s << "pixel (" << x << ", " << y << ") channel " << k << " is " << v << ", above the radiance limit "
            << max_radiance;
          fail(path, s.str());
        }
        if (v < 0.0f) {
          ++map.negative_clamped;
          if (v < map.lowest) {
            map.lowest = v;
            map.lowest_x = x;
            map.lowest_y = y;
          }
          v = 0.0f;
        }
        map.rgb[3 * (std::size_t(y) * std::size_t(img.width) + std::size_t(x)) + std::size_t(k)] = v;
      }
    }
  }
  return map;
}

void write_exr(const std::string& path, const Image& img, bool half) {
  check_image(path, img);
  check_finite(path, img);
  OIIO::ImageSpec spec(img.width, img.height, 3, half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"R", "G", "B"};
  spec.attribute("compression", "zip");
  spec.attribute("oiio:ColorSpace", "Linear");
  if (!half) {
    write_atomic(path, "openexr", spec, OIIO::TypeDesc::FLOAT, img.rgb.data());
    return;
  }
  // Values beyond the half range are clamped to the largest finite half rather than becoming inf.
  std::vector<float> clamped(img.rgb.size() * 3);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    for (int k = 0; k < 3; ++k) clamped[3 * i + std::size_t(k)] = std::clamp(img.rgb[i][k], -kHalfMax, kHalfMax);
  }
  write_atomic(path, "openexr", spec, OIIO::TypeDesc::FLOAT, clamped.data());
}

void write_png(const std::string& path, const Image& img, float exposure) {
  if (!std::isfinite(exposure) || exposure <= 0.0f) {
    std::ostringstream s;
    s << "exposure must be a finite positive number, got " << exposure;
    fail(path, s.str());
  }
  write_png8(path, img, exposure, true);
}

void write_png_display(const std::string& path, const Image& img) { write_png8(path, img, 1.0f, false); }

}  // namespace softgi::io
