// Point-proxy voxels with the visibility filter (paper 002, Chen et al. 2014): point proxies
// lit as VPLs, hashed into voxels (eqs. 1-3); sparse shadow rays march the voxels from a
// low-resolution G-buffer (section 3.1); the visibility filter unions the neighbours' lists (eq. 4);
// indirect light, diffuse and glossy, is gathered at a middle resolution (eqs. 5-6) and bilaterally
// upsampled. docs/techniques/point_voxels.md gives the method, the parameters and the extensions
// (environment light).
#include "softgi/techniques/point_voxels.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "pv_core.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/vertex_image.hpp"
#include "softgi/sh/sh.hpp"
#include "../common/pass_support.hpp"
#include "../common/upsample.hpp"

namespace softgi::techniques::point_voxels {

std::vector<render::ExperimentDef> experiments();  // pv_experiments.cpp

namespace {

using render::FrameContext;
using render::GBuffer;
using softgi::Image;
using render::ParamDesc;

constexpr float kPi = 3.14159265358979323846f;
constexpr int kSkyOrder = 3;

// Resources of the graph.
constexpr const char* kProxies = "point_voxels.proxies";        // shared_ptr<const Voxels>: sorted proxies and the grid
constexpr const char* kLightMaps = "point_voxels.light_maps";   // shared_ptr<const Lights>
constexpr const char* kVpls = "point_voxels.vpls";              // shared_ptr<const Voxels>: lit, with the voxels' SH
constexpr const char* kMarchGBuffer = "point_voxels.march_gbuffer";
constexpr const char* kGatherGBuffer = "point_voxels.gather_gbuffer";
constexpr const char* kLists = "point_voxels.lists";            // shared_ptr<const Marched>
constexpr const char* kFiltered = "point_voxels.filtered";      // shared_ptr<const Marched>
constexpr const char* kGathered = "point_voxels.gathered";      // shared_ptr<const std::vector<Gathered>>
constexpr const char* kIndirectEnabled = "point_voxels.indirect_enabled";  // input; empty when indirect=false

struct Settings {
  double proxy_count = 24000.0, disc_scale = 1.5;
  int grid = 8, march_scale = 8, gather_scale = 2, rays = 64;
  FilterOptions filter;
  double near_range = 0.25, sigma_depth = 0.05, sigma_normal = 0.1;
  int shadow_map_size = 512, vpl_env_rays = 4;
  bool environment = true, indirect = true;
  bool eq7 = false;
  double eq7_sigma_scale = 1.0;
};

std::vector<ParamDesc> params() {
  std::vector<ParamDesc> d;
  d.push_back(ParamDesc::real("proxy_count", 24000.0, 16.0, 4.0e6,
                              "expected number of point proxies, spread in proportion to triangle area (section 3.1; paper: 24k "
                              "Cornell box, 170k Sponza)"));
  d.push_back(ParamDesc::real("disc_scale", 1.5, 0.25, 8.0,
                              "disc radius of a proxy in units of sqrt(area per proxy / pi): 1 covers the surface on average, "
                              "more closes the gaps rays would leak through"));
  // Visibility is per voxel and found by sparse rays: the finer the grid, the more voxels a receiver
  // sees and the more rays it takes to find them (light is lost where rays miss a visible voxel:
  // experiment pv_rays, docs/techniques/point_voxels.md). The paper uses 6^3 on its Cornell box.
  d.push_back(ParamDesc::integer("grid", 8, 1, 128, "voxels per axis over the proxies' bounds (eq. 1; paper: 6 Cornell box, 20 Sponza)"));
  // Quality ladder (softgi report): the marching resolution and the ray count are the paper's
  // cost knobs (Table 1; section 4, Discussion).
  d.push_back(ParamDesc::integer("march_scale", 8, 1, 64, "marching G-buffer at 1/s of display resolution (paper: 512 / 64 = 8 and 512 / 128 = 4)")
                  .with_ladder({"16", "8", "8", "4"}));
  d.push_back(ParamDesc::integer("rays", 64, 1, 1024, "sparse shadow rays per marching pixel, cosine-distributed (section 3.1)")
                  .with_ladder({"16", "32", "64", "128"}));
  d.push_back(ParamDesc::integer("gather_scale", 2, 1, 16, "gathering at 1/s of display resolution (paper: 512 / 256 = 2), at most march_scale"));
  d.push_back(ParamDesc::integer("filter_radius", 3, 0, 16, "visibility filter window (2m + 1)^2 (eq. 4; paper: 3, a 7 x 7 window; 0 = no filter)"));
  d.push_back(ParamDesc::real("depth_threshold", 0.05, 0.0, 10.0, "delta_d of eq. 4: neighbours within this relative depth difference"));
  d.push_back(ParamDesc::real("normal_threshold", 0.9, -1.0, 1.0, "delta_n of eq. 4: neighbours whose normals' dot product is at least this"));
  d.push_back(ParamDesc::real("near_range", 0.25, 0.0, 100.0,
                              "R of eq. 6 as a fraction of the scene's diagonal: nearer voxels are gathered VPL by VPL, farther "
                              "ones through their SH (0 = all SH)"));
  d.push_back(ParamDesc::real("sigma_depth", 0.05, 1e-4, 10.0, "w_G of eq. 5: Gaussian of the relative depth difference"));
  d.push_back(ParamDesc::real("sigma_normal", 0.1, 1e-4, 10.0, "w_G of eq. 5: Gaussian of 1 - N . N'"));
  d.push_back(ParamDesc::choice("glossy_weight", "phong", {"phong", "eq7"},
                                "glossy indirect: the Phong BRDF per light, or each light's term times eq. 7's Gaussian of "
                                "|1 - cos^ns theta| relative to its peak (the paper's glossy importance)"));
  d.push_back(ParamDesc::real("eq7_sigma", 1.0, 1e-3, 100.0, "sigma_theta of eq. 7 in units of sqrt(2 / (ns + 2)), the Phong lobe's width"));
  d.push_back(ParamDesc::integer("shadow_map_size", 512, 16, 8192, "texels per edge of each light's depth map (Figure 2a)"));
  // Each VPL's sky light is a few rays' estimate: a receiver sums hundreds of VPLs, so their noise
  // averages out, while the rays per proxy are most of a sky-lit frame's cost.
  d.push_back(ParamDesc::integer("vpl_env_rays", 4, 0, 1024,
                                 "rays per proxy marched for the environment's light on the VPLs (0 = local lights and sun only)"));
  d.push_back(ParamDesc::boolean("environment", true, "light by the environment too (sky and sun or map; an extension of the paper)"));
  d.push_back(ParamDesc::boolean("indirect", true, "gather the VPLs' indirect light (off: direct light only)"));
  return d;
}

Settings read_settings(const render::ParamSet& p) {
  Settings s;
  s.proxy_count = p.get_float("proxy_count");
  s.disc_scale = p.get_float("disc_scale");
  s.grid = p.get_int("grid");
  s.march_scale = p.get_int("march_scale");
  s.gather_scale = p.get_int("gather_scale");
  if (s.gather_scale > s.march_scale)
    throw std::invalid_argument("parameter 'gather_scale': " + std::to_string(s.gather_scale) +
                                " is coarser than parameter 'march_scale' " + std::to_string(s.march_scale) +
                                " (the gathering resolution is between the marching and the display resolution)");
  s.rays = p.get_int("rays");
  s.filter.radius_x = s.filter.radius_y = p.get_int("filter_radius");
  s.filter.depth_threshold = p.get_float("depth_threshold");
  s.filter.normal_threshold = p.get_float("normal_threshold");
  s.near_range = p.get_float("near_range");
  s.sigma_depth = p.get_float("sigma_depth");
  s.sigma_normal = p.get_float("sigma_normal");
  s.shadow_map_size = p.get_int("shadow_map_size");
  s.vpl_env_rays = p.get_int("vpl_env_rays");
  s.environment = p.get_bool("environment");
  s.indirect = p.get_bool("indirect");
  s.eq7 = p.get_enum("glossy_weight") == "eq7";
  s.eq7_sigma_scale = p.get_float("eq7_sigma");
  return s;
}

struct Voxels {
  PosedProxies proxies;
  VoxelGrid grid;
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
  std::size_t bytes() const {
    std::size_t b = sun_map.depth.size() * sizeof(float) + sky_sh.size() * sizeof(glm::vec3);
    for (const auto& m : local) b += m.depth.size() * sizeof(float);
    return b;
  }
  glm::vec3 sky_radiance(const glm::vec3& w) const {
    float y[kSkyOrder * kSkyOrder];
    sh::eval_basis<float>(kSkyOrder, sh::Vec3<float>{w.x, w.y, w.z}, y);
    glm::vec3 l(0.0f);
    for (int i = 0; i < kSkyOrder * kSkyOrder; ++i) l += sky_sh[i] * y[i];
    return glm::max(l, glm::vec3(0.0f));
  }
};

// What the marching pass found per marching pixel: visible voxels, and the environment seen
// through the escaped rays (irradiance without the sun; the escaped fraction in visible.x).
struct Marched {
  PixelLists lists;
  std::vector<glm::vec3> sky_irradiance, visible;
  std::size_t bytes() const { return lists.bytes() + (sky_irradiance.size() + visible.size()) * sizeof(glm::vec3); }
};

// The marching and gathering buffers: point samples of the display G-buffer, pixel (x, y) at display
// pixel (x s + s / 2, y s + s / 2) (clamped to the image), so both see exactly the display's surfaces.
GBuffer subsample(const GBuffer& full, int s) {
  const int w = render::scaled_size(full.width, s), h = render::scaled_size(full.height, s);
  GBuffer g = GBuffer::background(w, h, s);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int X = std::min(full.width - 1, x * s + s / 2), Y = std::min(full.height - 1, y * s + s / 2);
      const std::size_t i = static_cast<std::size_t>(y) * w + x, j = static_cast<std::size_t>(Y) * full.width + X;
      g.position[i] = full.position[j];
      g.normal[i] = full.normal[j];
      g.depth[i] = full.depth[j];
      g.albedo[i] = full.albedo[j];
      g.object[i] = full.object[j];
      g.primitive[i] = full.primitive[j];
      g.barycentric[i] = full.barycentric[j];
      g.view_dir[i] = full.view_dir[j];
    }
  return g;
}


// Ray k of n of a stratified (Hammersley) set rotated per pixel (Cranley-Patterson with `h`).
glm::vec2 ray_sample(int k, int n, std::uint64_t h) {
  float u = (static_cast<float>(k) + 0.5f) / static_cast<float>(n) + static_cast<float>(h & 0xffff) / 65536.0f;
  float v = static_cast<float>(radical_inverse(static_cast<std::uint32_t>(k) + 1, 2)) + static_cast<float>((h >> 16) & 0xffff) / 65536.0f;
  return {u - std::floor(u), v - std::floor(v)};
}

// Irradiance of a spherical light (centre c, radius R, radiance L) at p with normal n: L pi R^2 / d^2
// times the cosine, exact while the sphere is above the horizon.
glm::vec3 local_irradiance(const scene::SphericalLight& l, const glm::vec3& p, const glm::vec3& n, glm::vec3& dir) {
  const glm::vec3 w = l.position - p;
  const float d2 = std::max(glm::dot(w, w), 1.0001f * l.radius * l.radius);
  dir = w / std::sqrt(glm::dot(w, w) > 0.0f ? glm::dot(w, w) : 1.0f);
  const float c = glm::dot(n, dir);
  if (c <= 0.0f) return glm::vec3(0.0f);
  return l.radiance * (kPi * l.radius * l.radius / d2 * c);
}

// --- passes ------------------------------------------------------------------------------------------

void pass_proxies(const Settings& s, FrameContext& ctx) {
  // Sampled once on the scene at t = 0 (triangle and barycentrics), interpolated on this frame's pose.
  const scene::PosedScene rest = ctx.posed.time == 0.0 ? scene::PosedScene{} : scene::evaluate(ctx.scene, 0.0);
  const ProxySampling sampling = sample_point_proxies(ctx.posed.time == 0.0 ? ctx.posed : rest, s.proxy_count);
  auto v = std::make_shared<Voxels>();
  v->density = sampling.density;
  v->proxies = pose_proxies(ctx.scene, ctx.posed, sampling, s.disc_scale);
  v->grid = build_voxel_grid(v->proxies, glm::ivec3(s.grid));
  v->diagonal = glm::length(v->grid.cell * glm::vec3(v->grid.dims));
  std::size_t occupied = 0;
  for (std::size_t k = 0; k < v->grid.cells(); ++k) occupied += v->grid.start[k + 1] > v->grid.start[k];
  auto& rec = ctx.record();
  rec.counters["proxies"] = static_cast<double>(v->proxies.size());
  rec.counters["roulette_triangles"] = static_cast<double>(sampling.roulette_triangles);
  rec.counters["disc_radius"] = v->proxies.radius;
  rec.counters["voxels"] = static_cast<double>(v->grid.cells());
  rec.counters["voxels_occupied"] = static_cast<double>(occupied);
  rec.bytes = v->proxies.size() * (4 * sizeof(glm::vec3)) + v->grid.bytes();
  ctx.put<std::shared_ptr<const Voxels>>(kProxies, std::move(v));
}

void pass_light_maps(const Settings& s, FrameContext& ctx, common::SharedCache<std::string, std::vector<glm::vec3>>& sky_cache) {
  auto L = std::make_shared<Lights>();
  for (const auto& l : ctx.posed.lights) {
    L->local.push_back(rasterize_cube_depth(ctx.posed, l.position, s.shadow_map_size));
    L->local_lights.push_back(l);
  }
  const scene::Environment& env = ctx.scene.environment;
  if (s.environment) {
    scene::Environment sky = env;
    if (env.kind == scene::Environment::Kind::Sky && env.sun_radius > 0.0f) {
      // The sun disk is a directional light with its own depth map; the sky keeps the rest (the disk
      // replaces the sky there, so the sky's SH is taken with the disk black).
      glm::vec3 sd = glm::length(env.sun_direction) > 0.0f ? glm::normalize(env.sun_direction) : glm::vec3(0.0f, 1.0f, 0.0f);
      const float c = std::cos(env.rotation_y), sn = std::sin(env.rotation_y);
      sd = {c * sd.x + sn * sd.z, sd.y, -sn * sd.x + c * sd.z};
      const float omega = 2.0f * kPi * (1.0f - std::cos(env.sun_radius));
      L->sun_irradiance = env.intensity * env.sun_radiance * omega;
      if (glm::dot(L->sun_irradiance, glm::vec3(1.0f)) > 0.0f) {
        L->sun = true;
        L->sun_map = rasterize_ortho_depth(ctx.posed, sd, s.shadow_map_size);
      }
      sky.sun_radiance = glm::vec3(0.0f);
    }
    bool cached = false;
    L->sky_sh = *sky_cache.get(common::environment_signature(sky),
                               [&] { return std::make_shared<const std::vector<glm::vec3>>(scene::environment_sh(sky, kSkyOrder)); },
                               cached);
    for (const auto& c : L->sky_sh)
      if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z))
        throw std::invalid_argument("point_voxels: the environment's SH projection is not finite");
    // A dark sky (only local lights, the paper's setting) leaves out the marched environment rays.
    for (const auto& c : L->sky_sh) L->sky = L->sky || c != glm::vec3(0.0f);
  }
  auto& rec = ctx.record();
  rec.counters["local_lights"] = static_cast<double>(L->local.size());
  rec.counters["sun"] = L->sun ? 1.0 : 0.0;
  rec.bytes = L->bytes();
  ctx.put<std::shared_ptr<const Lights>>(kLightMaps, std::move(L));
}

