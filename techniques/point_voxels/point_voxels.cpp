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
#include "pv_passes.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/vertex_image.hpp"
#include "softgi/sh/sh.hpp"
#include "../common/pass_support.hpp"
#include "../common/device_kernels.hpp"
#include "../common/upsample.hpp"

namespace softgi::techniques::point_voxels {

std::vector<render::ExperimentDef> experiments();  // pv_experiments.cpp

using render::FrameContext;
using render::GBuffer;
using softgi::Image;
using render::ParamDesc;

namespace {
constexpr float kPi = 3.14159265358979323846f;

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
  d.push_back(ParamDesc::choice("march_lanes", "discs", {"discs", "rays"},
                                "how a device backend's marching shader spreads rays over a subgroup's lanes: each ray's "
                                "discs across the lanes, the subgroup's rays one after another (as the CPU backend tests a "
                                "cell's discs in vector lanes), or one ray per lane; the same voxels either way"));
  return d;
}

common::DeviceKernelRegistry<DeviceKernels>& device_kernels() {
  static common::DeviceKernelRegistry<DeviceKernels> r;
  return r;
}

}  // namespace

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
  s.march_lanes_discs = p.get_enum("march_lanes") == "discs";
  return s;
}


std::size_t Lights::bytes() const {
  std::size_t b = sun_map.depth.size() * sizeof(float) + sky_sh.size() * sizeof(glm::vec3);
  for (const auto& m : local) b += m.depth.size() * sizeof(float);
  return b;
}

glm::vec3 Lights::sky_radiance(const glm::vec3& w) const {
  float y[kSkyOrder * kSkyOrder];
  sh::eval_basis<float>(kSkyOrder, sh::Vec3<float>{w.x, w.y, w.z}, y);
  glm::vec3 l(0.0f);
  for (int i = 0; i < kSkyOrder * kSkyOrder; ++i) l += sky_sh[i] * y[i];
  return glm::max(l, glm::vec3(0.0f));
}

std::uint32_t pixel_ray_seed(std::size_t i) { return static_cast<std::uint32_t>(mix_hash(i + 1)); }
std::uint32_t proxy_ray_seed(std::size_t sample) { return static_cast<std::uint32_t>(mix_hash(sample * 0x9e3779b97f4a7c15ULL + 17)); }

glm::vec2 ray_sample(int k, int n, std::uint32_t seed) {
  float u = (static_cast<float>(k) + 0.5f) / static_cast<float>(n) + static_cast<float>(seed & 0xffffu) / 65536.0f;
  float v = static_cast<float>(radical_inverse(static_cast<std::uint32_t>(k) + 1, 2)) + static_cast<float>(seed >> 16) / 65536.0f;
  return {u - std::floor(u), v - std::floor(v)};
}

