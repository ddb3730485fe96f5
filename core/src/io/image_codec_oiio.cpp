// image_codec.hpp through OpenImageIO 2.4: the only translation unit that includes it.
#include "image_codec.hpp"

#ifndef SOFTGI_WITH_OIIO
#error "SOFTGI_WITH_OIIO must be defined to 1 (OpenImageIO) or 0 (the built-in codec)"
#endif
#if SOFTGI_WITH_OIIO
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <memory>
#include <new>

namespace softgi::io::codec {
namespace {

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  return s.empty() ? std::string("unknown error") : s;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

void write(const std::string& path, const char* format, const OIIO::ImageSpec& spec, OIIO::TypeDesc buffer_type, const void* pixels) {
  auto out = OIIO::ImageOutput::create(format);
  if (!out) fail(path, std::string("OpenImageIO has no '") + format + "' writer: " + trim(OIIO::geterror()));
  if (!out->open(path, spec)) fail(path, "cannot open for writing: " + trim(out->geterror()));
  const bool ok = out->write_image(buffer_type, pixels);
  std::string reason = ok ? std::string() : trim(out->geterror());
  const bool closed = out->close();
  if (ok && !closed) reason = trim(out->geterror());
  if (!ok || !closed) fail(path, "write failed: " + reason);
}

}  // namespace

Decoded read(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) fail(path, "cannot read image: " + trim(OIIO::geterror()));
  const OIIO::ImageSpec spec = in->spec();
  if (spec.depth > 1) fail(path, "volume images (depth " + std::to_string(spec.depth) + ") are not supported");
  if (spec.deep) fail(path, "deep images are not supported");
  check_size(path, spec.width, spec.height);
  if (spec.nchannels < 1 || spec.nchannels > 64) fail(path, "unsupported channel count " + std::to_string(spec.nchannels));
  // Only the channels used are decoded, so a header declaring 64 channels costs no more than RGB;
  // the buffer is left uninitialised (read_image writes every pixel it reports read), so a few-byte
  // file declaring the largest size allowed does not touch gigabytes before it fails.
  const int nch = std::min(spec.nchannels, 3);
  const std::size_t count = std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(nch);
  std::unique_ptr<float[]> data(new (std::nothrow) float[count]);
  if (!data) fail(path, "cannot allocate " + std::to_string(count * sizeof(float)) + " bytes for its pixels");
  if (!in->read_image(0, 0, 0, nch, OIIO::TypeDesc::FLOAT, data.get())) fail(path, "cannot decode pixels: " + trim(in->geterror()));
  in->close();
  Decoded d;
  d.width = spec.width;
  d.height = spec.height;
  d.channels = spec.nchannels;
  d.is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT || spec.format.basetype == OIIO::TypeDesc::HALF ||
               spec.format.basetype == OIIO::TypeDesc::DOUBLE;
  d.color_space = lower(spec.get_string_attribute("oiio:ColorSpace"));
  d.gamma = spec.get_float_attribute("oiio:Gamma", 0.0f);
  d.data.assign(data.get(), data.get() + count);
  return d;
}

void write_exr(const std::string& path, int w, int h, const float* rgb, bool half) {
  OIIO::ImageSpec spec(w, h, 3, half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"R", "G", "B"};
  spec.attribute("compression", "zip");
  spec.attribute("oiio:ColorSpace", "Linear");
  write(path, "openexr", spec, OIIO::TypeDesc::FLOAT, rgb);
}

void write_png(const std::string& path, int w, int h, const std::uint8_t* rgb) {
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  write(path, "png", spec, OIIO::TypeDesc::UINT8, rgb);
}

const char* name() { return "OpenImageIO " OIIO_VERSION_STRING; }

}  // namespace softgi::io::codec

#else  // the built-in codec (image_codec_builtin.hpp)

#include <filesystem>
#include <fstream>

#include "image_codec_builtin.hpp"

namespace softgi::io::codec {

Decoded read(const std::string& path) {
  // The built-in reader knows uncompressed OpenEXR only: say so for anything else by its magic.
  std::ifstream f(path, std::ios::binary);
  unsigned char magic[4] = {0, 0, 0, 0};
  f.read(reinterpret_cast<char*>(magic), 4);
  if (!(magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01))
    fail(path, "this build reads only uncompressed OpenEXR files (built without OpenImageIO)");
  builtin::Decoded b = builtin::read_exr(path);
  Decoded d;
  d.width = b.width;
  d.height = b.height;
  d.channels = b.channels;
  d.is_float = b.is_float;
  d.data = std::move(b.data);
  return d;
}

void write_exr(const std::string& path, int w, int h, const float* rgb, bool half) { builtin::write_exr(path, w, h, rgb, half); }

void write_png(const std::string& path, int w, int h, const std::uint8_t* rgb) { builtin::write_png(path, w, h, 3, rgb); }

const char* name() { return "built-in (uncompressed OpenEXR, PNG writer)"; }

}  // namespace softgi::io::codec

#endif