// Figure 2a: the VPLs' energy from the lights (depth maps), the sky through marched rays; then
// eqs. 2-3 per voxel.
void pass_light_vpls(const Settings& s, FrameContext& ctx) {
  const auto& in = *ctx.get<std::shared_ptr<const Voxels>>(kProxies);
  const auto& L = *ctx.get<std::shared_ptr<const Lights>>(kLightMaps);
  auto v = std::make_shared<Voxels>(in);
  PosedProxies& P = v->proxies;
  const std::size_t n = P.size();
  const int k_rays = L.sky ? s.vpl_env_rays : 0;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const glm::vec3 p = P.position[i], nn = P.normal[i];
      glm::vec3 e(0.0f), dir;
      for (std::size_t l = 0; l < L.local.size(); ++l) {
        const glm::vec3 el = local_irradiance(L.local_lights[l], p, nn, dir);
        if (el != glm::vec3(0.0f)) e += el * L.local[l].visibility(p, nn);
      }
      if (L.sun) {
        const float c = glm::dot(nn, L.sun_map.dir);
        if (c > 0.0f) e += L.sun_irradiance * (c * L.sun_map.visibility(p, nn));
      }
      if (k_rays > 0) {
        const std::uint64_t h = mix_hash(i * 0x9e3779b97f4a7c15ULL + 17);
        const glm::vec3 o = p + nn * (0.25f * P.radius);
        glm::vec3 sky(0.0f);
        for (int k = 0; k < k_rays; ++k) {
          const glm::vec2 u = ray_sample(k, k_rays, h);
          const glm::vec3 d = cosine_direction(nn, u.x, u.y);
          if (march_ray(in.grid, in.proxies, o, d, 0.5f * P.radius, 1e30f) < 0) sky += L.sky_radiance(d);
        }
        e += sky * (kPi / static_cast<float>(k_rays));
      }
      P.radiance[i] = P.albedo[i] * e / kPi;
    }
  });
  accumulate_voxel_sh(v->grid, P);
  auto& rec = ctx.record();
  rec.counters["vpls"] = static_cast<double>(n);
  rec.counters["env_rays"] = static_cast<double>(n) * k_rays;
  rec.bytes = n * sizeof(glm::vec3) + v->grid.bytes();
  ctx.put<std::shared_ptr<const Voxels>>(kVpls, std::move(v));
}