glm::vec3 local_irradiance(const scene::SphericalLight& l, const glm::vec3& p, const glm::vec3& n, glm::vec3& dir) {
  const glm::vec3 w = l.position - p;
  const float d2 = std::max(glm::dot(w, w), 1.0001f * l.radius * l.radius);
  dir = w / std::sqrt(glm::dot(w, w) > 0.0f ? glm::dot(w, w) : 1.0f);
  const float c = glm::dot(n, dir);
  if (c <= 0.0f) return glm::vec3(0.0f);
  return l.radiance * (kPi * l.radius * l.radius / d2 * c);
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

int gather_taps(const Settings& s, const GBuffer& gg, const GBuffer& mg, std::size_t i, GatherTap (&taps)[4], bool& geometric) {
  const float ratio = static_cast<float>(gg.scale) / static_cast<float>(mg.scale);
  const int x = static_cast<int>(i % gg.width), y = static_cast<int>(i / gg.width);
  const float u = (x + 0.5f) * ratio - 0.5f, v = (y + 0.5f) * ratio - 0.5f;
  const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
  const float fx = u - x0, fy = v - y0;
  float wl[4], wg[4];
  int nt = 0;
  for (int j = 0; j < 2; ++j)
    for (int k = 0; k < 2; ++k) {
      const int qx = std::clamp(x0 + k, 0, mg.width - 1), qy = std::clamp(y0 + j, 0, mg.height - 1);
      const std::size_t q = static_cast<std::size_t>(qy) * mg.width + qx;
      if (!mg.hit(q)) continue;
      wl[nt] = (k ? fx : 1.0f - fx) * (j ? fy : 1.0f - fy);
      const float dz = (mg.depth[q] - gg.depth[i]) / (static_cast<float>(s.sigma_depth) * gg.depth[i]);
      const float dn = (1.0f - glm::dot(mg.normal[q], gg.normal[i])) / static_cast<float>(s.sigma_normal);
      wg[nt] = std::exp(-0.5f * (dz * dz + dn * dn));
      taps[nt++].q = q;
    }
  float nc = 0.0f, nl = 0.0f;
  for (int k = 0; k < nt; ++k) {
    nc += wl[k] * wg[k];
    nl += wl[k];
  }
  // No neighbour on this surface (a silhouette the marching buffer does not resolve): the linear
  // weights alone, so the pixel is not left black.
  geometric = nc > 1e-4f * nl;
  const float norm = geometric ? nc : nl;
  if (!(norm > 0.0f)) return 0;
  int used = 0;
  for (int k = 0; k < nt; ++k) {
    const float w = (geometric ? wl[k] * wg[k] : wl[k]) / norm;
    if (w > 0.0f) taps[used++] = {taps[k].q, w};
  }
  return used;
}

std::size_t hit_pixels(const GBuffer& g) {
  std::size_t hits = 0;
  for (std::size_t i = 0; i < g.depth.size(); ++i) hits += g.hit(i);
  return hits;
}

namespace {

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

// --- passes ------------------------------------------------------------------------------------------

void pass_proxies(const Settings& s, FrameContext& ctx) {
  // Sampled once on the scene at t = 0 (triangle and barycentrics), interpolated on this frame's pose.
  const scene::PosedScene rest = ctx.posed.time == 0.0 ? scene::PosedScene{} : scene::evaluate(ctx.scene, 0.0);
  const ProxySampling sampling = sample_point_proxies(ctx.posed.time == 0.0 ? ctx.posed : rest, s.proxy_count);
  auto v = std::make_shared<Posed>();
  v->density = sampling.density;
  v->proxies = pose_proxies(ctx.scene, ctx.posed, sampling, s.disc_scale);
  v->ray_seed.resize(v->proxies.size());
  for (std::size_t i = 0; i < v->ray_seed.size(); ++i) v->ray_seed[i] = proxy_ray_seed(i);
  auto& rec = ctx.record();
  rec.counters["proxies"] = static_cast<double>(v->proxies.size());
  rec.counters["roulette_triangles"] = static_cast<double>(sampling.roulette_triangles);
  rec.counters["disc_radius"] = v->proxies.radius;
  rec.bytes = v->proxies.size() * (4 * sizeof(glm::vec3) + sizeof(std::uint32_t));
  ctx.put<std::shared_ptr<const Posed>>(kProxies, std::move(v));
}

// Eq. 1: the proxies hashed into the grid and sorted by key, with each cell's range.
void pass_voxelize(const Settings& s, FrameContext& ctx) {
  const auto& in = *ctx.get<std::shared_ptr<const Posed>>(kProxies);
  auto v = std::make_shared<Voxels>();
  v->density = in.density;
  v->proxies = in.proxies;
  v->grid = build_voxel_grid(v->proxies, glm::ivec3(s.grid), &v->sample);
  v->ray_seed.resize(v->sample.size());
  for (std::size_t i = 0; i < v->sample.size(); ++i) v->ray_seed[i] = in.ray_seed[v->sample[i]];
  v->diagonal = glm::length(v->grid.cell * glm::vec3(v->grid.dims));
  v->planes = proxy_planes(v->proxies);
  std::size_t occupied = 0;
  for (std::size_t k = 0; k < v->grid.cells(); ++k) occupied += v->grid.start[k + 1] > v->grid.start[k];
  auto& rec = ctx.record();
  rec.counters["voxels"] = static_cast<double>(v->grid.cells());
  rec.counters["voxels_occupied"] = static_cast<double>(occupied);
  rec.bytes = v->proxies.size() * (4 * sizeof(glm::vec3) + 2 * sizeof(std::uint32_t)) + v->grid.bytes() + v->planes.bytes();
  ctx.put<std::shared_ptr<const Voxels>>(kVoxels, std::move(v));
}

// The lights seen from the proxies and the receivers, their depth maps left for `raster`: each local
// light and the sun (its map's frame), the rest of the environment as SH.
std::shared_ptr<Lights> plan_lights(const Settings& s, FrameContext& ctx, SkyCache& sky_cache) {
  auto L = std::make_shared<Lights>();
  for (const auto& l : ctx.posed.lights) {
    CubeDepthMap m;
    m.center = l.position;
    m.size = s.shadow_map_size;
    L->local.push_back(std::move(m));
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
        L->sun_map = ortho_frame(ctx.posed, sd, s.shadow_map_size);
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
  return L;
}

// Figure 2a's depth maps, rasterised in software from the posed triangles.
void pass_light_maps(const Settings& s, FrameContext& ctx, SkyCache& sky_cache) {
  const std::shared_ptr<Lights> L = plan_lights(s, ctx, sky_cache);
  for (auto& m : L->local) m = rasterize_cube_depth(ctx.posed, m.center, s.shadow_map_size, &ctx.pool());
  if (L->sun) L->sun_map = rasterize_ortho_depth(ctx.posed, L->sun_map.dir, s.shadow_map_size, &ctx.pool());
  // The maps go back to the pool at the end of the frame (fresh pages cost a fault each), unless the
  // caller asked for this resource and holds it.
  ctx.on_release([L](render::FramePool& pool) {
    if (L.use_count() > 1) return;
    for (auto& m : L->local) pool.give(std::move(m.depth));
    pool.give(std::move(L->sun_map.depth));
  });
  ctx.record().bytes = L->bytes();
  ctx.put<std::shared_ptr<const Lights>>(kLightMaps, L);
}

// Figure 2a: the VPLs' energy from the lights (depth maps), the sky through marched rays; then
// eqs. 2-3 per voxel.
void pass_light_vpls(const Settings& s, FrameContext& ctx) {
  const auto& in = *ctx.get<std::shared_ptr<const Voxels>>(kVoxels);
  const auto& L = *ctx.get<std::shared_ptr<const Lights>>(kLightMaps);
  auto v = std::make_shared<Voxels>(in);
  PosedProxies& P = v->proxies;
  const std::size_t n = P.size();
  const int k_rays = L.sky ? s.vpl_env_rays : 0;
  std::atomic<std::uint64_t> cells{0}, discs{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const tbb::blocked_range<std::size_t>& r) {
    MarchCount count;
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
        const glm::vec3 o = p + nn * (0.25f * P.radius);
        glm::vec3 sky(0.0f);
        for (int k = 0; k < k_rays; ++k) {
          const glm::vec2 u = ray_sample(k, k_rays, in.ray_seed[i]);
          const glm::vec3 d = cosine_direction(nn, u.x, u.y);
          if (march_ray(in.grid, in.proxies, o, d, 0.5f * P.radius, 1e30f, &in.planes, &count) < 0) sky += L.sky_radiance(d);
        }
        e += sky * (kPi / static_cast<float>(k_rays));
      }
      P.radiance[i] = P.albedo[i] * e / kPi;
    }
    cells += count.cells;
    discs += count.discs;
  });
  accumulate_voxel_sh(v->grid, P);
  set_radiance(v->planes, P);  // positions and normals came with the copy of kVoxels
  auto& rec = ctx.record();
  rec.counters["vpls"] = static_cast<double>(n);
  rec.counters["env_rays"] = static_cast<double>(n) * k_rays;
  rec.counters["env_cells_visited"] = static_cast<double>(cells.load());
  rec.counters["env_discs_in_cells_visited"] = static_cast<double>(discs.load());
  rec.bytes = n * sizeof(glm::vec3) + v->grid.bytes() + v->planes.bytes();
  ctx.put<std::shared_ptr<const Voxels>>(kVpls, std::move(v));
}

