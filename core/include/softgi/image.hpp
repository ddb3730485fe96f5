// A linear HDR RGB image: what renderers produce and metrics compare.
#pragma once

#include <glm/glm.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace softgi {

struct Image {
  int width = 0, height = 0;
  std::vector<glm::vec3> rgb;  // row-major, row 0 at the top
  Image() = default;
  Image(int w, int h, glm::vec3 fill = glm::vec3(0.0f)) : width(w), height(h), rgb(static_cast<std::size_t>(w) * h, fill) {}
  glm::vec3& at(int x, int y) { return rgb[static_cast<std::size_t>(y) * width + x]; }
  const glm::vec3& at(int x, int y) const { return rgb[static_cast<std::size_t>(y) * width + x]; }
  bool empty() const { return rgb.empty(); }
};

// A per-pixel mask (1 = counted). Empty mask = every pixel.
struct Mask {
  int width = 0, height = 0;
  std::vector<std::uint8_t> on;
};

}  // namespace softgi
