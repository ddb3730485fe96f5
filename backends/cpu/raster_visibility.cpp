// Primary visibility by rasterisation (raster_visibility.hpp).
//
// Every sample ray leaves the eye e along d(x, y) = F + sx(x) R + sy(y) U (the pinhole camera of
// softgi/render/camera.hpp before normalisation: F forward, R right, U up, so d . F = 1 and the ray
// parameter of a hit is its eye depth). With a_k = v_k - e, the ray meets the triangle's plane at
// depth t = det / (d . ng), det = a0 . ng, ng = (a1 - a0) x (a2 - a0), and the meeting point has the
// barycentrics b_k = E_k / (E_0 + E_1 + E_2) of the scalar triple products
//     E_0 = d . (a1 x a2),  E_1 = d . (a2 x a0),  E_2 = d . (a0 x a1)
// (their sum is d . ng). The ray meets the triangle in front of the eye exactly when all three E_k
// and d . ng have the sign of det. Every one of them is linear in (sx, sy): a triangle is set up once
// (twelve dot products) and each sample then costs four multiply-adds and a multiply, the same
// arithmetic whichever way the triangle faces (surfaces are two-sided), without a perspective
// division, and with no special case for triangles that reach behind the eye (only their screen
// bounds, which merely cull, are clipped). The nearest hit is the largest inverse depth
// (d . ng) / det. The samples are grouped in 32 x 32 tiles; each triangle is binned to the tiles its
// bounds overlap, and each tile, on one thread, tests its triangles against all its samples.
//
// Watertight: two triangles that share an edge compute its E from the same two vertices in opposite
// (or equal) order (SOFTGI_EDGE_NORMAL), so their values are exact negations (or equal) of each other at
// every sample, and a sample on the edge (E = 0 exactly) is covered by both; no sample falls
// through a crack. Equal depths keep the triangle that comes first (object, then triangle index),
// so the result does not depend on the number of threads.
#include "raster_visibility.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace softgi::backends::cpu_raster {