// Section 3.1: per marching pixel, `rays` shadow rays; the first voxel each hits joins the list.
void pass_march(const Settings& s, FrameContext& ctx) {
  const auto& g = ctx.get<GBuffer>(kMarchGBuffer);
  const auto& V = *ctx.get<std::shared_ptr<const Voxels>>(kVoxels);
  const Lights* L = ctx.has(kLightMaps) ? ctx.get<std::shared_ptr<const Lights>>(kLightMaps).get() : nullptr;
  const bool sky = L && L->sky;
  auto m = std::make_shared<Marched>();
  const std::size_t np = static_cast<std::size_t>(g.width) * g.height;
  std::vector<std::vector<std::int32_t>> lists(np);
  m->sky.irradiance.assign(np, glm::vec3(0.0f));
  m->sky.escaped.assign(np, 0.0f);
  const float r = V.proxies.radius;
  std::atomic<std::uint64_t> cells{0}, discs{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 64), [&](const tbb::blocked_range<std::size_t>& br) {
    MarchCount count;
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!g.hit(i)) continue;
      const glm::vec3 nn = g.normal[i], o = g.position[i] + nn * (0.25f * r);
      const std::uint32_t seed = pixel_ray_seed(i);
      auto& list = lists[i];
      glm::vec3 e(0.0f);
      int escaped = 0;
      for (int k = 0; k < s.rays; ++k) {
        const glm::vec2 u = ray_sample(k, s.rays, seed);
        const glm::vec3 d = cosine_direction(nn, u.x, u.y);
        const std::int32_t vox = march_ray(V.grid, V.proxies, o, d, 0.5f * r, 1e30f, &V.planes, &count);
        if (vox >= 0) {
          list.push_back(vox);
        } else {
          ++escaped;
          if (sky) e += L->sky_radiance(d);
        }
      }
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
      m->sky.irradiance[i] = e * (kPi / static_cast<float>(s.rays));
      m->sky.escaped[i] = static_cast<float>(escaped) / static_cast<float>(s.rays);
    }
    cells += count.cells;
    discs += count.discs;
  });
  m->lists.width = g.width;
  m->lists.height = g.height;
  m->lists.offset.assign(np + 1, 0);
  for (std::size_t i = 0; i < np; ++i) {
    m->lists.voxel.insert(m->lists.voxel.end(), lists[i].begin(), lists[i].end());
    m->lists.offset[i + 1] = static_cast<std::uint32_t>(m->lists.voxel.size());
  }
  const std::size_t hits = hit_pixels(g);
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(hits);
  rec.counters["rays"] = static_cast<double>(hits) * s.rays;
  rec.counters["list_mean"] = hits ? static_cast<double>(m->lists.voxel.size()) / hits : 0.0;
  rec.counters["cells_visited"] = static_cast<double>(cells.load());
  rec.counters["discs_in_cells_visited"] = static_cast<double>(discs.load());
  rec.bytes = m->bytes();
  ctx.put<std::shared_ptr<const Marched>>(kLists, std::move(m));
}

