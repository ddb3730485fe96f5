// 64-bit FNV-1a over bytes, for the content keys of the disk caches (proxy fits, references).
// Internal to softgi::io.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace softgi::io {

struct Fnv {
  std::uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, std::size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= c[i];
      h *= 1099511628211ull;
    }
  }
  // Trivially copyable values without padding (scalars, glm vectors and matrices).
  template <class T>
  void pod(const T& v) {
    bytes(&v, sizeof v);
  }
  template <class T>
  void vec(const std::vector<T>& v) {
    pod(v.size());
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  void str(const std::string& s) {
    pod(s.size());
    bytes(s.data(), s.size());
  }
};

}  // namespace softgi::io