// Section 3.1: per marching pixel, `rays` shadow rays; the first voxel each hits joins the list.
void pass_march(const Settings& s, FrameContext& ctx) {
  const auto& g = ctx.get<GBuffer>(kMarchGBuffer);
  const auto& V = *ctx.get<std::shared_ptr<const Voxels>>(kProxies);
  const Lights* L = ctx.has(kLightMaps) ? ctx.get<std::shared_ptr<const Lights>>(kLightMaps).get() : nullptr;
  const bool sky = L && L->sky;
  auto m = std::make_shared<Marched>();
  const std::size_t np = static_cast<std::size_t>(g.width) * g.height;
  std::vector<std::vector<std::int32_t>> lists(np);
  m->sky_irradiance.assign(np, glm::vec3(0.0f));
  m->visible.assign(np, glm::vec3(0.0f));
  const float r = V.proxies.radius;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 64), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!g.hit(i)) continue;
      const glm::vec3 nn = g.normal[i], o = g.position[i] + nn * (0.25f * r);
      const std::uint64_t h = mix_hash(i + 1);
      auto& list = lists[i];
      glm::vec3 e(0.0f);
      int escaped = 0;
      for (int k = 0; k < s.rays; ++k) {
        const glm::vec2 u = ray_sample(k, s.rays, h);
        const glm::vec3 d = cosine_direction(nn, u.x, u.y);
        const std::int32_t vox = march_ray(V.grid, V.proxies, o, d, 0.5f * r, 1e30f);
        if (vox >= 0) {
          list.push_back(vox);
        } else {
          ++escaped;
          if (sky) e += L->sky_radiance(d);
        }
      }
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
      m->sky_irradiance[i] = e * (kPi / static_cast<float>(s.rays));
      m->visible[i] = glm::vec3(static_cast<float>(escaped) / static_cast<float>(s.rays));
    }
  });
  m->lists.width = g.width;
  m->lists.height = g.height;
  m->lists.offset.assign(np + 1, 0);
  for (std::size_t i = 0; i < np; ++i) {
    m->lists.voxel.insert(m->lists.voxel.end(), lists[i].begin(), lists[i].end());
    m->lists.offset[i + 1] = static_cast<std::uint32_t>(m->lists.voxel.size());
  }
  std::size_t hits = 0;
  for (std::size_t i = 0; i < np; ++i) hits += g.hit(i);
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(hits);
  rec.counters["rays"] = static_cast<double>(hits) * s.rays;
  rec.counters["list_mean"] = hits ? static_cast<double>(m->lists.voxel.size()) / hits : 0.0;
  rec.bytes = m->bytes();
  ctx.put<std::shared_ptr<const Marched>>(kLists, std::move(m));
}