// Section 3.2, eq. 4; the escaped-ray environment terms are averaged over the same neighbours.
void pass_filter(const Settings& s, FrameContext& ctx) {
  const auto& g = ctx.get<GBuffer>(kMarchGBuffer);
  const auto& in = *ctx.get<std::shared_ptr<const Marched>>(kLists);
  auto m = std::make_shared<Marched>();
  m->lists = visibility_filter(in.lists, g.depth.data(), g.normal.data(), s.filter);
  auto sky = std::make_shared<SkyLight>();
  sky->irradiance.resize(in.sky.irradiance.size());
  sky->escaped.resize(in.sky.escaped.size());
  filter_field(&in.sky.irradiance[0].x, 3, g.width, g.height, g.depth.data(), g.normal.data(), s.filter, &sky->irradiance[0].x);
  filter_field(in.sky.escaped.data(), 1, g.width, g.height, g.depth.data(), g.normal.data(), s.filter, sky->escaped.data());
  const std::size_t hits = hit_pixels(g);
  auto& rec = ctx.record();
  rec.counters["list_mean_before"] = hits ? static_cast<double>(in.lists.voxel.size()) / hits : 0.0;
  rec.counters["list_mean"] = hits ? static_cast<double>(m->lists.voxel.size()) / hits : 0.0;
  rec.bytes = m->bytes() + sky->bytes();
  ctx.put<std::shared_ptr<const SkyLight>>(kFilteredSky, std::move(sky));
  ctx.put<std::shared_ptr<const Marched>>(kFiltered, std::move(m));
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
  std::atomic<std::size_t> unmatched{0}, voxels_gathered{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 64), [&](const tbb::blocked_range<std::size_t>& br) {
    std::size_t block_unmatched = 0, block_voxels = 0;  // counted per block: shared counters per pixel contend
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!gg.hit(i)) continue;
      GatherTap t[4];
      bool geometric = false;
      const int nt = gather_taps(s, gg, mg, i, t, geometric);
      if (!geometric) ++block_unmatched;
      if (nt == 0) continue;
      Receiver r = receiver_at(ctx, gg, i);
      if (s.eq7 && r.glossy > 0.0f) r.eq7_sigma = eq7_sigma(r.ns, static_cast<float>(s.eq7_sigma_scale));
      Gathered acc;
      std::size_t used = 0;
      // The neighbours' lists are sorted and free of repeats: merged in ascending voxel order, a
      // voxel in several of them is gathered once with the sum of their weights.
      std::uint32_t at[4], end[4];
      for (int k = 0; k < nt; ++k) {
        at[k] = F.lists.offset[t[k].q];
        end[k] = F.lists.offset[t[k].q + 1];
      }
      for (;;) {
        bool any = false;
        std::int32_t v = 0;
        for (int k = 0; k < nt; ++k)
          if (at[k] < end[k] && (!any || F.lists.voxel[at[k]] < v)) {
            v = F.lists.voxel[at[k]];
            any = true;
          }
        if (!any) break;
        float w = 0.0f;
        for (int k = 0; k < nt; ++k)
          if (at[k] < end[k] && F.lists.voxel[at[k]] == v) {
            w += t[k].weight;
            ++at[k];
          }
        gather_voxel(V.grid, V.proxies, v, r, near_range, w, acc, &V.planes);
        ++used;
      }
      block_voxels += used;
      (*out)[i] = acc;
    }
    unmatched += block_unmatched;
    voxels_gathered += block_voxels;
  });
  const std::size_t hits = hit_pixels(gg);
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
// depend only on the two buffers' geometry, so they are computed once for all the fields, each given
// as (floats, channels).
// The weights' planes and the fields come from the frame's pool; give_fields hands the fields back.
std::vector<std::vector<float>> upsample_fields(FrameContext& ctx, const GBuffer& coarse, const GBuffer& fine,
                                                const std::vector<std::pair<const float*, int>>& in) {
  render::FramePool& pool = ctx.pool();
  common::UpsampleWeights w =
      common::upsample_weights(common::plane_view(coarse), common::plane_view(fine), common::UpsampleOptions{}, &pool);
  std::vector<std::vector<float>> out;
  for (const auto& [field, channels] : in) {
    out.push_back(pool.take<float>(static_cast<std::size_t>(fine.width) * fine.height * channels, 0.0f));
    common::upsample_apply(w, field, channels, out.back().data());
  }
  common::give(pool, std::move(w));
  return out;
}