namespace {

using glm::vec3;
// Tile edge in samples: a tile's inverse depths and triangle ids (8 KiB) stay in L1 while every
// triangle that overlaps it is tested; 32 x 32 gives 1024 tiles at 1024 x 1024 for two cores.
constexpr int kTile = 32;
// Triangles per set-up task, at least.
constexpr std::size_t kChunk = 4096;

// A triangle set up for its tiles: the sign-normalised linear forms E_k = (ef + sy eu) + sx er and
// S = d . ng = (sf + sy su) + sx sr, and 1 / |det|.
struct Tri {
  float ef[3], eu[3], er[3];
  float sf, su, sr;
  float inv_det;
  // Conservative bounds of its projection on the image plane, in the camera's (sx, sy) units,
  // whatever the buffer's grid; live: it can meet a sample ray (in front, not degenerate, in view).
  float u0, u1, v0, v1;
  bool live;
  int x0, y0, x1, y1;  // samples [x0, x1) x [y0, y1) of this buffer that it can cover; empty: culled
  int object, prim;
};

// A posed vertex seen from the camera: z its eye depth (p - e) . F, and where z > 0, (u, v) its
// projection on the image plane (sx, sy units). Computed once per vertex, shared by its triangles.
struct Projected {
  float u, v, z;
};

// Working memory kept from frame to frame: a frame's set-up and tile lists are megabytes, which a
// frame should not pay page faults for each time. A frame that finds it in use by another
// (concurrent frames) allocates its own.
struct Scratch {
  // The set-up depends on the camera and the posed geometry only, not on the buffer's grid: a
  // frame's receiver buffer reuses its display buffer's (frame: FrameContext::id of the frame that
  // made it, 0 for none).
  std::uint64_t frame = 0;
  render::PinholeCamera camera;
  float ue = 0.0f, ve = 0.0f;  // the image-plane extent the set-up culled against
  std::vector<int> objects;
  std::vector<std::size_t> first;
  std::vector<Tri> tris;
  std::vector<std::uint32_t> count, list;
  std::vector<std::uint64_t> start;
  std::vector<float> sx, sy;
  std::vector<Projected> proj;
  std::size_t bytes() const {
    return tris.capacity() * sizeof(Tri) + proj.capacity() * sizeof(Projected) +
           (objects.capacity() * sizeof(int)) + first.capacity() * sizeof(std::size_t) +
           (count.capacity() + list.capacity()) * sizeof(std::uint32_t) + start.capacity() * sizeof(std::uint64_t) +
           (sx.capacity() + sy.capacity()) * sizeof(float);
  }
};
std::mutex& scratch_mutex() {
  static std::mutex m;
  return m;
}
Scratch& kept_scratch() {
  static Scratch s;
  return s;
}

// The buffer coordinate x (sample x sits at sx(x)) of camera-plane coordinate u = sx, and likewise
// for y: the inverses of PinholeCamera::direction's maps, for the conservative bounds only.
struct Inverse {
  float ax, bx, ay, by;
  float x(float u) const { return u * ax + bx; }
  float y(float v) const { return v * ay + by; }
};

Projected project(const render::PinholeCamera& cam, const vec3& p) {
  const vec3 a = p - cam.position;
  const float z = glm::dot(a, cam.forward), r = 1.0f / z;
  return {glm::dot(a, cam.right) * r, glm::dot(a, cam.up) * r, z};
}

// The part of a triangle's set-up that does not branch: the geometric normal ng, det = a0 . ng, the
// edge normals and from them the sign-normalised linear forms, with the sums whose finiteness the
// set-up checks. Computed for a block of triangles at a time (edge_block, vectorised across them);
// edge_forms_reference computes them one triangle at a time with glm, the same float operations in
// the same order, so the same bits.
struct EdgeForms {
  float ef[3], eu[3], er[3];
  float sf, su, sr;
  float det, inv_det, ng_sum, n_sum;
};

// Triangles per edge_block call.
constexpr int kBlock = 32;
// Block inputs: p[k * 3 + c][i], coordinate c of vertex k of triangle i.
struct EdgeBlockIn {
  alignas(64) float p[9][kBlock];
};
// Block outputs, one array per field.
struct EdgeBlockOut {
  alignas(64) float ef[3][kBlock], eu[3][kBlock], er[3][kBlock];
  alignas(64) float sf[kBlock], su[kBlock], sr[kBlock], det[kBlock], inv_det[kBlock], ng_sum[kBlock], n_sum[kBlock];
};

// a_i x a_j (a = p - e) for the edge from p_i to p_j, as a_lo x (p_hi - p_lo) with (lo, hi) the two
// ends in lexicographic order: the edge vector is taken between the vertices themselves, so the
// result carries rounding of the order of the float spacing at the eye distance, not of its square
// (a_i x a_j directly cancels catastrophically for a small triangle far away); and an edge shared
// by two triangles is computed from the same operands in both, so their values are exact negations
// of each other (or equal), which keeps the test watertight.
// The order is picked by selects (vectorised; no branch that goes either way as often), which move
// bits, so lo and hi are exactly the vertices; the sign of the swap multiplies the result (exact).
// glm's cross (x.y y.z - y.y x.z, x.z y.x - y.z x.x, x.x y.y - y.x x.y) written out.
inline void edge_normal(float ex, float ey, float ez, float pix, float piy, float piz, float pjx, float pjy, float pjz, float& nx,
                        float& ny, float& nz) {
  const bool swap = (pjx < pix) | ((pjx == pix) & ((pjy < piy) | ((pjy == piy) & (pjz < piz))));
  const float lox = swap ? pjx : pix, loy = swap ? pjy : piy, loz = swap ? pjz : piz;
  const float hix = swap ? pix : pjx, hiy = swap ? piy : pjy, hiz = swap ? piz : pjz;
  const float ax = lox - ex, ay = loy - ey, az = loz - ez;
  const float bx = hix - lox, by = hiy - loy, bz = hiz - loz;
  const float sg = swap ? -1.0f : 1.0f;
  nx = (ay * bz - by * az) * sg;
  ny = (az * bx - bz * ax) * sg;
  nz = (ax * by - bx * ay) * sg;
}

// The edge forms of a block of n triangles, one lane per triangle; glm's dot ((x + y) + z) written
// out. Compiled for AVX-512 and AVX2 as well (no contraction into FMA, backends/CMakeLists.txt: the
// same bits in every version, and those of edge_forms_reference).
__attribute__((target_clones("avx512f", "avx2", "default"))) void edge_block(const render::PinholeCamera& cam,
                                                                    const EdgeBlockIn& __restrict in, int n,
                                                                    EdgeBlockOut& __restrict out) {
  const float ex = cam.position.x, ey = cam.position.y, ez = cam.position.z;
  const float fx = cam.forward.x, fy = cam.forward.y, fz = cam.forward.z;
  const float upx = cam.up.x, upy = cam.up.y, upz = cam.up.z;
  const float rx = cam.right.x, ry = cam.right.y, rz = cam.right.z;
  for (int i = 0; i < n; ++i) {
    const float p0x = in.p[0][i], p0y = in.p[1][i], p0z = in.p[2][i], p1x = in.p[3][i], p1y = in.p[4][i], p1z = in.p[5][i];
    const float p2x = in.p[6][i], p2y = in.p[7][i], p2z = in.p[8][i];
    const float ux = p1x - p0x, uy = p1y - p0y, uz = p1z - p0z, vx = p2x - p0x, vy = p2y - p0y, vz = p2z - p0z;
    const float ngx = uy * vz - vy * uz, ngy = uz * vx - vz * ux, ngz = ux * vy - vx * uy;
    const float det = ((p0x - ex) * ngx + (p0y - ey) * ngy) + (p0z - ez) * ngz;
    float nx[3], ny[3], nz[3];
    edge_normal(ex, ey, ez, p1x, p1y, p1z, p2x, p2y, p2z, nx[0], ny[0], nz[0]);
    edge_normal(ex, ey, ez, p2x, p2y, p2z, p0x, p0y, p0z, nx[1], ny[1], nz[1]);
    edge_normal(ex, ey, ez, p0x, p0y, p0z, p1x, p1y, p1z, nx[2], ny[2], nz[2]);
    const float sg = det > 0.0f ? 1.0f : -1.0f;
    for (int k = 0; k < 3; ++k) {
      out.ef[k][i] = sg * ((nx[k] * fx + ny[k] * fy) + nz[k] * fz);
      out.eu[k][i] = sg * ((nx[k] * upx + ny[k] * upy) + nz[k] * upz);
      out.er[k][i] = sg * ((nx[k] * rx + ny[k] * ry) + nz[k] * rz);
    }
    out.sf[i] = sg * ((ngx * fx + ngy * fy) + ngz * fz);
    out.su[i] = sg * ((ngx * upx + ngy * upy) + ngz * upz);
    out.sr[i] = sg * ((ngx * rx + ngy * ry) + ngz * rz);
    out.det[i] = det;
    out.inv_det[i] = 1.0f / std::fabs(det);
    out.ng_sum[i] = (ngx + ngy) + ngz;
    out.n_sum[i] = ((((((((nx[0] + ny[0]) + nz[0]) + nx[1]) + ny[1]) + nz[1]) + nx[2]) + ny[2]) + nz[2]);
  }
}

// The edge forms by glm's cross and dot, one triangle at a time: the reference the block kernel is
// tested against (edge_form_differences).
vec3 edge_normal_reference(const vec3& e, const vec3& pi, const vec3& pj) {
  const bool swap = (pj.x < pi.x) || (pj.x == pi.x && (pj.y < pi.y || (pj.y == pi.y && pj.z < pi.z)));
  const vec3 lo = swap ? pj : pi, hi = swap ? pi : pj;
  return glm::cross(lo - e, hi - lo) * (swap ? -1.0f : 1.0f);
}

EdgeForms edge_forms_reference(const render::PinholeCamera& cam, const vec3& p0, const vec3& p1, const vec3& p2) {
  const vec3& e = cam.position;
  EdgeForms f;
  const vec3 ng = glm::cross(p1 - p0, p2 - p0);
  f.det = glm::dot(p0 - e, ng);
  const vec3 n[3] = {edge_normal_reference(e, p1, p2), edge_normal_reference(e, p2, p0), edge_normal_reference(e, p0, p1)};
  f.ng_sum = ng.x + ng.y + ng.z;
  f.n_sum = n[0].x + n[0].y + n[0].z + n[1].x + n[1].y + n[1].z + n[2].x + n[2].y + n[2].z;
  const float sg = f.det > 0.0f ? 1.0f : -1.0f;
  for (int k = 0; k < 3; ++k) {
    f.ef[k] = sg * glm::dot(n[k], cam.forward);
    f.eu[k] = sg * glm::dot(n[k], cam.up);
    f.er[k] = sg * glm::dot(n[k], cam.right);
  }
  f.sf = sg * glm::dot(ng, cam.forward);
  f.su = sg * glm::dot(ng, cam.up);
  f.sr = sg * glm::dot(ng, cam.right);
  f.inv_det = 1.0f / std::fabs(f.det);
  return f;
}

EdgeForms block_forms(const EdgeBlockOut& b, int i) {
  EdgeForms f;
  for (int k = 0; k < 3; ++k) {
    f.ef[k] = b.ef[k][i];
    f.eu[k] = b.eu[k][i];
    f.er[k] = b.er[k][i];
  }
  f.sf = b.sf[i];
  f.su = b.su[i];
  f.sr = b.sr[i];
  f.det = b.det[i];
  f.inv_det = b.inv_det[i];
  f.ng_sum = b.ng_sum[i];
  f.n_sum = b.n_sum[i];
  return f;
}

// Sets t up for any grid of sample rays of `cam` from its edge forms; false when its arithmetic
// overflows float (t is then not live). The bounds of the triangle's projection on the image plane
// cull the triangles off screen or behind the eye.
bool set_up(const render::PinholeCamera& cam, float ue, float ve, const vec3& p0, const vec3& p1, const vec3& p2,
            const Projected& q0, const Projected& q1, const Projected& q2, const EdgeForms& f, Tri& t) {
  t.live = false;
  const vec3& e = cam.position;
  const float z[3] = {q0.z, q1.z, q2.z};
  const float zmax = std::max(z[0], std::max(z[1], z[2]));
  if (!std::isfinite(zmax)) return false;  // coordinates relative to the eye overflowed
  if (zmax <= 0.0f) return true;           // wholly behind the eye
  // The projection of the triangle's part in front of the eye, clipped at zc, a millionth of its
  // farthest depth: the bounds leave out the sliver nearer the eye's plane than that, which a sample
  // ray meets only where the triangle passes within a millionth of its own depth of the eye.
  const float zc = std::max(zmax * 1e-6f, std::numeric_limits<float>::min());
  float umin = std::numeric_limits<float>::infinity(), umax = -umin, vmin = umin, vmax = -umin;
  auto add = [&](const vec3& p, float pz) {
    const float r = 1.0f / pz;
    const float u = glm::dot(p, cam.right) * r, v = glm::dot(p, cam.up) * r;
    umin = std::min(umin, u);
    umax = std::max(umax, u);
    vmin = std::min(vmin, v);
    vmax = std::max(vmax, v);
  };
  if (z[0] >= zc && z[1] >= zc && z[2] >= zc) {
    umin = std::min(q0.u, std::min(q1.u, q2.u));
    umax = std::max(q0.u, std::max(q1.u, q2.u));
    vmin = std::min(q0.v, std::min(q1.v, q2.v));
    vmax = std::max(q0.v, std::max(q1.v, q2.v));
  } else {
    const vec3 a[3] = {p0 - e, p1 - e, p2 - e};
    for (int k = 0; k < 3; ++k) {
      const int j = k == 2 ? 0 : k + 1;
      if (z[k] >= zc) add(a[k], z[k]);
      if ((z[k] < zc) != (z[j] < zc)) {  // the edge crosses the clip plane
        const float s = (zc - z[k]) / (z[j] - z[k]);
        add(a[k] + s * (a[j] - a[k]), zc);
      }
    }
  }
  t.u0 = umin;
  t.u1 = umax;
  t.v0 = vmin;
  t.v1 = vmax;
  // Every sample ray of the grids this set-up serves has |sx| <= ue and |sy| <= ve (Extent). NaN
  // bounds keep the triangle (the whole buffer is tested).
  const bool off_screen = umax < -ue || umin > ue || vmax < -ve || vmin > ve;
  // Off screen; a triangle whose bounds overflowed still has its arithmetic checked below.
  if (off_screen && std::isfinite(umin + umax + vmin + vmax)) return true;
  if (!std::isfinite(f.det) || !std::isfinite(f.ng_sum) || !std::isfinite(f.n_sum)) return false;
  // det = 0: degenerate, or the eye lies in the triangle's plane; no ray meets it at a point.
  if (f.det == 0.0f || off_screen) return true;
  // The forms were multiplied by the sign of det, which is exact, so shared edges stay exact
  // negations (watertight).
  for (int k = 0; k < 3; ++k) {
    t.ef[k] = f.ef[k];
    t.eu[k] = f.eu[k];
    t.er[k] = f.er[k];
  }
  t.sf = f.sf;
  t.su = f.su;
  t.sr = f.sr;
  t.inv_det = f.inv_det;
  t.live = std::isfinite(t.inv_det);  // |det| below float's range: no sample can resolve it
  return true;
}

// The samples [x0, x1) x [y0, y1) of a buffer (inv: its grid) that t's projection can cover. One
// sample of margin on either side for the rounding of the bounds (the coverage test itself is
// exact); clamped in float first (NaN keeps the whole buffer), then truncated: trunc(v) - 1 <=
// floor(v) and trunc(v) + 2 >= ceil(v) + 1 for v >= -1.
void grid_bounds(const Inverse& inv, int W, int H, Tri& t) {
  t.x0 = t.x1 = t.y0 = t.y1 = 0;
  if (!t.live) return;
  const float fw = static_cast<float>(W), fh = static_cast<float>(H);
  const auto lo = [](float v, float hi) { return static_cast<int>(v >= -1.0f ? std::min(v, hi) : -1.0f) - 1; };
  const auto up = [](float v, float hi) { return static_cast<int>(v <= hi ? std::max(v, -1.0f) : hi) + 2; };
  // x grows with u; y falls as v grows (row 0 at the top).
  t.x0 = std::max(0, lo(inv.x(t.u0), fw));
  t.x1 = std::min(W, up(inv.x(t.u1), fw));
  t.y0 = std::max(0, lo(inv.y(t.v1), fh));
  t.y1 = std::min(H, up(inv.y(t.v0), fh));
  if (t.x0 >= t.x1 || t.y0 >= t.y1) t.x1 = t.x0;
}

// Tests the triangles of one tile (its top-left sample (tx, ty)) against its samples and keeps the
// nearest. Compiled for AVX-512 and AVX2 as well, chosen at load time; every version computes the
// same values (this file is compiled with -ffp-contract=off: backends/CMakeLists.txt). A row is
// tested in spans of kSpan samples, only those that the triangle's bounds reach: no sample outside
// [x0, x1) is covered (grid_bounds), so skipping the others changes nothing, and a triangle within
// one span costs one vector per row instead of the tile's width.
constexpr int kSpan = 16;
static_assert(kTile % kSpan == 0);
__attribute__((target_clones("avx512f", "avx2", "default"))) void raster_tile(const Tri* __restrict tris, const std::uint32_t* list,
                                                                     std::size_t count, const float* __restrict sx,
                                                                     const float* __restrict sy, int tx, int ty, int rows,
                                                                     float* __restrict wbuf, std::int32_t* __restrict ibuf) {
  for (std::size_t k = 0; k < count; ++k) {
    const std::int32_t id = static_cast<std::int32_t>(list[k]);
    const Tri& t = tris[id];
    const int ya = std::max(t.y0 - ty, 0), yb = std::min(t.y1 - ty, rows);
    const int xa = std::max(t.x0 - tx, 0) / kSpan * kSpan, xb = std::min(t.x1 - tx, kTile);
    const float er0 = t.er[0], er1 = t.er[1], er2 = t.er[2], sr = t.sr, inv = t.inv_det;
    for (int y = ya; y < yb; ++y) {
      const float s_y = sy[y];
      const float r0 = t.ef[0] + s_y * t.eu[0], r1 = t.ef[1] + s_y * t.eu[1], r2 = t.ef[2] + s_y * t.eu[2];
      const float rs = t.sf + s_y * t.su;
      float* __restrict w = wbuf + y * kTile;
      std::int32_t* __restrict ids = ibuf + y * kTile;
      for (int x0 = xa; x0 < xb; x0 += kSpan)
        for (int x = x0; x < x0 + kSpan; ++x) {
          const float s_x = sx[x];
          const float e0 = r0 + s_x * er0, e1 = r1 + s_x * er1, e2 = r2 + s_x * er2;
          const float wv = (rs + s_x * sr) * inv;  // inverse depth; > 0 only in front of the eye
          // Nearer, or as near and first in (object, triangle) order.
          const bool take = (e0 >= 0.0f) & (e1 >= 0.0f) & (e2 >= 0.0f) & ((wv > w[x]) | ((wv == w[x]) & (id < ids[x])));
          w[x] = take ? wv : w[x];
          ids[x] = take ? id : ids[x];
        }
    }
  }
}

bool same_camera(const render::PinholeCamera& a, const render::PinholeCamera& b) {
  return a.position == b.position && a.forward == b.forward && a.right == b.right && a.up == b.up &&
         a.tan_half_fov_y == b.tan_half_fov_y && a.aspect == b.aspect && a.width == b.width && a.height == b.height;
}

// Validates the posed objects and sets every triangle up into sc (see Scratch) for sample rays with
// |sx| <= ue, |sy| <= ve: throws as rasterise_visibility says.
void set_up_frame(const render::PinholeCamera& cam, float ue, float ve, const scene::PosedScene& posed, const char* who,
                  Scratch& sc) {
  const std::string prefix = std::string(who) + ": mesh '";
  // Validation first, in order, so that the error names the first bad vertex or index. Triangles
  // are numbered across the objects: object k's triangle t is first[k] + t.
  sc.objects.clear();
  sc.first.clear();
  std::vector<std::size_t> vfirst;  // object k's vertex v is vfirst[k] + v
  std::size_t total = 0, vertices = 0;
  for (std::size_t oi = 0; oi < posed.objects.size(); ++oi) {
    const scene::PosedObject& o = posed.objects[oi];
    if (!o.source || o.source->triangles.empty() || o.positions.empty()) continue;
    for (std::size_t v = 0; v < o.positions.size(); ++v) {
      const vec3& p = o.positions[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw std::invalid_argument(prefix + o.source->name + "': posed vertex " + std::to_string(v) + " is not finite");
    }
    const auto& tris = o.source->triangles;
    for (std::size_t t = 0; t < tris.size(); ++t)
      for (int k = 0; k < 3; ++k)
        if (tris[t][k] >= o.positions.size())
          throw std::invalid_argument(prefix + o.source->name + "': triangle " + std::to_string(t) + " has vertex index " +
                                      std::to_string(tris[t][k]) + " >= " + std::to_string(o.positions.size()));
    sc.objects.push_back(static_cast<int>(oi));
    sc.first.push_back(total);
    vfirst.push_back(vertices);
    total += tris.size();
    vertices += o.positions.size();
  }
  if (total > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw std::invalid_argument(std::string(who) + ": " + std::to_string(total) + " triangles; the rasteriser takes at most 2^31 - 1");

  std::vector<Projected>& proj = sc.proj;
  proj.resize(vertices);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, sc.objects.size(), 1), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      const auto& pos = posed.objects[static_cast<std::size_t>(sc.objects[k])].positions;
      Projected* out = proj.data() + vfirst[k];
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pos.size(), 8192), [&](const tbb::blocked_range<std::size_t>& vr) {
        for (std::size_t v = vr.begin(); v != vr.end(); ++v) out[v] = project(cam, pos[v]);
      });
    }
  });

  sc.tris.resize(total);
  // The first triangle whose set-up overflowed float, for the error.
  std::atomic<std::size_t> first_large{std::numeric_limits<std::size_t>::max()};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, total, kChunk), [&](const tbb::blocked_range<std::size_t>& r) {
    std::size_t k = static_cast<std::size_t>(std::upper_bound(sc.first.begin(), sc.first.end(), r.begin()) - sc.first.begin()) - 1;
    EdgeBlockIn in;
    EdgeBlockOut forms;
    std::array<glm::uvec3, kBlock> corners;
    std::array<std::size_t, kBlock> object;
    for (std::size_t g0 = r.begin(); g0 < r.end(); g0 += kBlock) {
      const int n = static_cast<int>(std::min<std::size_t>(kBlock, r.end() - g0));
      for (int i = 0; i < n; ++i) {
        const std::size_t g = g0 + static_cast<std::size_t>(i);
        while (k + 1 < sc.first.size() && g >= sc.first[k + 1]) ++k;
        const scene::PosedObject& o = posed.objects[static_cast<std::size_t>(sc.objects[k])];
        object[i] = k;
        corners[i] = o.source->triangles[g - sc.first[k]];
        for (int v = 0; v < 3; ++v) {
          const vec3& p = o.positions[corners[i][v]];
          in.p[3 * v][i] = p.x;
          in.p[3 * v + 1][i] = p.y;
          in.p[3 * v + 2][i] = p.z;
        }
      }
      edge_block(cam, in, n, forms);
      for (int i = 0; i < n; ++i) {
        const std::size_t g = g0 + static_cast<std::size_t>(i), ok = object[i];
        const scene::PosedObject& o = posed.objects[static_cast<std::size_t>(sc.objects[ok])];
        const glm::uvec3 tri = corners[i];
        Tri& out = sc.tris[g];
        out.object = sc.objects[ok];
        out.prim = static_cast<int>(g - sc.first[ok]);
        const Projected* q = proj.data() + vfirst[ok];
        if (!set_up(cam, ue, ve, o.positions[tri.x], o.positions[tri.y], o.positions[tri.z], q[tri.x], q[tri.y], q[tri.z],
                    block_forms(forms, i), out)) {
          std::size_t cur = first_large.load();
          while (g < cur && !first_large.compare_exchange_weak(cur, g)) {
          }
        }
      }
    }
  });
  if (const std::size_t g = first_large.load(); g < total) {
    const Tri& t = sc.tris[g];
    throw std::invalid_argument(prefix + posed.objects[static_cast<std::size_t>(t.object)].source->name + "': triangle " +
                                std::to_string(t.prim) +
                                " is too large for float arithmetic (its vertices, relative to the camera, reach about "
                                "1e19 or more)");
  }
}

}  // namespace

