// Point-proxy voxels' frame resources, settings and backend kernels (paper 002, Chen et al. 2014),
// shared by the host passes (point_voxels.cpp), the Vulkan passes (pv_vulkan.cpp) and the tests.
// Not installed; include by path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "pv_core.hpp"
#include "../common/pass_support.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"

namespace softgi::techniques::point_voxels {

inline constexpr int kSkyOrder = 3;

// Resources of the graph.
inline constexpr const char* kProxies = "point_voxels.proxies";        // shared_ptr<const Posed>: posed, in sampling order
inline constexpr const char* kVoxels = "point_voxels.voxels";          // shared_ptr<const Voxels>: sorted by eq. 1, cell ranges
inline constexpr const char* kLightMaps = "point_voxels.light_maps";   // shared_ptr<const Lights>
inline constexpr const char* kVpls = "point_voxels.vpls";              // shared_ptr<const Voxels>: lit, with the voxels' SH
inline constexpr const char* kMarchGBuffer = "point_voxels.march_gbuffer";
inline constexpr const char* kGatherGBuffer = "point_voxels.gather_gbuffer";
inline constexpr const char* kLists = "point_voxels.lists";            // shared_ptr<const Marched>
inline constexpr const char* kFiltered = "point_voxels.filtered";      // shared_ptr<const Marched>: the lists only
inline constexpr const char* kFilteredSky = "point_voxels.filtered_sky";  // shared_ptr<const SkyLight>
inline constexpr const char* kGathered = "point_voxels.gathered";      // shared_ptr<const std::vector<Gathered>>
inline constexpr const char* kIndirectEnabled = "point_voxels.indirect_enabled";  // input; empty when indirect=false

struct Settings {
  double proxy_count = 24000.0, disc_scale = 1.5;
  int grid = 8, march_scale = 8, gather_scale = 2, rays = 64;
  FilterOptions filter;
  double near_range = 0.25, sigma_depth = 0.05, sigma_normal = 0.1;
  int shadow_map_size = 512, vpl_env_rays = 4;
  bool environment = true, indirect = true;
  bool eq7 = false;
  double eq7_sigma_scale = 1.0;
  bool march_lanes_discs = true;  // device marching: a ray's discs across a subgroup's lanes
};
// Throws std::invalid_argument naming the parameter.
Settings read_settings(const render::ParamSet& p);

// The proxies of this frame in sampling order (section 3.1), before voxelisation: the sampling is
// the scene's at t = 0, posed on this frame's meshes.
struct Posed {
  PosedProxies proxies;
  double density = 0.0;
  // Per proxy, the seed of its environment rays (a hash of its sampling index: the same proxy draws
  // the same rays on every backend, whatever order voxelisation leaves it in).
  std::vector<std::uint32_t> ray_seed;
  // The grid over the proxies' bounds (padded by the disc radius), `grid` cells per axis: lo, cell.
  VoxelGrid frame;
};

struct Voxels {
  PosedProxies proxies;  // sorted by voxel (eq. 1)
  VoxelGrid grid;
  ProxyPlanes planes;  // the proxies as planes (lit in kVpls), for marching and gathering
  std::vector<std::uint32_t> sample;    // per sorted proxy: its index in sampling order (Posed)
  std::vector<std::uint32_t> ray_seed;  // per sorted proxy: Posed::ray_seed of that index
  double density = 0.0;
  float diagonal = 0.0f;  // of the grid: the unit of near_range
};

// Lights seen from the proxies and the receivers: each local light's cube depth map, the sun's
// directional one, the rest of the environment as SH.
struct Lights {
  std::vector<CubeDepthMap> local;
  std::vector<scene::SphericalLight> local_lights;
  bool sun = false;
  OrthoDepthMap sun_map;
  glm::vec3 sun_irradiance{0.0f};  // at normal incidence: L_sun * solid angle
  bool sky = false;
  std::vector<glm::vec3> sky_sh;   // order kSkyOrder, radiance without the sun disk
  std::size_t bytes() const;
  glm::vec3 sky_radiance(const glm::vec3& w) const;
};

// The environment's SH per environment (signature), shared across frames.
using SkyCache = common::SharedCache<std::string, std::vector<glm::vec3>>;

// The environment seen through a marching pixel's escaped rays: irradiance without the sun, and the
// escaped fraction.
struct SkyLight {
  std::vector<glm::vec3> irradiance;
  std::vector<float> escaped;
  std::size_t bytes() const { return irradiance.size() * sizeof(glm::vec3) + escaped.size() * sizeof(float); }
};
// What the marching pass found per marching pixel: visible voxels, and the sky through the escaped
// rays. The filtered lists (kFiltered) leave `sky` empty: the filtered sky is kFilteredSky, which
// only the direct pass reads.
struct Marched {
  PixelLists lists;
  SkyLight sky;
  std::size_t bytes() const { return lists.bytes() + sky.bytes(); }
};

// The seed of marching pixel i's rays, and of the environment rays of the proxy sampled i-th.
std::uint32_t pixel_ray_seed(std::size_t i);
std::uint32_t proxy_ray_seed(std::size_t sample);
// Ray k of n of a stratified (Hammersley) set rotated by `seed` (Cranley-Patterson): its point of
// the unit square.
glm::vec2 ray_sample(int k, int n, std::uint32_t seed);
// Irradiance of a spherical light (centre c, radius R, radiance L) at p with normal n: L pi R^2 / d^2
// times the cosine, exact while the sphere is above the horizon; `dir` gets the unit direction to it.
glm::vec3 local_irradiance(const scene::SphericalLight& l, const glm::vec3& p, const glm::vec3& n, glm::vec3& dir);
// Pixels of `g` that hit a surface (the passes' "pixels" counters).
std::size_t hit_pixels(const render::GBuffer& g);
// The receiver of G-buffer pixel i: position, normal, the view direction's mirror, the material's
// Phong glossiness (section 3.3).
Receiver receiver_at(const render::FrameContext& ctx, const render::GBuffer& g, std::size_t i);
// Eq. 5's joint bilateral weights of gathering pixel i over its four marching neighbours.
struct GatherTap {
  std::size_t q = 0;   // marching pixel
  float weight = 0.0f; // normalised w_l w_G / N_c
};
// Returns the taps (at most 4); `geometric` false when no neighbour lies on the pixel's surface and
// the linear weights alone were used, and no taps when no neighbour was hit at all.
int gather_taps(const Settings& s, const render::GBuffer& gg, const render::GBuffer& mg, std::size_t i, GatherTap (&taps)[4],
                bool& geometric);

// Backend kernels of the passes with a device implementation (pv_vulkan.cpp registers Vulkan's):
// each reads and writes the same frame resources as the host pass of the same name.
struct DeviceKernels {
  std::function<void(const Settings&, render::FrameContext&)> voxelize, light_vpls, march, filter, gather;
  // Rasterises the depth maps of `lights` (planned: every map's frame set, no depths) and puts
  // kLightMaps.
  std::function<void(const Settings&, render::FrameContext&, std::shared_ptr<Lights> lights)> light_maps;
};
void register_device_kernels(const std::string& backend, DeviceKernels kernels);
void register_vulkan_kernels();  // pv_vulkan.cpp (softgi::techniques_vulkan)

}  // namespace softgi::techniques::point_voxels