void give_fields(FrameContext& ctx, std::vector<std::vector<float>>& fields) {
  for (auto& f : fields) ctx.pool().give(std::move(f));
  fields.clear();
}

glm::vec3 at3(const std::vector<float>& v, std::size_t i) { return {v[3 * i], v[3 * i + 1], v[3 * i + 2]}; }

void pass_indirect(FrameContext& ctx) {
  const auto& fine = ctx.get<GBuffer>(render::kGBuffer);
  const auto& gg = ctx.get<GBuffer>(kGatherGBuffer);
  const auto& gathered = *ctx.get<std::shared_ptr<const std::vector<Gathered>>>(kGathered);
  std::vector<glm::vec3> e = ctx.pool().take_for_overwrite<glm::vec3>(gathered.size());
  std::vector<glm::vec3> sp = ctx.pool().take_for_overwrite<glm::vec3>(gathered.size());
  for (std::size_t i = 0; i < gathered.size(); ++i) {
    e[i] = gathered[i].irradiance;
    sp[i] = gathered[i].glossy_term();
  }
  auto up = upsample_fields(ctx, gg, fine, {{&e[0].x, 3}, {&sp[0].x, 3}});
  Image img = ctx.pool().image(fine.width, fine.height);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, img.rgb.size(), 4096), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!fine.hit(i)) continue;
      const Receiver r = receiver_at(ctx, fine, i);
      img.rgb[i] = fine.albedo[i] * ((1.0f - r.glossy) / kPi * at3(up[0], i) + r.glossy * at3(up[1], i));
    }
  });
  give_fields(ctx, up);
  ctx.pool().give(std::move(e));
  ctx.pool().give(std::move(sp));
  ctx.record().bytes = 2 * img.rgb.size() * sizeof(glm::vec3);
  ctx.put<Image>(render::kIndirect, std::move(img));
}