// Section 3.2, eq. 4; the escaped-ray environment terms are averaged over the same neighbours.
void pass_filter(const Settings& s, FrameContext& ctx) {
  const auto& g = ctx.get<GBuffer>(kMarchGBuffer);
  const auto& in = *ctx.get<std::shared_ptr<const Marched>>(kLists);
  auto m = std::make_shared<Marched>();
  m->lists = visibility_filter(in.lists, g.depth.data(), g.normal.data(), s.filter);
  filter_field(in.sky_irradiance, g.width, g.height, g.depth.data(), g.normal.data(), s.filter, m->sky_irradiance);
  filter_field(in.visible, g.width, g.height, g.depth.data(), g.normal.data(), s.filter, m->visible);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < g.depth.size(); ++i) hits += g.hit(i);
  auto& rec = ctx.record();
  rec.counters["list_mean_before"] = hits ? static_cast<double>(in.lists.voxel.size()) / hits : 0.0;
  rec.counters["list_mean"] = hits ? static_cast<double>(m->lists.voxel.size()) / hits : 0.0;
  rec.bytes = m->bytes();
  ctx.put<std::shared_ptr<const Marched>>(kFiltered, std::move(m));
}

Receiver receiver_at(const FrameContext& ctx, const GBuffer& g, std::size_t i) {
  Receiver r;
  r.position = g.position[i];
  r.normal = g.normal[i];
  const glm::vec3 v = g.view_dir[i];
  r.reflect = 2.0f * glm::dot(r.normal, v) * r.normal - v;
  const auto& obj = ctx.posed.objects[static_cast<std::size_t>(g.object[i])];
  const scene::Material& mat = ctx.scene.materials[static_cast<std::size_t>(obj.material)];
  if (mat.phong_ns > 0.0f) {
    r.glossy = std::clamp(mat.glossy, 0.0f, 1.0f);
    r.ns = mat.phong_ns;
  }
  return r;
}