std::size_t edge_form_differences(const render::PinholeCamera& cam, const scene::PosedScene& posed) {
  std::size_t differ = 0;
  EdgeBlockIn in;
  EdgeBlockOut forms;
  std::vector<std::array<vec3, 3>> tris;
  for (const scene::PosedObject& o : posed.objects) {
    if (!o.source) continue;
    for (const glm::uvec3& t : o.source->triangles)
      if (t.x < o.positions.size() && t.y < o.positions.size() && t.z < o.positions.size())
        tris.push_back({o.positions[t.x], o.positions[t.y], o.positions[t.z]});
  }
  const auto bits = [](const EdgeForms& f) { return std::bit_cast<std::array<std::uint32_t, sizeof(EdgeForms) / 4>>(f); };
  for (std::size_t g0 = 0; g0 < tris.size(); g0 += kBlock) {
    const int n = static_cast<int>(std::min<std::size_t>(kBlock, tris.size() - g0));
    for (int i = 0; i < n; ++i)
      for (int v = 0; v < 3; ++v)
        for (int c = 0; c < 3; ++c) in.p[3 * v + c][i] = tris[g0 + static_cast<std::size_t>(i)][v][c];
    edge_block(cam, in, n, forms);
    for (int i = 0; i < n; ++i) {
      const auto& t = tris[g0 + static_cast<std::size_t>(i)];
      differ += bits(block_forms(forms, i)) != bits(edge_forms_reference(cam, t[0], t[1], t[2]));
    }
  }
  return differ;
}