// The direct term at display resolution: local lights and the sun through their depth maps (as the
// paper's light depth map), the sky through the marching rays' escaped fraction, filtered and
// upsampled like the indirect light.
void pass_direct(FrameContext& ctx) {
  const auto& g = ctx.get<GBuffer>(render::kGBuffer);
  const auto& L = *ctx.get<std::shared_ptr<const Lights>>(kLightMaps);
  std::vector<std::vector<float>> sky;  // irradiance (3 channels), escaped fraction (1)
  if (L.sky && ctx.has(kFilteredSky)) {
    const auto& F = *ctx.get<std::shared_ptr<const SkyLight>>(kFilteredSky);
    sky = upsample_fields(ctx, ctx.get<GBuffer>(kMarchGBuffer), g, {{&F.irradiance[0].x, 3}, {F.escaped.data(), 1}});
  }
  Image img = ctx.pool().image_for_overwrite(g.width, g.height);  // every pixel is written below
  const std::size_t np = img.rgb.size();
  const render::BackgroundFn background = render::environment_background(ctx.scene.environment);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 256), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i < br.end(); ++i) {
      if (!g.hit(i)) {
        img.rgb[i] = background(g.view_dir[i]);
        continue;
      }
      const Receiver r = receiver_at(ctx, g, i);
      auto brdf = [&](const glm::vec3& w) { return (1.0f - r.glossy) / kPi + glossy_lobe(r, w); };
      glm::vec3 lo(0.0f), dir;
      for (std::size_t l = 0; l < L.local.size(); ++l) {
        const glm::vec3 el = local_irradiance(L.local_lights[l], r.position, r.normal, dir);
        if (el != glm::vec3(0.0f)) lo += el * (brdf(dir) * L.local[l].visibility(r.position, r.normal));
      }
      if (L.sun) {
        const float c = glm::dot(r.normal, L.sun_map.dir);
        if (c > 0.0f) lo += L.sun_irradiance * (c * brdf(L.sun_map.dir) * L.sun_map.visibility(r.position, r.normal));
      }
      if (!sky.empty()) {
        lo += at3(sky[0], i) * ((1.0f - r.glossy) / kPi);
        if (r.glossy > 0.0f) lo += r.glossy * L.sky_radiance(r.reflect) * (std::max(0.0f, glm::dot(r.normal, r.reflect)) * sky[1][i]);
      }
      img.rgb[i] = g.albedo[i] * lo;
    }
  });
  give_fields(ctx, sky);
  ctx.record().bytes = np * sizeof(glm::vec3);
  ctx.put<Image>(render::kDirect, std::move(img));
}

