// The one camera model of softgi: a pinhole camera looking from Camera::position at Camera::target,
// vertical field of view fov_y_deg, aspect width / height. The G-buffer pass, the reference renderer
// and every image-space technique generate their rays here, so a technique's pixel (x, y) and the
// reference's pixel (x, y) see the same point.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/scene/scene.hpp"

namespace softgi::render {

struct PinholeCamera {
  glm::vec3 position{0.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f};  // unit; the image-plane normal E of paper 000 section 4
  glm::vec3 right{1.0f, 0.0f, 0.0f};     // unit, forward x up_hint
  glm::vec3 up{0.0f, 1.0f, 0.0f};        // unit, right x forward
  float tan_half_fov_y = 1.0f;
  float aspect = 1.0f;  // width / height
  int width = 0, height = 0;

  // Unit direction of the ray through image point (px, py) in pixel units: (0, 0) is the top-left
  // corner of the image, (width, height) the bottom-right; pixel (x, y) has its centre at
  // (x + 0.5, y + 0.5). Row 0 is the top row (Image convention).
  glm::vec3 direction(float px, float py) const { return glm::normalize(unnormalized_direction(px, py)); }
  // The same direction before normalisation (forward + sx right + sy up, length >= 1): for a test of
  // sides (a sign of a dot product) it saves the square root and division.
  glm::vec3 unnormalized_direction(float px, float py) const { return screen_ray(screen_x(px), screen_y(py)); }
  // Its parts: sx depends on px alone and sy on py alone, so that a pass over an image can work them
  // out once per column and row (BufferRays) and get the same directions to the bit.
  float screen_x(float px) const { return (2.0f * px / static_cast<float>(width) - 1.0f) * tan_half_fov_y * aspect; }
  float screen_y(float py) const { return (1.0f - 2.0f * py / static_cast<float>(height)) * tan_half_fov_y; }
  glm::vec3 screen_ray(float sx, float sy) const { return forward + sx * right + sy * up; }
  glm::vec3 pixel_center_direction(int x, int y) const {
    return direction(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
  }
  // The ray of pixel (x, y) of a buffer at 1/scale of the image's resolution (render::GBuffer): through
  // image point ((x + 0.5) scale, (y + 0.5) scale). Scale 1 is pixel_center_direction exactly.
  glm::vec3 buffer_direction(int x, int y, int scale) const { return glm::normalize(buffer_ray(x, y, scale)); }
  glm::vec3 buffer_ray(int x, int y, int scale) const {  // buffer_direction before normalisation
    const float s = static_cast<float>(scale);
    return unnormalized_direction((static_cast<float>(x) + 0.5f) * s, (static_cast<float>(y) + 0.5f) * s);
  }
  // Eye-space depth z_p = (p - e) . E (paper 000 section 4).
  float depth(const glm::vec3& p) const { return glm::dot(p - position, forward); }
};

// buffer_ray and buffer_direction of every pixel of a width x height buffer at `scale`, from the
// screen coordinates of its columns and rows worked out once: the same values, without the two
// divisions per pixel.
struct BufferRays {
  const PinholeCamera* cam = nullptr;
  std::vector<float> sx, sy;  // per column, per row
  BufferRays(const PinholeCamera& c, int width, int height, int scale) : cam(&c), sx(static_cast<std::size_t>(width)), sy(static_cast<std::size_t>(height)) {
    const float s = static_cast<float>(scale);
    for (int x = 0; x < width; ++x) sx[static_cast<std::size_t>(x)] = c.screen_x((static_cast<float>(x) + 0.5f) * s);
    for (int y = 0; y < height; ++y) sy[static_cast<std::size_t>(y)] = c.screen_y((static_cast<float>(y) + 0.5f) * s);
  }
  glm::vec3 ray(int x, int y) const { return cam->screen_ray(sx[static_cast<std::size_t>(x)], sy[static_cast<std::size_t>(y)]); }
  glm::vec3 direction(int x, int y) const { return glm::normalize(ray(x, y)); }
};

// The camera of `scene` at width x height pixels. Throws std::invalid_argument, prefixed with `who`
// and naming the scene and the field, for a size outside 1..16384 per side, fov_y_deg outside
// (0, 179), position equal to target or not finite, or up parallel to the view direction.
PinholeCamera make_pinhole_camera(const scene::Scene& scene, int width, int height, const std::string& who);

// The image size a request gets: 0 means the camera's; when only one of width and height is given,
// the other keeps the camera's aspect ratio. Does not validate (make_pinhole_camera does).
void resolve_resolution(const scene::Camera& camera, int& width, int& height);

}  // namespace softgi::render
