// resolve_surface_run (surface_resolve.hpp): embree::triangle_surface and surface_at for a run of
// pixels, written over flat float arrays so that GCC vectorises the loop (gathers for the triangles'
// corners and normals), compiled for AVX-512, AVX2 and the baseline (target_clones). The compile
// options of this file (backends/CMakeLists.txt) keep every version's bits those of the scalar rule:
// no contraction into FMAs, no errno for sqrt (which would keep the loop scalar), no trapping math
// (so that the selects become blends).
#include "surface_resolve.hpp"

#include "../../core/src/render/vertex_image_run.hpp"

#include <cmath>
#include <limits>

namespace softgi::backends::cpu_resolve {

static_assert(sizeof(glm::vec3) == 3 * sizeof(float) && sizeof(glm::vec2) == 2 * sizeof(float) &&
              sizeof(glm::uvec3) == 3 * sizeof(unsigned));

namespace {

// The camera's frame as floats: forward, right, up, eye.
struct Frame {
  float fx, fy, fz, rx, ry, rz, ux, uy, uz, ex, ey, ez;
};

// resolve_surface_run over flat arrays; every pointer a parameter of its own, restrict-qualified,
// which GCC's vectoriser needs to see the loop's loads and stores as independent.
__attribute__((target_clones("avx512f", "avx2", "default"))) void resolve_run(
    const Frame cf, const unsigned* __restrict tri, const float* __restrict pos, const float* __restrict nrm, bool has_normals,
    const std::int32_t* __restrict primitive, const float* __restrict bary, const float* __restrict sx, float sy, int n,
    bool want_view, float* __restrict out_p, float* __restrict out_n, float* __restrict depth) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const float fx = cf.fx, fy = cf.fy, fz = cf.fz, rx = cf.rx, ry = cf.ry, rz = cf.rz;
  const float ux = cf.ux, uy = cf.uy, uz = cf.uz, ex = cf.ex, ey = cf.ey, ez = cf.ez;
  for (int t = 0; t < n; ++t) {
    const int q = 3 * primitive[t];
    const unsigned a = 3 * tri[q], b = 3 * tri[q + 1], c = 3 * tri[q + 2];
    const float u = bary[2 * t], v = bary[2 * t + 1];
    const float w = 1.0f - u - v;
    const float p0x = pos[a], p0y = pos[a + 1], p0z = pos[a + 2];
    const float p1x = pos[b], p1y = pos[b + 1], p1z = pos[b + 2];
    const float p2x = pos[c], p2y = pos[c + 1], p2z = pos[c + 2];
    // surface_at: p = w p0 + u p1 + v p2, summed left to right as glm does.
    const float px = w * p0x + u * p1x + v * p2x, py = w * p0y + u * p1y + v * p2y, pz = w * p0z + u * p1z + v * p2z;
    // triangle_surface: the unit geometric normal, glm::cross (p1 - p0, p2 - p0) over glm::length.
    const float e1x = p1x - p0x, e1y = p1y - p0y, e1z = p1z - p0z;
    const float e2x = p2x - p0x, e2y = p2y - p0y, e2z = p2z - p0z;
    const float cx = e1y * e2z - e2y * e1z, cy = e1z * e2x - e2z * e1x, cz = e1x * e2y - e2x * e1y;
    const float len = std::sqrt(cx * cx + cy * cy + cz * cz);
    const bool unit_ng = len > 0.0f;
    // The camera ray (PinholeCamera::screen_ray) and its unit direction (glm::normalize: times
    // 1 / sqrt). surface_at takes the unit one where it stands in for a degenerate triangle's
    // normal or is written as view_dir, else the ray as it is (only the side it points to matters).
    const float sxt = sx[t];
    const float rrx = fx + sxt * rx + sy * ux, rry = fy + sxt * ry + sy * uy, rrz = fz + sxt * rz + sy * uz;
    const float inv = 1.0f / std::sqrt(rrx * rrx + rry * rry + rrz * rrz);
    const bool unit = want_view | !unit_ng;
    const float dx = unit ? rrx * inv : rrx, dy = unit ? rry * inv : rry, dz = unit ? rrz * inv : rrz;
    // The geometric normal turned towards the viewer (negation as a product with -1: exact).
    float gx = unit_ng ? cx / len : -dx, gy = unit_ng ? cy / len : -dy, gz = unit_ng ? cz / len : -dz;
    const float sg = gx * dx + gy * dy + gz * dz > 0.0f ? -1.0f : 1.0f;
    gx *= sg;
    gy *= sg;
    gz *= sg;
    // The interpolated vertex normal, unit, on the geometric normal's side; kept where its length
    // is above 1e-12 and finite.
    const float n0x = nrm[a], n0y = nrm[a + 1], n0z = nrm[a + 2];
    const float n1x = nrm[b], n1y = nrm[b + 1], n1z = nrm[b + 2];
    const float n2x = nrm[c], n2y = nrm[c + 1], n2z = nrm[c + 2];
    float nx = w * n0x + u * n1x + v * n2x, ny = w * n0y + u * n1y + v * n2y, nz = w * n0z + u * n1z + v * n2z;
    const float nl = std::sqrt(nx * nx + ny * ny + nz * nz);
    const bool use_n = has_normals & (nl > 1e-12f) & (nl < kInf);
    nx = nx / nl;
    ny = ny / nl;
    nz = nz / nl;
    const float sn = nx * gx + ny * gy + nz * gz < 0.0f ? -1.0f : 1.0f;
    out_p[3 * t] = px;
    out_p[3 * t + 1] = py;
    out_p[3 * t + 2] = pz;
    out_n[3 * t] = use_n ? nx * sn : gx;
    out_n[3 * t + 1] = use_n ? ny * sn : gy;
    out_n[3 * t + 2] = use_n ? nz * sn : gz;
    // PinholeCamera::depth: (p - eye) . forward.
    depth[t] = (px - ex) * fx + (py - ey) * fy + (pz - ez) * fz;
  }
}

}  // namespace

void resolve_surface_run(const render::PinholeCamera& cam, const ObjectArrays& obj, const std::int32_t* primitive,
                         const glm::vec2* barycentric, const float* sx, float sy, int n, glm::vec3* position,
                         glm::vec3* normal, float* depth, glm::vec3* view_dir) {
  if (n <= 0) return;
  const Frame cf{cam.forward.x, cam.forward.y, cam.forward.z, cam.right.x, cam.right.y, cam.right.z,
                 cam.up.x,      cam.up.y,      cam.up.z,      cam.position.x, cam.position.y, cam.position.z};
  const float* pos = &obj.positions[0].x;
  // Without vertex normals the loop reads the positions in their place and ignores what it read.
  const float* nrm = obj.normals ? &obj.normals[0].x : pos;
  resolve_run(cf, &obj.triangles[0].x, pos, nrm, obj.normals != nullptr, primitive, &barycentric[0].x, sx, sy, n,
              view_dir != nullptr, &position[0].x, &normal[0].x, depth);
  if (!view_dir) return;
  // view_dir apart from the loop above (a store under a condition would keep it scalar): the unit
  // ray that loop takes wherever view_dir is written (the same expression), turned round.
  render::detail::ray_directions(cam.forward, cam.right, cam.up, sx, sy, n, view_dir);
  float* v = &view_dir[0].x;
  for (int k = 0; k < 3 * n; ++k) v[k] = -v[k];
}

}  // namespace softgi::backends::cpu_resolve
