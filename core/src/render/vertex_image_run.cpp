// interpolate_run and ray_directions (vertex_image_run.hpp) over flat float arrays, every pointer a
// restrict parameter of its own, so that GCC vectorises the loops (gathers for the triangles'
// vertex values), compiled for AVX-512, AVX2 and the baseline (target_clones). No contraction into
// FMAs in this file (core/CMakeLists.txt): every version computes the bits of the per-pixel
// expressions, (1 - b1 - b2) * v0 + b1 * v1 + b2 * v2 summed left to right as glm evaluates it, and
// glm::normalize's v * (1 / sqrt(v . v)).
#include "vertex_image_run.hpp"

#include <cmath>

namespace softgi::render::detail {

namespace {

static_assert(sizeof(glm::vec3) == 3 * sizeof(float) && sizeof(glm::vec2) == 2 * sizeof(float) &&
              sizeof(glm::uvec3) == 3 * sizeof(unsigned));

__attribute__((target_clones("avx512f", "avx2", "default"))) bool run(
    const unsigned* __restrict tri, int triangles, const float* __restrict val, const std::int32_t* __restrict primitive,
    const float* __restrict bary, int n, const float* __restrict albedo, bool times_uniform, float ur, float ug, float ub,
    float* __restrict out) {
  int bad = 0;
  for (int t = 0; t < n; ++t) bad |= (primitive[t] < 0) | (primitive[t] >= triangles);
  if (bad) return false;
  // Times 1 where nothing multiplies: exact.
  if (!times_uniform) ur = ug = ub = 1.0f;
  for (int t = 0; t < n; ++t) {
    const int q = 3 * primitive[t];
    const unsigned a = 3 * tri[q], b = 3 * tri[q + 1], c = 3 * tri[q + 2];
    const float u = bary[2 * t], v = bary[2 * t + 1];
    const float w = 1.0f - u - v;
    out[3 * t] = (w * val[a] + u * val[b] + v * val[c]) * ur;
    out[3 * t + 1] = (w * val[a + 1] + u * val[b + 1] + v * val[c + 1]) * ug;
    out[3 * t + 2] = (w * val[a + 2] + u * val[b + 2] + v * val[c + 2]) * ub;
  }
  if (albedo) {
    for (int k = 0; k < 3 * n; ++k) out[k] = out[k] * albedo[k];
  }
  return true;
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void directions(
    float fx, float fy, float fz, float rx, float ry, float rz, float ux, float uy, float uz, const float* __restrict sx, float sy,
    int n, float* __restrict out) {
  for (int t = 0; t < n; ++t) {
    // PinholeCamera::screen_ray: (forward + sx right) + sy up.
    const float x = fx + sx[t] * rx + sy * ux, y = fy + sx[t] * ry + sy * uy, z = fz + sx[t] * rz + sy * uz;
    const float inv = 1.0f / std::sqrt(x * x + y * y + z * z);
    out[3 * t] = x * inv;
    out[3 * t + 1] = y * inv;
    out[3 * t + 2] = z * inv;
  }
}

}  // namespace

void ray_directions(const glm::vec3& forward, const glm::vec3& right, const glm::vec3& up, const float* sx, float sy, int n,
                    glm::vec3* out) {
  if (n <= 0) return;
  directions(forward.x, forward.y, forward.z, right.x, right.y, right.z, up.x, up.y, up.z, sx, sy, n, &out[0].x);
}

bool interpolate_run(const glm::uvec3* tri, int triangles, const glm::vec3* values, const std::int32_t* primitive,
                     const glm::vec2* barycentric, int n, const glm::vec3* albedo, bool times_uniform,
                     const glm::vec3& uniform, glm::vec3* out) {
  if (n <= 0) return true;
  return run(&tri[0].x, triangles, &values[0].x, primitive, &barycentric[0].x, n, albedo ? &albedo[0].x : nullptr,
             times_uniform, uniform.x, uniform.y, uniform.z, &out[0].x);
}

}  // namespace softgi::render::detail