void rasterise_visibility(const render::PinholeCamera& cam, const scene::PosedScene& posed, const char* who,
                          render::GBuffer& gb, RasterStats& stats, std::uint64_t frame) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const int W = gb.width, H = gb.height;
  const float fs = static_cast<float>(gb.scale);

  std::unique_lock<std::mutex> lock(scratch_mutex(), std::try_to_lock);
  Scratch own;
  Scratch& sc = lock.owns_lock() ? kept_scratch() : own;

  // Sample ray coordinates, computed as PinholeCamera::direction does (so the rays are the ones the
  // ray tracer casts); sx padded to whole tiles.
  const int tiles_x = (W + kTile - 1) / kTile, tiles_y = (H + kTile - 1) / kTile;
  std::vector<float>& sx = sc.sx;
  std::vector<float>& sy = sc.sy;
  sx.resize(static_cast<std::size_t>(tiles_x) * kTile);
  sy.resize(static_cast<std::size_t>(tiles_y) * kTile);
  const float cw = static_cast<float>(cam.width), ch = static_cast<float>(cam.height);
  for (std::size_t x = 0; x < sx.size(); ++x)
    sx[x] = (2.0f * ((static_cast<float>(x) + 0.5f) * fs) / cw - 1.0f) * cam.tan_half_fov_y * cam.aspect;
  for (std::size_t y = 0; y < sy.size(); ++y)
    sy[y] = (1.0f - 2.0f * ((static_cast<float>(y) + 0.5f) * fs) / ch) * cam.tan_half_fov_y;
  // x = (px / s - 0.5) with px = (sx / (tan aspect) + 1) w / 2; y likewise with sy = (1 - 2 py / h) tan.
  const Inverse inv{cw / (2.0f * fs * cam.tan_half_fov_y * cam.aspect), cw / (2.0f * fs) - 0.5f,
                    -ch / (2.0f * fs * cam.tan_half_fov_y), ch / (2.0f * fs) - 0.5f};

  // The image-plane extent the set-up culls against: this grid's samples (a receiver grid's last
  // samples can lie beyond the display image when its size is not a multiple of the scale), and at
  // least the display image, so that the receiver buffer usually finds the display buffer's set-up
  // wide enough; a thousandth of margin for the rounding of the bounds.
  const float ue = std::max({std::fabs(sx[0]), std::fabs(sx[static_cast<std::size_t>(W) - 1]),
                             cam.tan_half_fov_y * cam.aspect}) * 1.001f;
  const float ve = std::max({std::fabs(sy[0]), std::fabs(sy[static_cast<std::size_t>(H) - 1]), cam.tan_half_fov_y}) * 1.001f;
  stats.reused = frame != 0 && sc.frame == frame && same_camera(sc.camera, cam) && ue <= sc.ue && ve <= sc.ve;
  if (!stats.reused) {
    sc.frame = 0;  // invalid until the set-up is complete
    set_up_frame(cam, ue, ve, posed, who, sc);
    sc.frame = frame;
    sc.camera = cam;
    sc.ue = ue;
    sc.ve = ve;
  }
  const std::size_t total = sc.tris.size();
  std::vector<Tri>& tris = sc.tris;

  // Binning by counting, over at most kMaxChunks fixed ranges of triangles: each range counts its
  // triangles into the tiles their bounds on this grid overlap (a count array per range, so no two
  // threads write one counter), the counts become list offsets per (tile, range), and a second
  // sweep scatters the triangle indices. Each tile's list is in triangle order.
  constexpr std::size_t kMaxChunks = 64;
  const std::size_t chunk = std::max(kChunk, (total + kMaxChunks - 1) / kMaxChunks);
  const std::size_t chunks = (total + chunk - 1) / chunk;
  const std::size_t tiles = static_cast<std::size_t>(tiles_x) * tiles_y;
  std::vector<std::uint32_t>& count = sc.count;
  count.assign(chunks * tiles, 0u);
  auto each_tile = [&](const Tri& t, auto&& f) {
    for (int by = t.y0 / kTile; by <= (t.y1 - 1) / kTile; ++by)
      for (int bx = t.x0 / kTile; bx <= (t.x1 - 1) / kTile; ++bx) f(static_cast<std::size_t>(by) * tiles_x + bx);
  };
  std::atomic<long long> set_up_count{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const tbb::blocked_range<std::size_t>& r) {
    long long kept = 0;
    for (std::size_t c = r.begin(); c != r.end(); ++c) {
      std::uint32_t* cnt = count.data() + c * tiles;
      for (std::size_t g = c * chunk; g < std::min(total, (c + 1) * chunk); ++g) {
        Tri& t = tris[g];
        grid_bounds(inv, W, H, t);
        if (t.x0 >= t.x1) continue;
        ++kept;
        each_tile(t, [&](std::size_t tile) { ++cnt[tile]; });
      }
    }
    set_up_count += kept;
  });
  // Offsets: tile by tile, range by range; count[] becomes each (range, tile)'s fill position.
  std::vector<std::uint64_t>& start = sc.start;
  start.resize(tiles + 1);
  std::uint64_t entries = 0;
  for (std::size_t tile = 0; tile < tiles; ++tile) {
    start[tile] = entries;
    for (std::size_t c = 0; c < chunks; ++c) {
      const std::uint64_t n = count[c * tiles + tile];
      count[c * tiles + tile] = static_cast<std::uint32_t>(std::min<std::uint64_t>(entries, 0xFFFFFFFFu));
      entries += n;
    }
  }
  start[tiles] = entries;
  // Each entry is 4 bytes and offsets are 32-bit: a scene that would need more than 2^31 of them
  // (8 GiB) is refused.
  if (entries > (std::uint64_t(1) << 31))
    throw std::invalid_argument(std::string(who) + ": " + std::to_string(entries) +
                                " triangle-tile pairs to rasterise (more than 2^31); use a smaller image or the Embree "
                                "visibility (SOFTGI_CPU_VISIBILITY=embree)");
  std::vector<std::uint32_t>& list = sc.list;
  list.resize(entries);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t c = r.begin(); c != r.end(); ++c) {
      std::uint32_t* fill = count.data() + c * tiles;
      for (std::size_t i = c * chunk; i < std::min(total, (c + 1) * chunk); ++i) {
        const Tri& t = tris[i];
        if (t.x0 >= t.x1) continue;
        each_tile(t, [&](std::size_t tile) { list[fill[tile]++] = static_cast<std::uint32_t>(i); });
      }
    }
  });
  const auto t1 = clock::now();

  std::atomic<long long> hits{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tiles, 1), [&](const tbb::blocked_range<std::size_t>& r) {
    alignas(64) std::array<float, kTile * kTile> wbuf;
    alignas(64) std::array<std::int32_t, kTile * kTile> ibuf;
    long long local_hits = 0;
    for (std::size_t tile = r.begin(); tile != r.end(); ++tile) {
      const int tx = static_cast<int>(tile % tiles_x) * kTile, ty = static_cast<int>(tile / tiles_x) * kTile;
      const int rows = std::min(kTile, H - ty), cols = std::min(kTile, W - tx);
      wbuf.fill(0.0f);
      ibuf.fill(-1);
      raster_tile(tris.data(), list.data() + start[tile], start[tile + 1] - start[tile], sx.data() + tx, sy.data() + ty,
                  tx, ty, rows, wbuf.data(), ibuf.data());
      for (int y = 0; y < rows; ++y)
        for (int x = 0; x < cols; ++x) {
          const std::size_t i = static_cast<std::size_t>(ty + y) * W + (tx + x);
          const std::int32_t id = ibuf[static_cast<std::size_t>(y) * kTile + x];
          if (id < 0) {
            gb.object[i] = gb.primitive[i] = -1;
            continue;
          }
          const Tri& t = tris[static_cast<std::size_t>(id)];
          const float s_x = sx[static_cast<std::size_t>(tx + x)], s_y = sy[static_cast<std::size_t>(ty + y)];
          float e[3];
          for (int k = 0; k < 3; ++k) e[k] = std::max(0.0f, (t.ef[k] + s_y * t.eu[k]) + s_x * t.er[k]);
          const float sum = e[0] + e[1] + e[2];
          gb.object[i] = t.object;
          gb.primitive[i] = t.prim;
          gb.barycentric[i] = sum > 0.0f ? glm::vec2(e[1] / sum, e[2] / sum) : glm::vec2(1.0f / 3.0f);
          ++local_hits;
        }
    }
    hits += local_hits;
  });
  const auto t2 = clock::now();

  stats.triangles = static_cast<long long>(total);
  stats.set_up = set_up_count.load();
  stats.held_bytes = lock.owns_lock() ? sc.bytes() : 0;
  stats.tile_entries = static_cast<long long>(entries);
  stats.hits = hits.load();
  stats.setup_seconds = std::chrono::duration<double>(t1 - t0).count();
  stats.raster_seconds = std::chrono::duration<double>(t2 - t1).count();
}

}  // namespace softgi::backends::cpu_raster