// Section 3.3, eqs. 5-6: each gathering pixel takes the filtered lists of its four marching
// neighbours with linear weights w_l times joint bilateral w_G, normalised by their sum N_c.
void pass_gather(const Settings& s, FrameContext& ctx) {
  const auto& gg = ctx.get<GBuffer>(kGatherGBuffer);
  const auto& mg = ctx.get<GBuffer>(kMarchGBuffer);
  const auto& F = *ctx.get<std::shared_ptr<const Marched>>(kFiltered);
  const auto& V = *ctx.get<std::shared_ptr<const Voxels>>(kVpls);
  const std::size_t np = static_cast<std::size_t>(gg.width) * gg.height;
  auto out = std::make_shared<std::vector<Gathered>>(np);
  const float near_range = static_cast<float>(s.near_range) * V.diagonal;
  const float ratio = static_cast<float>(gg.scale) / static_cast<float>(mg.scale);
  std::atomic<std::size_t> unmatched{0}, voxels_gathered{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 64), [&](const tbb::blocked_range<std::size_t>& br) {
    std::vector<std::pair<std::int32_t, float>> taps;
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!gg.hit(i)) continue;
      const int x = static_cast<int>(i % gg.width), y = static_cast<int>(i / gg.width);
      const float u = (x + 0.5f) * ratio - 0.5f, v = (y + 0.5f) * ratio - 0.5f;
      const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
      const float fx = u - x0, fy = v - y0;
      struct Tap {
        std::size_t q;
        float wl, wg;
      };
      Tap t[4];
      int nt = 0;
      for (int j = 0; j < 2; ++j)
        for (int k = 0; k < 2; ++k) {
          const int qx = std::clamp(x0 + k, 0, mg.width - 1), qy = std::clamp(y0 + j, 0, mg.height - 1);
          const std::size_t q = static_cast<std::size_t>(qy) * mg.width + qx;
          if (!mg.hit(q)) continue;
          const float wl = (k ? fx : 1.0f - fx) * (j ? fy : 1.0f - fy);
          const float dz = (mg.depth[q] - gg.depth[i]) / (static_cast<float>(s.sigma_depth) * gg.depth[i]);
          const float dn = (1.0f - glm::dot(mg.normal[q], gg.normal[i])) / static_cast<float>(s.sigma_normal);
          t[nt++] = {q, wl, std::exp(-0.5f * (dz * dz + dn * dn))};
        }
      float nc = 0.0f, nl = 0.0f;
      for (int k = 0; k < nt; ++k) {
        nc += t[k].wl * t[k].wg;
        nl += t[k].wl;
      }
      // No neighbour on this surface (a silhouette the marching buffer does not resolve): the
      // linear weights alone, so the pixel is not left black.
      const bool geometric = nc > 1e-4f * nl;
      const float norm = geometric ? nc : nl;
      if (!(norm > 0.0f)) {
        ++unmatched;
        continue;
      }
      if (!geometric) ++unmatched;
      taps.clear();
      for (int k = 0; k < nt; ++k) {
        const float w = (geometric ? t[k].wl * t[k].wg : t[k].wl) / norm;
        if (!(w > 0.0f)) continue;
        for (std::uint32_t e = F.lists.offset[t[k].q]; e < F.lists.offset[t[k].q + 1]; ++e) taps.push_back({F.lists.voxel[e], w});
      }
      // A voxel in several neighbours' lists is gathered once with the sum of their weights.
      std::sort(taps.begin(), taps.end());
      Receiver r = receiver_at(ctx, gg, i);
      if (s.eq7 && r.glossy > 0.0f) r.eq7_sigma = eq7_sigma(r.ns, static_cast<float>(s.eq7_sigma_scale));
      Gathered acc;
      std::size_t used = 0;
      for (std::size_t a = 0; a < taps.size();) {
        std::size_t b = a;
        float w = 0.0f;
        while (b < taps.size() && taps[b].first == taps[a].first) w += taps[b++].second;
        gather_voxel(V.grid, V.proxies, taps[a].first, r, near_range, w, acc);
        ++used;
        a = b;
      }
      voxels_gathered += used;
      (*out)[i] = acc;
    }
  });
  std::size_t hits = 0;
  for (std::size_t i = 0; i < np; ++i) hits += gg.hit(i);
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(hits);
  rec.counters["unmatched"] = static_cast<double>(unmatched.load());
  rec.counters["voxels_per_pixel"] = hits ? static_cast<double>(voxels_gathered.load()) / hits : 0.0;
  rec.counters["near_range"] = near_range;
  rec.bytes = np * sizeof(Gathered);
  ctx.put<std::shared_ptr<const std::vector<Gathered>>>(kGathered, std::move(out));
}

