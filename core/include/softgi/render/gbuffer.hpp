// The shared G-buffer: primary visibility at display resolution. Per-vertex techniques interpolate
// their vertex results with (object, primitive, barycentrics); image-space techniques read
// position, normal and depth. A frame's G-buffer holds the planes its passes read
// (Technique::gbuffer_planes): the visibility planes always, the others where they are needed.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

namespace softgi::render {

class FramePool;

// Plane groups beyond the visibility planes (object, primitive, barycentric), which every G-buffer
// holds. A plane left out is an empty vector.
enum GBufferPlanes : unsigned {
  kGBufferVisibility = 0u,
  kGBufferSurface = 1u << 0,  // position, normal, depth
  kGBufferAlbedo = 1u << 1,   // albedo
  kGBufferViewDir = 1u << 2,  // view_dir
  kGBufferAll = kGBufferSurface | kGBufferAlbedo | kGBufferViewDir,
};

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
  unsigned planes = kGBufferAll;     // the GBufferPlanes held
  bool hit(std::size_t i) const { return object[i] >= 0; }
  bool has(unsigned p) const { return (planes & p) == p; }
  // width x height pixels that hit nothing: depth +inf, object and primitive -1, zero vectors; the
  // planes taken from `pool` where one is given.
  static GBuffer background(int width, int height, int scale = 1, FramePool* pool = nullptr, unsigned planes = kGBufferAll);
  // width x height pixels of unspecified values, the planes taken from `pool` (last frame's, when
  // it has them): for a renderer that writes every pixel, a miss with set_background.
  static GBuffer for_overwrite(int width, int height, int scale, FramePool& pool, unsigned planes = kGBufferAll);
  // Pixel i hits nothing: what background() holds, with the ray direction `ray_dir` as view_dir.
  void set_background(std::size_t i, const glm::vec3& ray_dir) {
    if (planes & kGBufferSurface) {
      position[i] = normal[i] = glm::vec3(0.0f);
      depth[i] = std::numeric_limits<float>::infinity();
    }
    if (planes & kGBufferAlbedo) albedo[i] = glm::vec3(0.0f);
    if (planes & kGBufferViewDir) view_dir[i] = ray_dir;
    object[i] = primitive[i] = -1;
    barycentric[i] = glm::vec2(0.0f);
  }
  std::size_t bytes() const;
};

}  // namespace softgi::render
