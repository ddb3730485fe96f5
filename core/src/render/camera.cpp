#include "softgi/render/camera.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace softgi::render {

namespace {
constexpr int kMaxDimension = 16384;  // per image side, as everywhere else in softgi
constexpr float kPi = 3.14159265358979323846f;
// |forward x up| below this: the up hint is (numerically) parallel to the view direction.
constexpr float kMinRightLength = 1e-6f;

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
}  // namespace

PinholeCamera make_pinhole_camera(const scene::Scene& scene, int width, int height, const std::string& who) {
  const scene::Camera& c = scene.camera;
  const std::string where = who + ": scene '" + scene.name + "': ";
  if (width < 1 || height < 1 || width > kMaxDimension || height > kMaxDimension)
    throw std::invalid_argument(where + "image size " + std::to_string(width) + "x" + std::to_string(height) +
                                " is outside 1.." + std::to_string(kMaxDimension) + " per side");
  if (!(c.fov_y_deg > 0.0f && c.fov_y_deg < 179.0f)) {
    std::ostringstream os;
    os << where << "camera.fov_y_deg = " << c.fov_y_deg << " is outside (0, 179)";
    throw std::invalid_argument(os.str());
  }
  const glm::vec3 fwd = c.target - c.position;
  if (!finite3(c.position) || !finite3(fwd) || !finite3(c.up) || !(glm::length(fwd) > 0.0f))
    throw std::invalid_argument(where + "camera position equals target or is not finite");
  PinholeCamera cam;
  cam.forward = glm::normalize(fwd);
  const glm::vec3 r = glm::cross(cam.forward, c.up);
  if (!(glm::length(r) > kMinRightLength))
    throw std::invalid_argument(where + "camera.up is parallel to the view direction");
  cam.right = glm::normalize(r);
  cam.up = glm::cross(cam.right, cam.forward);
  cam.position = c.position;
  cam.tan_half_fov_y = std::tan(0.5f * c.fov_y_deg * kPi / 180.0f);
  cam.width = width;
  cam.height = height;
  cam.aspect = static_cast<float>(width) / static_cast<float>(height);
  return cam;
}

void resolve_resolution(const scene::Camera& camera, int& width, int& height) {
  const int w = width, h = height;
  if (w <= 0) width = camera.width;
  if (h <= 0) height = camera.height;
  if (w > 0 && h <= 0 && camera.width > 0)
    height = std::max(1, static_cast<int>(std::lround(static_cast<double>(w) * camera.height / camera.width)));
  if (h > 0 && w <= 0 && camera.height > 0)
    width = std::max(1, static_cast<int>(std::lround(static_cast<double>(h) * camera.width / camera.height)));
}

}  // namespace softgi::render