// Bilateral upsampling of coarse per-pixel fields to display resolution (paper 000 eq. 11, the
// shared kernel; paper 002 section 3.3 asks for a geometry-aware bilateral filter). The weights
// depend only on the two buffers' geometry, so they are computed once for all the fields.
std::vector<std::vector<glm::vec3>> upsample_fields(const GBuffer& coarse, const GBuffer& fine,
                                                    const std::vector<const std::vector<glm::vec3>*>& in) {
  const common::UpsampleWeights w = common::upsample_weights(common::plane_view(coarse), common::plane_view(fine), common::UpsampleOptions{});
  std::vector<std::vector<glm::vec3>> out;
  for (const auto* field : in) {
    out.emplace_back(static_cast<std::size_t>(fine.width) * fine.height, glm::vec3(0.0f));
    common::upsample_apply(w, &(*field)[0].x, 3, &out.back()[0].x);
  }
  return out;
}

void pass_indirect(FrameContext& ctx) {
  const auto& fine = ctx.get<GBuffer>(render::kGBuffer);
  const auto& gg = ctx.get<GBuffer>(kGatherGBuffer);
  const auto& gathered = *ctx.get<std::shared_ptr<const std::vector<Gathered>>>(kGathered);
  std::vector<glm::vec3> e(gathered.size()), sp(gathered.size());
  for (std::size_t i = 0; i < gathered.size(); ++i) {
    e[i] = gathered[i].irradiance;
    sp[i] = gathered[i].glossy_term();
  }
  const auto up = upsample_fields(gg, fine, {&e, &sp});
  const auto &eu = up[0], &su = up[1];
  Image img(fine.width, fine.height);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    if (!fine.hit(i)) continue;
    const Receiver r = receiver_at(ctx, fine, i);
    img.rgb[i] = fine.albedo[i] * ((1.0f - r.glossy) / kPi * eu[i] + r.glossy * su[i]);
  }
  ctx.record().bytes = 2 * img.rgb.size() * sizeof(glm::vec3);
  ctx.put<Image>(render::kIndirect, std::move(img));
}