// The large resources of a frame: proxies and voxels grow with proxy_count and grid, the depth
// maps with the lights, the lists with the marching pixels (a list holds at most the window's rays
// and never more than the grid's cells), the gathered light and the images with the resolution.
// Device items: the buffers of the Vulkan kernels (pv_vulkan.cpp, pv_depth_vulkan.cpp), by the names
// they allocate them under; the lists there are bitsets over the cells.
std::vector<render::MemoryItem> memory_items(const scene::Scene& scene, const render::ParamSet& params, int w, int h) {
  using render::MemoryPlace;
  const Settings s = read_settings(params);
  std::vector<render::MemoryItem> m;
  auto host = [&](std::string name, std::size_t bytes, const char* pass, bool transient = false, bool host_only = false) {
    m.push_back({std::move(name), bytes, MemoryPlace::Host, pass, transient, false, host_only});
  };
  auto device = [&](std::string name, std::size_t bytes, const char* pass) {
    m.push_back({std::move(name), bytes, MemoryPlace::Device, pass, false, true, false});
  };
  const auto n = static_cast<std::size_t>(s.proxy_count * 1.05) + 64;  // the roulette's spread stays far below 5 %
  const std::size_t cells = static_cast<std::size_t>(s.grid) * s.grid * s.grid;
  const std::size_t grid_bytes = (cells + 1) * 4 + n * 4 + cells * (5 * sizeof(glm::vec3));
  host(kProxies, n * (4 * sizeof(glm::vec3) + 4), "proxies");
  host(kVoxels, n * (4 * sizeof(glm::vec3) + 8 + 9 * sizeof(float)) + grid_bytes, "voxelize", false, true);
  host(kVpls, n * (4 * sizeof(glm::vec3) + 8 + 9 * sizeof(float)) + grid_bytes, "light_vpls", false, true);
  const std::size_t face = static_cast<std::size_t>(s.shadow_map_size) * s.shadow_map_size * sizeof(float);
  const std::size_t maps = scene.lights.size() * 6 * face + (s.environment ? face : 0);
  host(kLightMaps, maps, "light_maps");
  if (maps) host("point_voxels depth map scratch", 6 * face, "light_maps", true, true);
  const int mw = render::scaled_size(w, s.march_scale), mh = render::scaled_size(h, s.march_scale);
  const std::size_t mp = render::pixel_count(mw, mh);
  const std::size_t window = static_cast<std::size_t>(2 * s.filter.radius_x + 1) * (2 * s.filter.radius_y + 1);
  host(kMarchGBuffer, render::gbuffer_bytes(mw, mh), "march_gbuffer");
  host(kLists, mp * (static_cast<std::size_t>(s.rays) * 4 + 4 + 4 * sizeof(float)), "march", false, true);
  host(kFiltered, mp * (std::min(window * s.rays, cells) * 4 + 4), "filter", false, true);
  host(kFilteredSky, mp * 4 * sizeof(float), "filter");
  const int gw = render::scaled_size(w, s.gather_scale), gh = render::scaled_size(h, s.gather_scale);
  const std::size_t gp = render::pixel_count(gw, gh);
  if (s.indirect) {
    host(kGatherGBuffer, render::gbuffer_bytes(gw, gh), "gather_gbuffer");
    host(kGathered, gp * sizeof(Gathered), "gather");
    host(render::kIndirect, 3 * render::image_bytes(w, h), "indirect");
  }
  host(render::kDirect, 3 * render::image_bytes(w, h), "direct");
  // The Vulkan kernels' buffers (64-byte proxies, 32-byte march items, a march batch at most 128 MiB).
  std::size_t triangles = 0;
  for (const auto& node : scene.nodes)
    if (node.mesh >= 0 && node.mesh < static_cast<int>(scene.meshes.size())) triangles += scene.meshes[node.mesh].triangles.size();
  const std::size_t words = (cells + 31) / 32, item = 32, batch = std::size_t{128} << 20;
  device("point_voxels proxies", n * 64, "voxelize");
  device("point_voxels sorted proxies", n * 64, "voxelize");
  device("point_voxels cell ranges", (cells + 1) * 4, "voxelize");
  device("point_voxels voxel counts", cells * 4, "voxelize");
  std::size_t sorted = 2048;  // the sort's (key, sampling index) pairs, a power of two from one block (pv_vulkan.cpp)
  while (sorted < n) sorted *= 2;
  device("point_voxels sort keys", sorted * 8, "voxelize");
  device("point_voxels triangle corners", triangles * 3 * 16, "light_maps");
  device("point_voxels depth map texels", 6 * face, "light_maps");
  device("point_voxels cube depth maps", scene.lights.size() * 6 * face, "light_maps");
  device("point_voxels sun depth map", face + 64, "light_maps");
  device("point_voxels VPLs", n * 64, "light_vpls");
  device("point_voxels VPL cell ranges", (cells + 1) * 4, "light_vpls");
  device("point_voxels VPL radiance", n * 16, "light_vpls");
  device("point_voxels voxel SH", cells * 64, "light_vpls");
  device("point_voxels march items",
         std::min(batch, std::max(n * static_cast<std::size_t>(s.vpl_env_rays), mp * static_cast<std::size_t>(s.rays)) * item), "march");
  device("point_voxels marching pixels", mp * 48, "march");
  device("point_voxels voxel bitsets", mp * words * 4, "march");
  device("point_voxels sky fields", mp * 16, "march");
  device("point_voxels filtered bitsets", mp * words * 4, "filter");
  device("point_voxels filtered sky fields", mp * 16, "filter");
  if (s.indirect) {
    device("point_voxels gathering pixels", gp * 64, "gather");
    device("point_voxels gathered light", gp * 48, "gather");
    device("point_voxels gathering state", gp * 32, "gather");
  }
  return m;
}

