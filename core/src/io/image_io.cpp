// Image files: checks, colour transfer and atomic writes, over the codec of image_codec.hpp
// (OpenImageIO, or the built-in one in a build without it).
#include "softgi/io/image_io.hpp"

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

#include "image_codec.hpp"

namespace softgi::io {
namespace {

namespace fs = std::filesystem;

// Largest finite half; larger values would become +inf in a half EXR.
constexpr float kHalfMax = 65504.0f;

using codec::check_size;
using codec::fail;

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

// Writes PATH.tmp with `write` (a codec function), then renames over PATH, so an existing file is
// never left half-written and a failed write leaves nothing behind.
template <class Write>
void write_atomic(const std::string& path, Write&& write) {
  if (path.empty()) throw std::runtime_error("cannot write an image to an empty path");
  const std::string tmp = path + ".tmp";
  try {
    write(tmp);
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(tmp, ec);
    // The codec names the temporary file; the caller asked for `path`.
    std::string reason = e.what();
    if (reason.rfind(tmp + ": ", 0) == 0) reason = reason.substr(tmp.size() + 2);
    fail(path, reason + " (writing " + tmp + ")");
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
  write_atomic(path, [&](const std::string& tmp) { codec::write_png(tmp, img.width, img.height, bytes.data()); });
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
  const codec::Decoded d = codec::read(path);
  check_size(path, d.width, d.height);
  const int nch = std::min(d.channels, 3);
  if (nch < 1 || d.data.size() != std::size_t(d.width) * std::size_t(d.height) * std::size_t(nch))
    fail(path, "decoder returned " + std::to_string(d.data.size()) + " values for " + std::to_string(d.width) + "x" +
                   std::to_string(d.height) + " pixels of " + std::to_string(nch) + " channel(s)");
  const float* data = d.data.data();
  // Decides how stored values map to linear radiance. 8/16-bit files without a colour-space tag are
  // assumed sRGB (PNG, JPEG convention); float files are linear.
  const std::string& cs = d.color_space;
  const float gamma = d.gamma;
  enum class Transfer { Linear, Srgb, Gamma } transfer = d.is_float ? Transfer::Linear : Transfer::Srgb;
  if (cs.find("linear") != std::string::npos || cs == "scene_linear" || cs == "acescg") {
    transfer = Transfer::Linear;
  } else if (cs == "srgb") {
    transfer = Transfer::Srgb;
  } else if (gamma > 0.0f && std::isfinite(gamma) && std::fabs(gamma - 1.0f) > 1e-6f) {
    transfer = Transfer::Gamma;
  } else if (gamma > 0.0f) {
    transfer = Transfer::Linear;
  }

  Image img(d.width, d.height);
  for (int y = 0; y < d.height; ++y) {
    for (int x = 0; x < d.width; ++x) {
      const float* p = &data[(std::size_t(y) * std::size_t(d.width) + std::size_t(x)) * std::size_t(nch)];
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
  const float* rgb = &img.rgb[0].x;
  std::vector<float> clamped;
  if (half) {
    // Values beyond the half range are clamped to the largest finite half rather than becoming inf.
    clamped.resize(img.rgb.size() * 3);
    for (std::size_t i = 0; i < img.rgb.size(); ++i)
      for (int k = 0; k < 3; ++k) clamped[3 * i + std::size_t(k)] = std::clamp(img.rgb[i][k], -kHalfMax, kHalfMax);
    rgb = clamped.data();
  }
  write_atomic(path, [&](const std::string& tmp) { codec::write_exr(tmp, img.width, img.height, rgb, half); });
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

const char* image_codec_name() { return codec::name(); }

}  // namespace softgi::io