// The direct term at display resolution: local lights and the sun through their depth maps (as the
// paper's light depth map), the sky through the marching rays' escaped fraction, filtered and
// upsampled like the indirect light.
void pass_direct(FrameContext& ctx) {
  const auto& g = ctx.get<GBuffer>(render::kGBuffer);
  const auto& L = *ctx.get<std::shared_ptr<const Lights>>(kLightMaps);
  std::vector<glm::vec3> sky_e, sky_v;
  if (L.sky && ctx.has(kFiltered)) {
    const auto& F = *ctx.get<std::shared_ptr<const Marched>>(kFiltered);
    const auto& mg = ctx.get<GBuffer>(kMarchGBuffer);
    auto up = upsample_fields(mg, g, {&F.sky_irradiance, &F.visible});
    sky_e = std::move(up[0]);
    sky_v = std::move(up[1]);
  }
  Image img(g.width, g.height);
  const std::size_t np = img.rgb.size();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 256), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!g.hit(i)) {
        img.rgb[i] = render::background_radiance(ctx.scene.environment, g.view_dir[i]);
        continue;
      }
      const Receiver r = receiver_at(ctx, g, i);
      auto brdf = [&](const glm::vec3& w) {
        float f = (1.0f - r.glossy) / kPi;
        if (r.glossy > 0.0f) {
          const float ca = glm::dot(r.reflect, w);
          if (ca > 0.0f) f += r.glossy * (r.ns + 2.0f) / (2.0f * kPi) * std::pow(ca, r.ns);
        }
        return f;
      };
      glm::vec3 lo(0.0f), dir;
      for (std::size_t l = 0; l < L.local.size(); ++l) {
        const glm::vec3 el = local_irradiance(L.local_lights[l], r.position, r.normal, dir);
        if (el != glm::vec3(0.0f)) lo += el * (brdf(dir) * L.local[l].visibility(r.position, r.normal));
      }
      if (L.sun) {
        const float c = glm::dot(r.normal, L.sun_map.dir);
        if (c > 0.0f) lo += L.sun_irradiance * (c * brdf(L.sun_map.dir) * L.sun_map.visibility(r.position, r.normal));
      }
      if (!sky_e.empty()) {
        lo += sky_e[i] * ((1.0f - r.glossy) / kPi);
        if (r.glossy > 0.0f) lo += r.glossy * L.sky_radiance(r.reflect) * (std::max(0.0f, glm::dot(r.normal, r.reflect)) * sky_v[i].x);
      }
      img.rgb[i] = g.albedo[i] * lo;
    }
  });
  ctx.record().bytes = np * sizeof(glm::vec3);
  ctx.put<Image>(render::kDirect, std::move(img));
}

// The large resources of a frame: proxies and voxels grow with proxy_count and grid, the depth
// maps with the lights, the lists with the marching pixels (a list holds at most the window's rays
// and never more than the grid's cells), the gathered light and the images with the resolution.
std::vector<render::MemoryItem> memory_items(const scene::Scene& scene, const render::ParamSet& params, int w, int h) {
  const Settings s = read_settings(params);
  std::vector<render::MemoryItem> m;
  auto host = [&](std::string name, std::size_t bytes, const char* pass, bool transient = false) {
    m.push_back({std::move(name), bytes, render::MemoryPlace::Host, pass, transient, false, false});
  };
  const auto n = static_cast<std::size_t>(s.proxy_count * 1.05) + 64;  // the roulette's spread stays far below 5 %
  const std::size_t cells = static_cast<std::size_t>(s.grid) * s.grid * s.grid;
  const std::size_t grid_bytes = (cells + 1) * 4 + n * 4 + cells * (5 * sizeof(glm::vec3));
  host(kProxies, n * 4 * sizeof(glm::vec3) + grid_bytes, "proxies");
  host(kVpls, n * 4 * sizeof(glm::vec3) + grid_bytes, "light_vpls");
  const std::size_t maps = scene.lights.size() + (s.environment ? 1 : 0);
  const std::size_t face = static_cast<std::size_t>(s.shadow_map_size) * s.shadow_map_size * sizeof(float);
  host(kLightMaps, scene.lights.size() * 6 * face + (s.environment ? face : 0), "light_maps");
  if (maps) host("point_voxels depth map scratch", 6 * face, "light_maps", true);
  const std::size_t mp = render::pixel_count(render::scaled_size(w, s.march_scale), render::scaled_size(h, s.march_scale));
  const std::size_t window = static_cast<std::size_t>(2 * s.filter.radius_x + 1) * (2 * s.filter.radius_y + 1);
  host(kMarchGBuffer, render::gbuffer_bytes(render::scaled_size(w, s.march_scale), render::scaled_size(h, s.march_scale)), "march_gbuffer");
  host(kLists, mp * (static_cast<std::size_t>(s.rays) * 4 + 4 + 2 * sizeof(glm::vec3)), "march");
  host(kFiltered, mp * (std::min(window * s.rays, cells) * 4 + 4 + 2 * sizeof(glm::vec3)), "filter");
  if (s.indirect) {
    const int gw = render::scaled_size(w, s.gather_scale), gh = render::scaled_size(h, s.gather_scale);
    host(kGatherGBuffer, render::gbuffer_bytes(gw, gh), "gather_gbuffer");
    host(kGathered, render::pixel_count(gw, gh) * sizeof(Gathered), "gather");
    host(render::kIndirect, 3 * render::image_bytes(w, h), "indirect");
  }
  host(render::kDirect, 3 * render::image_bytes(w, h), "direct");
  return m;
}

