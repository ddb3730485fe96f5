// Helpers for the io tests: scratch directories and a small glTF/GLB writer, so that every test
// file is produced by the test itself from known values.
#pragma once

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace softgi::test {

// A fresh directory per test, removed afterwards.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string(info ? info->test_suite_name() : "io") + "_" + (info ? info->name() : "test");
    for (char& c : name) {
      if (c == '/') c = '_';
    }
    path_ = std::filesystem::temp_directory_path() / ("softgi_io_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline void write_bytes(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}
inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}
inline std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<unsigned char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The message of the exception f() throws, or "(no exception)".
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

// Builds a glTF 2.0 document with one binary buffer; writes it as GLB or as .gltf + .bin.
class GltfBuilder {
 public:
  nlohmann::json doc;

  GltfBuilder() {
    doc["asset"] = {{"version", "2.0"}, {"generator", "softgi tests"}};
    doc["buffers"] = nlohmann::json::array();
    doc["bufferViews"] = nlohmann::json::array();
    doc["accessors"] = nlohmann::json::array();
  }

  // Appends raw bytes (4-byte aligned) as a new buffer view; returns its index.
  int view(const void* data, std::size_t bytes) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    const std::size_t offset = bin_.size();
    bin_.resize(offset + bytes);
    std::memcpy(bin_.data() + offset, data, bytes);
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}});
    return int(doc["bufferViews"].size()) - 1;
  }

  template <typename T>
  int accessor(const std::vector<T>& values, int component_type, const char* type, int components,
               bool normalized = false) {
    const int v = view(values.data(), values.size() * sizeof(T));
    nlohmann::json a = {{"bufferView", v},
                        {"componentType", component_type},
                        {"count", values.size() / std::size_t(components)},
                        {"type", type}};
    if (normalized) a["normalized"] = true;
    doc["accessors"].push_back(a);
    return int(doc["accessors"].size()) - 1;
  }
  int floats(const std::vector<float>& v, const char* type, int components) { return accessor(v, 5126, type, components); }
  int ushorts(const std::vector<std::uint16_t>& v, const char* type, int components) {
    return accessor(v, 5123, type, components);
  }

  std::vector<unsigned char> glb() {
    finish_buffer(false);
    std::string json = doc.dump();
    while (json.size() % 4 != 0) json.push_back(' ');
    std::vector<unsigned char> out;
    auto u32 = [&out](std::uint32_t x) {
      for (int i = 0; i < 4; ++i) out.push_back(static_cast<unsigned char>(x >> (8 * i)));
    };
    std::vector<unsigned char> bin = bin_;
    while (bin.size() % 4 != 0) bin.push_back(0);
    const std::uint32_t total = 12 + 8 + std::uint32_t(json.size()) + (bin.empty() ? 0 : 8 + std::uint32_t(bin.size()));
    u32(0x46546C67);
    u32(2);
    u32(total);
    u32(std::uint32_t(json.size()));
    u32(0x4E4F534A);
    out.insert(out.end(), json.begin(), json.end());
    if (!bin.empty()) {
      u32(std::uint32_t(bin.size()));
      u32(0x004E4942);
      out.insert(out.end(), bin.begin(), bin.end());
    }
    return out;
  }
  void write_glb(const std::string& path) { write_bytes(path, glb()); }
  // .gltf with the buffer in `bin_name` next to it.
  void write_gltf(const std::string& path, const std::string& bin_name) {
    finish_buffer(true, bin_name);
    write_text(path, doc.dump(1));
    write_bytes((std::filesystem::path(path).parent_path() / bin_name).string(), bin_);
  }

 private:
  std::vector<unsigned char> bin_;

  void finish_buffer(bool external, const std::string& uri = "") {
    nlohmann::json b = {{"byteLength", bin_.size()}};
    if (external) b["uri"] = uri;
    doc["buffers"] = nlohmann::json::array({b});
  }
};

}  // namespace softgi::test