// A device kernel as the pass function of a graph (none when the backend has no such kernel).
render::PassFn bind(const std::function<void(const Settings&, FrameContext&)>& kernel, const Settings& s) {
  if (!kernel) return {};
  return [kernel, s](FrameContext& c) { kernel(s, c); };
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
  std::vector<std::string> overlay_outputs() const override { return {kVoxels}; }
  // The frame's point proxies (discs of the ray-disc test's radius) and its occupied voxels.
  render::OverlayGeometry overlay(const render::FrameResult& frame) const override {
    render::OverlayGeometry g;
    g.scene_spheres = false;  // its proxies are sampled from the meshes, not the scene's sphere sets
    const auto it = frame.resources.find(kVoxels);
    if (it == frame.resources.end()) return g;
    const auto* v = std::any_cast<std::shared_ptr<const Voxels>>(&it->second);
    if (!v || !*v) return g;
    const Voxels& vox = **v;
    g.points_label = "point proxies";
    g.boxes_label = "occupied voxels";
    g.points.reserve(vox.proxies.size());
    for (const auto& p : vox.proxies.position) g.points.push_back({p, vox.proxies.radius});
    const VoxelGrid& grid = vox.grid;
    for (int z = 0; z < grid.dims.z; ++z)
      for (int y = 0; y < grid.dims.y; ++y)
        for (int x = 0; x < grid.dims.x; ++x) {
          const std::uint32_t k = grid.hash({x, y, z});
          if (k + 1 >= grid.start.size() || grid.start[k + 1] == grid.start[k]) continue;
          const glm::vec3 lo = grid.lo + glm::vec3(x, y, z) * grid.cell;
          g.boxes.push_back({lo, lo + grid.cell});
        }
    return g;
  }
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
    const auto kernels = device_kernels().all();
    render::PassGraph g;
    g.add_input(render::kScene);
    g.add_input(kIndirectEnabled);
    render::add_gbuffer_pass(g);
    g.add({"proxies", {render::kScene}, {}, {kProxies},
           "point proxies by area with Russian roulette, Halton barycentrics, posed on this frame's meshes (section 3.1)",
           cpu([s](FrameContext& c) { pass_proxies(s, c); })});
    g.add({"voxelize", {kProxies}, {}, {kVoxels}, "the proxies hashed into voxels (eq. 1), sorted by key, cell ranges",
           common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_voxelize(s, c); }), kernels,
                                               [s](const DeviceKernels& k) { return bind(k.voxelize, s); })});
    g.add({"light_maps", {render::kScene}, {}, {kLightMaps}, "depth maps of the local lights and the sun (Figure 2a); the sky's SH",
           common::with_kernels<DeviceKernels>(cpu([s, cache](FrameContext& c) { pass_light_maps(s, c, *cache); }), kernels,
                                               [s, cache](const DeviceKernels& k) -> render::PassFn {
                                                 if (!k.light_maps) return {};
                                                 return [s, cache, raster = k.light_maps](FrameContext& c) { raster(s, c, plan_lights(s, c, *cache)); };
                                               })});
    g.add({"light_vpls", {kVoxels, kLightMaps, kIndirectEnabled}, {}, {kVpls},
           "the proxies' energy as VPLs (Figure 2a) and each voxel's order-2 SH (eqs. 2-3)",
           common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_light_vpls(s, c); }), kernels,
                                               [s](const DeviceKernels& k) { return bind(k.light_vpls, s); })});
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
    g.add({"march", {kMarchGBuffer, kVoxels}, {kLightMaps}, {kLists},
           "sparse shadow rays march the voxels, ray-disc tests, first hit ends a ray: the visible voxels per pixel (section 3.1)",
           common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_march(s, c); }), kernels,
                                               [s](const DeviceKernels& k) { return bind(k.march, s); })});
    g.add({"filter", {kMarchGBuffer, kLists}, {}, {kFiltered, kFilteredSky},
           "visibility filter: union of the neighbours' lists under the depth and normal constraints (eq. 4)",
           common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_filter(s, c); }), kernels,
                                               [s](const DeviceKernels& k) { return bind(k.filter, s); })});
    g.add({"gather", {kGatherGBuffer, kMarchGBuffer, kFiltered, kVpls}, {}, {kGathered},
           "diffuse and glossy indirect from the four neighbours' lists, near voxels by VPL, far ones by SH (eqs. 5-6)",
           common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_gather(s, c); }), kernels,
                                               [s](const DeviceKernels& k) { return bind(k.gather, s); })});
    g.add({"indirect", {render::kGBuffer, kGatherGBuffer, kGathered}, {}, {render::kIndirect},
           "bilateral upsampling of the gathered light to display resolution, times the Phong terms",
           cpu([](FrameContext& c) { pass_indirect(c); })});
    g.add({"direct", {render::kGBuffer, kLightMaps}, {kFilteredSky, kMarchGBuffer}, {render::kDirect},
           "local lights and sun through their depth maps, the sky through the filtered escaped rays",
           cpu([](FrameContext& c) { pass_direct(c); })});
    render::add_compose_pass(g);
    return g;
  }

 private:
  std::shared_ptr<SkyCache> sky_cache_ = std::make_shared<SkyCache>();
};

}  // namespace

std::unique_ptr<render::Technique> create() { return std::make_unique<PointVoxels>(); }

void register_device_kernels(const std::string& backend, DeviceKernels kernels) { device_kernels().add(backend, std::move(kernels)); }

}  // namespace softgi::techniques::point_voxels