class PointVoxels final : public render::Technique {
 public:
  std::string name() const override { return "point_voxels"; }
  std::string description() const override {
    return "point proxies hashed into voxels, sparse shadow rays, the visibility filter, VPL and SH gathering with "
           "glossy indirect (paper 002, Chen et al. 2014)";
  }
  std::vector<ParamDesc> params() const override { return point_voxels::params(); }
  std::vector<render::ExperimentDef> experiments() const override { return point_voxels::experiments(); }
  std::vector<render::MemoryItem> estimate_memory(const scene::Scene& scene, const render::ParamSet& params, int width,
                                                  int height) const override {
    return memory_items(scene, params, width, height);
  }

  render::PassGraph plan(const scene::Scene& scene, const render::ParamSet& p, std::set<std::string>& empty) override {
    const Settings s = read_settings(p);
    render::add_scene_facts(scene, empty);
    if (!s.indirect) empty.insert(kIndirectEnabled);
    auto cache = sky_cache_;
    const auto cpu = render::host_impl;
    render::PassGraph g;
    g.add_input(render::kScene);
    g.add_input(kIndirectEnabled);
    render::add_gbuffer_pass(g);
    g.add({"proxies", {render::kScene}, {}, {kProxies},
           "point proxies by area with Russian roulette, Halton barycentrics, posed; hashed (eq. 1) and sorted into voxels",
           cpu([s](FrameContext& c) { pass_proxies(s, c); })});
    g.add({"light_maps", {render::kScene}, {}, {kLightMaps}, "depth maps of the local lights and the sun (Figure 2a); the sky's SH",
           cpu([s, cache](FrameContext& c) { pass_light_maps(s, c, *cache); })});
    g.add({"light_vpls", {kProxies, kLightMaps, kIndirectEnabled}, {}, {kVpls},
           "the proxies' energy as VPLs (Figure 2a) and each voxel's order-2 SH (eqs. 2-3)",
           cpu([s](FrameContext& c) { pass_light_vpls(s, c); })});
    g.add({"march_gbuffer", {render::kGBuffer}, {}, {kMarchGBuffer}, "the marching G-buffer (every march_scale-th display pixel)",
           cpu([s](FrameContext& c) {
             c.put<GBuffer>(kMarchGBuffer, subsample(c.get<GBuffer>(render::kGBuffer), s.march_scale));
             c.record().bytes = render::gbuffer_bytes(c.get<GBuffer>(kMarchGBuffer).width, c.get<GBuffer>(kMarchGBuffer).height);
           })});
    g.add({"gather_gbuffer", {render::kGBuffer, kIndirectEnabled}, {}, {kGatherGBuffer}, "the gathering G-buffer (every gather_scale-th display pixel)",
           cpu([s](FrameContext& c) {
             c.put<GBuffer>(kGatherGBuffer, subsample(c.get<GBuffer>(render::kGBuffer), s.gather_scale));
             c.record().bytes = render::gbuffer_bytes(c.get<GBuffer>(kGatherGBuffer).width, c.get<GBuffer>(kGatherGBuffer).height);
           })});
    g.add({"march", {kMarchGBuffer, kProxies}, {kLightMaps}, {kLists},
           "sparse shadow rays march the voxels, ray-disc tests, first hit ends a ray: the visible voxels per pixel (section 3.1)",
           cpu([s](FrameContext& c) { pass_march(s, c); })});
    g.add({"filter", {kMarchGBuffer, kLists}, {}, {kFiltered},
           "visibility filter: union of the neighbours' lists under the depth and normal constraints (eq. 4)",
           cpu([s](FrameContext& c) { pass_filter(s, c); })});
    g.add({"gather", {kGatherGBuffer, kMarchGBuffer, kFiltered, kVpls}, {}, {kGathered},
           "diffuse and glossy indirect from the four neighbours' lists, near voxels by VPL, far ones by SH (eqs. 5-6)",
           cpu([s](FrameContext& c) { pass_gather(s, c); })});
    g.add({"indirect", {render::kGBuffer, kGatherGBuffer, kGathered}, {}, {render::kIndirect},
           "bilateral upsampling of the gathered light to display resolution, times the Phong terms",
           cpu([](FrameContext& c) { pass_indirect(c); })});
    g.add({"direct", {render::kGBuffer, kLightMaps}, {kFiltered, kMarchGBuffer}, {render::kDirect},
           "local lights and sun through their depth maps, the sky through the filtered escaped rays",
           cpu([](FrameContext& c) { pass_direct(c); })});
    render::add_compose_pass(g);
    return g;
  }

 private:
  std::shared_ptr<common::SharedCache<std::string, std::vector<glm::vec3>>> sky_cache_ =
      std::make_shared<common::SharedCache<std::string, std::vector<glm::vec3>>>();
};

}  // namespace

std::unique_ptr<render::Technique> create() { return std::make_unique<PointVoxels>(); }

}  // namespace softgi::techniques::point_voxels
