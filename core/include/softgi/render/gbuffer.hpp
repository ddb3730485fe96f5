// The shared G-buffer: primary visibility at display resolution. Per-vertex techniques interpolate
// their vertex results with (object, primitive, barycentrics); image-space techniques read
// position, normal and depth.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

namespace softgi::render {

class FramePool;

struct GBuffer {
  int width = 0, height = 0;
  // Receiver buffers (paper 000 section 4) sample every `scale`-th display point: pixel (x, y) holds
  // the primary hit through display image point ((x + 0.5) scale, (y + 0.5) scale). 1 = display.
  int scale = 1;
  std::vector<glm::vec3> position;   // world space
  std::vector<glm::vec3> normal;     // world space shading normal (interpolated, unit)
  std::vector<float> depth;          // eye-space depth (p - e) . E (paper 000 section 4); +inf where no hit
  std::vector<glm::vec3> albedo;     // material * texture * vertex colour
  std::vector<std::int32_t> object;  // PosedScene::objects index, -1 = background
  std::vector<std::int32_t> primitive;
  std::vector<glm::vec2> barycentric;  // (b1, b2); b0 = 1 - b1 - b2
  std::vector<glm::vec3> view_dir;   // unit, from the surface towards the eye (or the ray direction for background)
  bool hit(std::size_t i) const { return object[i] >= 0; }
  // width x height pixels that hit nothing: depth +inf, object and primitive -1, zero vectors; the
  // planes taken from `pool` where one is given.
  static GBuffer background(int width, int height, int scale = 1, FramePool* pool = nullptr);
  // width x height pixels of unspecified values, the planes taken from `pool` (last frame's, when
  // it has them): for a renderer that writes every pixel, a miss with set_background.
  static GBuffer for_overwrite(int width, int height, int scale, FramePool& pool);
  // Pixel i hits nothing: what background() holds, with the ray direction `ray_dir` as view_dir.
  void set_background(std::size_t i, const glm::vec3& ray_dir) {
    position[i] = normal[i] = albedo[i] = glm::vec3(0.0f);
    depth[i] = std::numeric_limits<float>::infinity();
    object[i] = primitive[i] = -1;
    barycentric[i] = glm::vec2(0.0f);
    view_dir[i] = ray_dir;
  }
  std::size_t bytes() const;
};

}  // namespace softgi::render
