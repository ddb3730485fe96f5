// The derivation is in softgi/backends/vulkan/projection.hpp.
#include "softgi/backends/vulkan/projection.hpp"

namespace softgi::backends::vulkan {

glm::mat4 clip_from_world(const render::PinholeCamera& cam, int bw, int bh, int scale, float near_plane) {
  const double kx = static_cast<double>(bw) * scale / cam.width, ky = static_cast<double>(bh) * scale / cam.height;
  const double t = cam.tan_half_fov_y, a = cam.aspect;
  glm::dmat4 view(1.0);  // rows: right, up, forward; translation -R.e, -U.e, -E.e
  const glm::dvec3 R(cam.right), U(cam.up), E(cam.forward), e(cam.position);
  for (int c = 0; c < 3; ++c) {
    view[c][0] = R[c];
    view[c][1] = U[c];
    view[c][2] = E[c];
    view[c][3] = 0.0;
  }
  view[3] = glm::dvec4(-glm::dot(R, e), -glm::dot(U, e), -glm::dot(E, e), 1.0);
  glm::dmat4 proj(0.0);
  proj[0][0] = 1.0 / (kx * t * a);
  proj[2][0] = -(kx - 1.0) / kx;
  proj[1][1] = -1.0 / (ky * t);
  proj[2][1] = -(ky - 1.0) / ky;
  proj[3][2] = near_plane;  // z_c = n: reverse Z, infinite far plane
  proj[2][3] = 1.0;         // w_c = z
  return glm::mat4(proj * view);
}

}  // namespace softgi::backends::vulkan
