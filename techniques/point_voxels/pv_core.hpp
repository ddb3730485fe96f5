// Point-proxy voxels (paper 002, Chen et al. 2014): the data structures and kernels of the
// technique's passes, as plain functions of plain data so that tests can check each one against a
// closed form or a brute-force reference. Not installed; include by path.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/scene/scene.hpp"

namespace softgi::render {
class FramePool;
}

namespace softgi::techniques::point_voxels {

// --- Section 3.1: point proxies ------------------------------------------------------------------
// A proxy is a triangle and barycentrics, so it follows its mesh through rigid and skinned motion.
struct ProxySample {
  std::int32_t object = 0;  // PosedScene::objects index
  std::int32_t prim = 0;    // triangle of the object's mesh
  float b1 = 0.0f, b2 = 0.0f;
};
struct ProxySampling {
  std::vector<ProxySample> samples;
  double density = 0.0;      // proxies per square metre (target count / total area)
  double total_area = 0.0;   // of every triangle, square metres
  std::size_t roulette_triangles = 0;  // triangles whose expected count had a fractional part drawn by the hash
};
// A 64-bit finaliser (splitmix64's): the per-triangle and per-pixel sample rotations hash with it.
std::uint64_t mix_hash(std::uint64_t z);
// Halton radical inverse in `base` of index i (i >= 1).
double radical_inverse(std::uint32_t i, std::uint32_t base);
// A pseudo-random number in [0, 1) from a triangle's position (its centroid's float bits): the same
// triangle draws the same number in every frame and on every machine.
double position_hash01(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);
// Expected count per triangle n = area * density; floor(n) proxies plus one more when the
// position hash falls below frac(n) (the paper's Russian roulette on small triangles, extended to
// every triangle's remainder), so the expected total is exactly total_area * density. Barycentrics
// from the Halton (2, 3) sequence, warped to be uniform on the triangle. `geometry` is the scene
// posed at the sampling time (the technique uses t = 0). Throws std::invalid_argument for a
// non-positive target or a scene without triangles.
ProxySampling sample_point_proxies(const scene::PosedScene& geometry, double target_count);

// The proxies at one pose, sorted by voxel (build_voxel_grid permutes them).
struct PosedProxies {
  std::vector<glm::vec3> position, normal, albedo;
  std::vector<glm::vec3> radiance;  // outgoing (diffuse) radiance as a VPL, W / (m^2 sr)
  // Disc radius for the ray-disc tests, and the surface area each proxy stands for (1 / density):
  // the VPL's emitting area. The disc is larger than that area by disc_scale^2, so that discs overlap
  // and rays do not slip between them; the energy must not grow with it.
  float radius = 0.0f;
  float patch_area = 0.0f;
  std::size_t size() const { return position.size(); }
};
// Positions and normals interpolated on the posed meshes, albedo by scene::surface_albedo; radius
// disc_scale * sqrt(1 / (pi density)), patch_area 1 / density.
PosedProxies pose_proxies(const scene::Scene& scene, const scene::PosedScene& posed, const ProxySampling& s,
                          double disc_scale);

// The proxies' positions, normals and radiance (zero before they are lit) as float planes in their
// order, with kProxyLanes zeros after the last one so that a voxel's last lanes read inside the planes.
constexpr std::size_t kProxyLanes = 16;
struct ProxyPlanes {
  std::vector<float> px, py, pz, nx, ny, nz, lr, lg, lb;
  std::size_t size = 0;  // proxies (the planes hold size + kProxyLanes floats)
  std::size_t bytes() const { return 9 * px.size() * sizeof(float); }
};
ProxyPlanes proxy_planes(const PosedProxies& proxies);
// Writes the radiance planes of `planes` (made from the same proxies) from proxies.radiance, once the
// proxies are lit.
void set_radiance(ProxyPlanes& planes, const PosedProxies& proxies);

// --- Section 3.1, eqs. 1-3: voxels ----------------------------------------------------------------
struct VoxelGrid {
  glm::vec3 lo{0.0f}, cell{1.0f};  // world-space origin and cell size
  glm::vec3 inv_cell{1.0f};        // 1 / cell: cell_of multiplies by it, as the GPU does, so both round alike
  glm::ivec3 dims{1};
  // Proxy indices of cell k are [start[k], start[k + 1]) in the sorted order.
  std::vector<std::uint32_t> start;
  std::vector<std::uint32_t> key;   // per sorted proxy: its cell's hash (eq. 1)
  // Per cell: centroid of its proxies (the voxel's position, section 3.3), and the order-2 SH
  // (l <= 1, eqs. 2-3) of the radiant intensity of its VPLs, per RGB channel (4 coefficients).
  std::vector<glm::vec3> centroid;
  std::vector<std::array<glm::vec3, 4>> sh;
  std::size_t cells() const { return static_cast<std::size_t>(dims.x) * dims.y * dims.z; }
  // H(v) = v.z Dx Dy + v.y Dx + v.x (eq. 1).
  std::uint32_t hash(const glm::ivec3& v) const {
    return static_cast<std::uint32_t>(v.z) * dims.x * dims.y + static_cast<std::uint32_t>(v.y) * dims.x + v.x;
  }
  glm::ivec3 cell_of(const glm::vec3& p) const;  // clamped into the grid
  std::size_t bytes() const;
};
// The grid over the proxies' bounds (padded by the disc radius) with `dims` cells per axis: lo, cell
// and dims only (no proxies sorted). Throws std::invalid_argument for dims outside 1 to 2^24 cells.
VoxelGrid grid_frame(const PosedProxies& proxies, glm::ivec3 dims);
// The grid of grid_frame; sorts the proxies by eq. 1's key (stable: equal keys keep their sampling
// order) and permutes every array of `proxies` into that order; `permutation` (optional) receives
// the old index of each sorted proxy. The SH and centroids are left for accumulate_voxel_sh (the
// VPLs are lit after sorting).
VoxelGrid build_voxel_grid(PosedProxies& proxies, glm::ivec3 dims, std::vector<std::uint32_t>* permutation = nullptr);
// Eqs. 2-3: each VPL's intensity I_p(w) = L_p A max(0, n_p . w) projected to order 2 (ZH of the
// clamped cosine turned to n_p) and summed per voxel; the centroids.
void accumulate_voxel_sh(VoxelGrid& grid, const PosedProxies& proxies);

// --- Section 3.1: sparse ray marching ---------------------------------------------------------------
// The first voxel along the ray o + t d (t in [t_min, t_max]) whose proxies' discs the ray hits,
// marching the grid cell by cell (3D DDA), or -1 when the ray leaves the grid unblocked.
// With `planes` (proxy_planes of the same proxies), a cell's discs are tested kProxyLanes at a time,
// each by ray_disc's arithmetic: the same voxel. With `count`, adds the cells the ray visited and the
// discs they hold (the hit's cell included: what a ray-by-ray search may test).
struct MarchCount {
  std::uint64_t cells = 0, discs = 0;
};
std::int32_t march_ray(const VoxelGrid& grid, const PosedProxies& proxies, const glm::vec3& o, const glm::vec3& d,
                       float t_min, float t_max, const ProxyPlanes* planes = nullptr, MarchCount* count = nullptr);
// Ray-disc intersection: t of the hit of o + t d with the disc (centre c, unit normal n, radius r),
// or a negative value for none (parallel rays miss).
float ray_disc(const glm::vec3& o, const glm::vec3& d, const glm::vec3& c, const glm::vec3& n, float r);
// Cosine-weighted direction about n from a point of the unit square (Shirley-Chiu concentric map).
glm::vec3 cosine_direction(const glm::vec3& n, float u, float v);

// Variable-length lists per pixel (the per-pixel lists of visible voxels), compressed rows.
struct PixelLists {
  int width = 0, height = 0;
  std::vector<std::uint32_t> offset;  // width * height + 1
  std::vector<std::int32_t> voxel;    // sorted, unique within a pixel
  std::size_t count(std::size_t p) const { return offset[p + 1] - offset[p]; }
  std::size_t bytes() const { return offset.size() * sizeof(std::uint32_t) + voxel.size() * sizeof(std::int32_t); }
};

// --- Section 3.2, eq. 4: the visibility filter -------------------------------------------------------
struct FilterOptions {
  int radius_x = 3, radius_y = 3;   // m, n: the window is (2m + 1) x (2n + 1) (paper: 7 x 7)
  double depth_threshold = 0.05;    // delta_d: |z_q - z_p| <= threshold * z_p (relative: unit-free)
  double normal_threshold = 0.9;    // delta_n: N_p . N_q >= threshold
};
// V'_p = union of the neighbours' lists V_q over the window where delta_d delta_n = 1 (pixels that
// hit nothing have no list and take none). depth: eye-space depth, +inf for background.
PixelLists visibility_filter(const PixelLists& in, const float* depth, const glm::vec3* normal, const FilterOptions& opt);
// The same window and constraints applied to a per-pixel field of `channels` floats (the mean over
// accepted neighbours): the environment's escaped-ray irradiance is smoothed exactly where the lists
// are unioned.
void filter_field(const float* in, int channels, int width, int height, const float* depth, const glm::vec3* normal,
                  const FilterOptions& opt, float* out);

// --- Section 3.3, eqs. 5-6: gathering ----------------------------------------------------------------
// Modified Phong (the measurement function of section 3.3, the reference renderer's BRDF):
// (1 - g) albedo / pi + g albedo (ns + 2) / (2 pi) max(0, R . w)^ns.
struct Receiver {
  glm::vec3 position{0.0f}, normal{0.0f, 1.0f, 0.0f}, reflect{0.0f, 1.0f, 0.0f};  // reflect: mirror of the view direction
  float glossy = 0.0f, ns = 0.0f;
  // sigma_theta of eq. 7 (0: the glossy term is the Phong BRDF's alone).
  float eq7_sigma = 0.0f;
};
// The glossy part of the Phong BRDF: g (ns + 2) / (2 pi) max(0, R . w)^ns (0 for a diffuse receiver).
float glossy_lobe(const Receiver& r, const glm::vec3& w);
// Eq. 7: w_spec = exp(-(|1 - cos^ns theta_i| / sigma)^2 / 2) / (sigma sqrt(2 pi)), theta_i between the
// light's direction and the reflection vector.
float eq7_weight(float cos_theta, float ns, float sigma);
// sigma_theta from the glossiness: sqrt(2 / (ns + 2)), the angular width of the normalised Phong lobe
// (its cos^ns falls to 1/e at theta ~ sqrt(2 / ns)), times `scale`.
float eq7_sigma(float ns, float scale);
// Incoming light at a receiver, separated for the diffuse and glossy terms: diffuse E (irradiance,
// W/m^2) and glossy S = sum_i E_i (ns + 2) / (2 pi) max(0, R . w_i)^ns, so that the outgoing radiance is
// albedo ((1 - g) E / pi + g S).
struct Gathered {
  glm::vec3 irradiance{0.0f}, glossy{0.0f};
  // With eq. 7 (Receiver::eq7_sigma > 0): sum_i (w_i / w_max) G_i, each light's glossy term times its
  // eq. 7 importance relative to the peak w_max = 1 / (sigma sqrt(2 pi)) at the reflection vector.
  glm::vec3 weighted{0.0f};
  bool eq7 = false;
  glm::vec3 glossy_term() const { return eq7 ? weighted : glossy; }
};
// f(v_l) of eq. 6 for one voxel: its VPLs one by one when the receiver is within `near_range` of
// the voxel's centroid, else its SH intensity from the centroid. A VPL is a disc of area A: the
// irradiance it gives is L A cos_v cos_r / (d^2 + A / pi), exact on the disc's axis and bounded as
// d -> 0 (the usual VPL singularity).
// With `planes` (proxy_planes of the same proxies), a diffuse receiver's near VPLs are summed
// kProxyLanes at a time in partial sums per lane, and cos_v cos_r / d^2 without the square root: the
// same sum in another order of float operations (equal within rounding to the one VPL at a time).
void gather_voxel(const VoxelGrid& grid, const PosedProxies& proxies, std::int32_t voxel, const Receiver& r,
                  float near_range, float weight, Gathered& out, const ProxyPlanes* planes = nullptr);

// --- Depth maps of the lights (Figure 2a) -----------------------------------------------------------
// A cube depth map around a local light: six 90-degree faces of size x size texels holding the
// distance along the face's axis to the nearest triangle, rasterised from the posed meshes.
struct CubeDepthMap {
  glm::vec3 center{0.0f};
  int size = 0;
  std::vector<float> depth;  // 6 * size * size, +inf where nothing
  // 1 when p is lit (3 x 3 percentage-closer filtering), 0 when shadowed; p_normal offsets the
  // lookup by two texels along the surface normal against self-shadowing.
  float visibility(const glm::vec3& p, const glm::vec3& p_normal) const;
};
// Faces 2a (+axis a) and 2a + 1 (-axis a), a = x, y, z; texel (i, j) of a face looks along
// (d[(a + 1) % 3], d[(a + 2) % 3]) / |d[a]| = ((i + 0.5) / size * 2 - 1, (j + 0.5) / size * 2 - 1).
// Triangles nearer than kCubeNear along the face's axis are clipped. Throws std::invalid_argument
// for a size outside 1 to 8192. The six faces are rasterised in parallel. `pool`: where the depths
// and the rasteriser's scratch plane come from (render::FramePool), else allocated.
inline constexpr float kCubeNear = 1e-4f;
CubeDepthMap rasterize_cube_depth(const scene::PosedScene& posed, const glm::vec3& center, int size,
                                  render::FramePool* pool = nullptr);
// An orthographic depth map along a distant light's direction, covering the posed scene.
struct OrthoDepthMap {
  glm::vec3 dir{0.0f, 1.0f, 0.0f};  // towards the light
  glm::vec3 u{1.0f, 0.0f, 0.0f}, v{0.0f, 0.0f, 1.0f};
  glm::vec2 lo{0.0f}, extent{1.0f};
  int size = 0;
  std::vector<float> depth;  // size * size: min of -dot(p, dir) over the rasterised triangles
  float visibility(const glm::vec3& p, const glm::vec3& p_normal) const;
};
// The map's frame without its depths: dir, u, v, and lo and extent covering every posed vertex
// (padded by 1 %). Throws std::invalid_argument for a size outside 1 to 8192.
OrthoDepthMap ortho_frame(const scene::PosedScene& posed, const glm::vec3& towards_light, int size);
OrthoDepthMap rasterize_ortho_depth(const scene::PosedScene& posed, const glm::vec3& towards_light, int size,
                                    render::FramePool* pool = nullptr);

}  // namespace softgi::techniques::point_voxels
