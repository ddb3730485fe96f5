// Point-proxy voxels (paper 002) on the Vulkan backend against the CPU backend, pass by pass: the CPU
// graph runs up to a pass, then the pass runs on both backends from the same inputs and their
// outputs are compared (the CPU output then goes back, so every pass starts from the CPU's inputs).
// A second frame runs every GPU pass on Vulkan in sequence, its intermediates left on the device,
// and its images are compared with the CPU frame's. Scenes: cornell_glossy (a local light through
// its cube depth map, a glossy floor, no sky), spheres (sky and sun: environment rays for the VPLs
// and the marching pixels), character at t = 0.5 s (skinned), atrium (the Sponza stand-in's grid),
// glossy_sweep with eq. 7 (Ns 10 to 50: the weighted lobe, compiled only for frames that use it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "../../techniques/point_voxels/pv_passes.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/point_voxels.hpp"
#include "pv_shared.h"  // march.comp's workgroup size
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace pv = softgi::techniques::point_voxels;

namespace {

using softgi::testing::compare_rows;
using softgi::testing::Compared;

// --- Tolerances ------------------------------------------------------------------------------------
// light_maps: the device's rasteriser against the CPU's software one, on the same projections (texel
// centres, perspective-correct 1/z for the cube faces, depth along the light for the directional map;
// depth_raster.vert). They differ where a texel centre lies on a triangle's edge (the device's
// top-left rule covers it on one side only, the CPU on both; a silhouette edge then leaves it
// empty on the device) and by the float rounding of the interpolation: texels whose depths differ by
// more than kDepthRelTol, as a share of all texels. The directional map stores its depth in [0, 1]
// of the scene's depth range (2^-24 of it) before it is turned back.
constexpr double kDepthRelTol = 1e-4;
constexpr double kDepthTexelShare = 0.01;
// voxelize: the keys are floor((p - lo) * (1 / cell)) on both backends (multiplication and
// subtraction are correctly rounded in Vulkan), so every proxy lands in the same cell and the cell
// ranges are equal; the device sorts by (key, sampling index), so the order within each cell is the
// CPU's stable sort's too. Exact, slot for slot.
//
// light_vpls: per VPL the same depth-map texels and the same environment rays, but each ray's
// direction is computed with Vulkan's division and inverse square root (2.5 and 2 ulp) and the
// Taylor sin/cos, and a driver may fuse multiply-adds: a ray that grazes a disc's rim may hit on one
// backend and escape on the other, which changes that VPL's sky term by one ray's share
// (1 / vpl_env_rays). Such VPLs are counted (kVplFlipShare), the others agree to float rounding of
// their sums (kVplRelTol, relative to the VPL's radiance, floored at kFloorFraction of the largest).
// Observed on lavapipe: no flip on the four scenes; rounding at most 1e-6.
constexpr double kVplRelTol = 1e-4;
constexpr double kVplFlipShare = 0.01;
// Voxel SH and centroids of the cells without a flipped VPL: the same terms summed in the same order,
// each VPL's radiance within kVplRelTol's rounding and the products perhaps fused on the device; the
// centroid's division is Vulkan's (2.5 ulp). Relative to the voxel's largest coefficient, floored at
// kFloorFraction of the grid's.
constexpr double kVoxelRelTol = 1e-4;
//
// march: the same rays, with the grazing flips above (a flipped ray adds or drops one voxel of a
// pixel's list, or moves its sky light by one ray's share): the share of pixels whose list differs.
// Observed: none.
constexpr double kListFlipShare = 0.01;
// filter: bit operations on the same lists with the same float depth and normal comparisons: exact,
// but for neighbours whose normals' dot product sits on the threshold within its rounding (a fused
// dot product). Observed: none.
constexpr double kFilterFlipShare = 0.005;
// The filtered sky fields: sums over the same neighbours in the same order, one division (2.5 ulp).
// Observed: exact.
constexpr double kFieldRelTol = 1e-5;
// The marched sky light of pixels whose lists agree: the escaped rays' sky radiance (the closed-form
// order-3 basis in float against the CPU's recurrence) summed in ray order. Observed: 2.7e-7.
constexpr double kMarchSkyRelTol = 1e-5;
// gather: the same lists, VPLs and SH in the CPU's order (uploaded from the CPU's voxels); float
// exp, pow and division rounding in the weights and the Phong lobe. Vulkan bounds pow only as
// exp2(y log2 x), whose log2 is accurate to 2^-21 absolute near 1: at ns = 50 the lobe may differ by
// 50 * 2^-21 * ln 2 ~ 2e-5 relative. Per gathering pixel, relative to its largest channel, floored at
// kFloorFraction of the image's. Observed on lavapipe: 2.3e-6.
constexpr double kGatherRelTol = 2e-4;
// The whole frame on Vulkan against the CPU frame: the flips above, passed on through the VPLs and
// lists, averaged by the filter, the gathering and the upsampling. Bound on the relative mean
// squared error of each image (sum of squared differences over sum of squares), far below the
// technique's own error against the path tracer (relMSE 1e-2 on these scenes). Without flips only
// rounding remains (observed: 1e-14); a flipped ray moves one VPL by a ray's share, or one marching
// pixel's list by a voxel, which the filter and the gathering average over hundreds of terms.
constexpr double kFrameRelMse = 1e-6;

struct SceneCase {
  const char* scene;
  double time;
  std::vector<std::pair<const char*, const char*>> params;
};
const SceneCase kScenes[] = {
    {"cornell_glossy", 0.0, {{"proxy_count", "6000"}, {"grid", "6"}, {"rays", "32"}, {"march_scale", "4"}, {"shadow_map_size", "128"}}},
    {"spheres", 0.0, {{"proxy_count", "4000"}, {"rays", "16"}, {"march_scale", "4"}, {"shadow_map_size", "128"}, {"vpl_env_rays", "8"}}},
    {"character", 0.5, {{"proxy_count", "4000"}, {"rays", "16"}, {"march_scale", "4"}, {"shadow_map_size", "128"}}},
    {"glossy_sweep", 0.0, {{"proxy_count", "4000"}, {"rays", "16"}, {"march_scale", "4"}, {"shadow_map_size", "128"}, {"glossy_weight", "eq7"}}},
    {"atrium", 0.0, {{"proxy_count", "8000"}, {"grid", "20"}, {"rays", "16"}, {"march_scale", "4"}, {"shadow_map_size", "128"}}},
};

std::vector<float> flatten(const std::vector<glm::vec3>& v) {
  std::vector<float> out;
  out.reserve(3 * v.size());
  for (const auto& x : v) out.insert(out.end(), {x.x, x.y, x.z});
  return out;
}

// The shared passes (the G-buffer) have no host implementation of their own: the CPU backend's.
std::string host_backend(const render::PassDesc& pass) {
  return pass.impl.empty() ? std::string(backends::cpu::kBackendName) : std::string(render::kHostImpl);
}

render::ParamSet params_for(render::Technique& tech, const SceneCase& sc) {
  render::ParamSet p = render::default_params(tech);
  for (const auto& [k, v] : sc.params) p.set(k, v);
  return p;
}

render::RenderRequest request(double time) {
  render::RenderRequest req;
  req.width = req.height = 96;
  req.time = time;
  req.outputs = {render::kFinal, render::kDirect, render::kIndirect};
  return req;
}

// Per sample index, the sorted position of that proxy.
std::vector<std::size_t> by_sample(const pv::Voxels& v) {
  std::vector<std::size_t> at(v.sample.size());
  for (std::size_t i = 0; i < v.sample.size(); ++i) at.at(v.sample[i]) = i;
  return at;
}

// Texels whose depths differ beyond kDepthRelTol (relative to the CPU's; inf against a finite depth
// counts), over all texels.
void compare_maps(const std::vector<float>& c, const std::vector<float>& g, std::size_t& differ, std::size_t& texels, std::size_t& lit) {
  ASSERT_EQ(c.size(), g.size());
  for (std::size_t i = 0; i < c.size(); ++i) {
    ++texels;
    lit += std::isfinite(c[i]);
    if (std::isinf(c[i]) || std::isinf(g[i])) {
      differ += std::isinf(c[i]) != std::isinf(g[i]);
      continue;
    }
    differ += std::abs(static_cast<double>(c[i]) - g[i]) > kDepthRelTol * std::abs(c[i]);
  }
}

void compare_lights(const pv::Lights& c, const pv::Lights& g) {
  ASSERT_EQ(c.local.size(), g.local.size());
  EXPECT_EQ(c.sun, g.sun);
  EXPECT_EQ(c.sky, g.sky);
  std::size_t differ = 0, texels = 0, lit = 0;
  for (std::size_t l = 0; l < c.local.size(); ++l) compare_maps(c.local[l].depth, g.local[l].depth, differ, texels, lit);
  if (c.sun) compare_maps(c.sun_map.depth, g.sun_map.depth, differ, texels, lit);
  EXPECT_GT(lit, 0u) << "some texel sees a surface";
  EXPECT_LE(differ, kDepthTexelShare * texels) << "depth-map texels that differ";
  std::printf("[pv parity]   light_maps: %zu of %zu texels differ (%zu lit)\n", differ, texels, lit);
}

void compare_voxelize(const pv::Voxels& c, const pv::Voxels& g) {
  ASSERT_EQ(c.proxies.size(), g.proxies.size());
  EXPECT_EQ(c.grid.lo, g.grid.lo);
  EXPECT_EQ(c.grid.cell, g.grid.cell);
  EXPECT_EQ(c.grid.dims, g.grid.dims);
  EXPECT_EQ(c.grid.start, g.grid.start) << "cell ranges";
  const auto gc = by_sample(c), gg = by_sample(g);
  std::size_t moved = 0;
  for (std::size_t s = 0; s < gc.size(); ++s) {
    const std::size_t a = gc[s], b = gg[s];
    moved += c.grid.key[a] != g.grid.key[b];
    EXPECT_EQ(c.proxies.position[a], g.proxies.position[b]);
    EXPECT_EQ(c.ray_seed[a], g.ray_seed[b]);
  }
  EXPECT_EQ(moved, 0u) << "proxies in another cell";
  EXPECT_EQ(c.sample, g.sample) << "the sorted order (sampling order within each cell)";
  // Every sorted proxy's key is its cell's: the ranges and the order agree.
  for (std::size_t k = 0; k < g.grid.cells(); ++k)
    for (std::uint32_t i = g.grid.start[k]; i < g.grid.start[k + 1]; ++i) ASSERT_EQ(g.grid.key[i], k);
  std::printf("[pv parity]   voxelize: %zu proxies, %zu cells, all in the same cell\n", c.proxies.size(), c.grid.cells());
}

void compare_vpls(const pv::Voxels& c, const pv::Voxels& g) {
  ASSERT_EQ(c.proxies.size(), g.proxies.size());
  const auto gc = by_sample(c), gg = by_sample(g);
  std::vector<float> a, b;
  for (std::size_t s = 0; s < gc.size(); ++s) {
    const glm::vec3 x = c.proxies.radiance[gc[s]], y = g.proxies.radiance[gg[s]];
    a.insert(a.end(), {x.x, x.y, x.z});
    b.insert(b.end(), {y.x, y.y, y.z});
  }
  double scale = 0.0;
  for (float v : a) scale = std::max(scale, static_cast<double>(v));
  ASSERT_GT(scale, 0.0) << "the VPLs are lit";
  std::size_t flipped = 0;
  double worst = 0.0;
  std::vector<bool> flipped_cell(c.grid.cells(), false);
  for (std::size_t i = 0; i < gc.size(); ++i) {
    double mag = 0.0, diff = 0.0;
    for (int k = 0; k < 3; ++k) {
      mag = std::max(mag, static_cast<double>(std::abs(a[3 * i + k])));
      diff = std::max(diff, std::abs(static_cast<double>(a[3 * i + k]) - b[3 * i + k]));
    }
    const double rel = diff / std::max(mag, softgi::testing::kFloorFraction * scale);
    if (rel > kVplRelTol) {
      ++flipped;
      flipped_cell[c.grid.key[gc[i]]] = true;
    } else {
      worst = std::max(worst, rel);
    }
  }
  EXPECT_LE(flipped, kVplFlipShare * gc.size()) << "VPLs beyond rounding";
  std::vector<float> sc, sg;
  for (std::size_t k = 0; k < c.grid.cells(); ++k) {
    if (flipped_cell[k]) continue;
    for (int m = 0; m < 4; ++m)
      for (int ch = 0; ch < 3; ++ch) {
        sc.push_back(c.grid.sh[k][m][ch]);
        sg.push_back(g.grid.sh[k][m][ch]);
      }
  }
  const Compared dsh = compare_rows(sc, sg, 12);
  EXPECT_LE(dsh.worst, kVoxelRelTol) << "voxel " << dsh.worst_index << " SH";
  std::vector<float> cc = flatten(c.grid.centroid), cg = flatten(g.grid.centroid);
  const Compared dc = compare_rows(cc, cg, 3);
  EXPECT_LE(dc.worst, kVoxelRelTol) << "voxel " << dc.worst_index << " centroid (sums of the same positions in another order)";
  std::printf("[pv parity]   light_vpls: %zu of %zu VPLs beyond rounding (%.2g %%), worst other %.3g; voxel SH %.3g, centroids %.3g\n", flipped,
              gc.size(), 100.0 * flipped / gc.size(), worst, dsh.worst, dc.worst);
}

// Pixels whose lists differ.
void compare_marched(const pv::Marched& c, const pv::Marched& g, double flip_share, const char* what) {
  ASSERT_EQ(c.lists.offset.size(), g.lists.offset.size());
  const std::size_t np = c.lists.offset.size() - 1;
  std::size_t differ = 0;
  for (std::size_t p = 0; p < np; ++p)
    differ += !std::equal(c.lists.voxel.begin() + c.lists.offset[p], c.lists.voxel.begin() + c.lists.offset[p + 1],
                          g.lists.voxel.begin() + g.lists.offset[p], g.lists.voxel.begin() + g.lists.offset[p + 1]);
  EXPECT_LE(differ, flip_share * np) << what << ": pixels whose lists differ";
  EXPECT_GT(c.lists.voxel.size(), 0u) << what << ": some pixel sees a voxel";
  std::printf("[pv parity]   %s: %zu of %zu pixels' lists differ, %zu entries on the CPU, %zu on Vulkan\n", what, differ, np,
              c.lists.voxel.size(), g.lists.voxel.size());
}

// The largest per-pixel relative difference of two sky lights (compare_rows over irradiance and escaped fraction).
double compare_sky(const pv::SkyLight& c, const pv::SkyLight& g) {
  EXPECT_EQ(c.irradiance.size(), g.irradiance.size());
  std::vector<float> fc, fg;
  for (std::size_t p = 0; p < c.irradiance.size() && p < g.irradiance.size(); ++p) {
    fc.insert(fc.end(), {c.irradiance[p].x, c.irradiance[p].y, c.irradiance[p].z, c.escaped[p]});
    fg.insert(fg.end(), {g.irradiance[p].x, g.irradiance[p].y, g.irradiance[p].z, g.escaped[p]});
  }
  return fc.empty() ? 0.0 : compare_rows(fc, fg, 4).worst;
}

void compare_gathered(const std::vector<pv::Gathered>& c, const std::vector<pv::Gathered>& g) {
  ASSERT_EQ(c.size(), g.size());
  std::vector<float> a, b;
  for (std::size_t i = 0; i < c.size(); ++i) {
    a.insert(a.end(), {c[i].irradiance.x, c[i].irradiance.y, c[i].irradiance.z, c[i].glossy_term().x, c[i].glossy_term().y,
                       c[i].glossy_term().z});
    b.insert(b.end(), {g[i].irradiance.x, g[i].irradiance.y, g[i].irradiance.z, g[i].glossy_term().x, g[i].glossy_term().y,
                       g[i].glossy_term().z});
    EXPECT_EQ(c[i].eq7, g[i].eq7);
  }
  const Compared d = compare_rows(a, b, 6);
  EXPECT_LE(d.worst, kGatherRelTol) << "gathering pixel " << d.worst_index;
  std::printf("[pv parity]   gather: %zu pixels, worst relative difference %.3g (tolerance %.1g)\n", c.size(), d.worst, kGatherRelTol);
}

double rel_mse(const Image& a, const Image& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double d = static_cast<double>(a.rgb[i][c]) - b.rgb[i][c];
      num += d * d;
      den += static_cast<double>(a.rgb[i][c]) * a.rgb[i][c];
    }
  return den > 0.0 ? num / den : (num > 0.0 ? 1.0 : 0.0);
}

const std::vector<std::string> kGpuPasses = {"voxelize", "light_maps", "light_vpls", "march", "filter", "gather"};

class PointVoxelsParity : public softgi::testing::ValidatedParamSuite<PointVoxelsParity> {
 protected:
  static void SetUpTestSuite() {
    backends::register_cpu_backend();  // the Embree G-buffer pass
    softgi::testing::ValidatedParamSuite<PointVoxelsParity>::SetUpTestSuite();
  }
};

TEST_P(PointVoxelsParity, EveryVulkanPassMatchesTheCpuPass) {
  const std::string name = GetParam();
  const SceneCase* sc_case = nullptr;
  for (const auto& c : kScenes)
    if (name == c.scene) sc_case = &c;
  ASSERT_NE(sc_case, nullptr);
  const scene::Scene sc = scene::make_builtin(name);
  std::unique_ptr<render::Technique> tech = pv::create();
  const render::ParamSet params = params_for(*tech, *sc_case);
  const std::string vk_name = backends::vulkan::kBackendName;
  Image cpu_final, cpu_direct, cpu_indirect;
  // Frame 1: pass by pass from the CPU's inputs.
  {
    render::SteppedFrame frame(*tech, sc, params, request(sc_case->time), ctx_.get());
    render::FrameContext& ctx = frame.context();
    std::size_t compared = 0;
    for (const render::PassDesc* pp : frame.passes()) {
      const render::PassDesc& pass = *pp;
      frame.run(pass, host_backend(pass));
      if (std::find(kGpuPasses.begin(), kGpuPasses.end(), pass.name) == kGpuPasses.end()) continue;
      ASSERT_TRUE(pass.impl.count(vk_name)) << pass.name << " has no Vulkan implementation";
      const std::string out = pass.writes.at(0);
      SCOPED_TRACE(name + ", " + pass.name);
      if (pass.name == "light_maps") {
        auto c = ctx.get<std::shared_ptr<const pv::Lights>>(out);
        frame.run(pass, vk_name, pass.name + "@vulkan");
        EXPECT_TRUE(ctx.is_deferred(out)) << "the maps stay on the device until asked for";
        auto g = ctx.get<std::shared_ptr<const pv::Lights>>(out);
        ASSERT_NE(c, g);
        compare_lights(*c, *g);
        ctx.put<std::shared_ptr<const pv::Lights>>(out, c);
      } else if (pass.name == "voxelize" || pass.name == "light_vpls") {
        auto c = ctx.get<std::shared_ptr<const pv::Voxels>>(out);
        frame.run(pass, vk_name, pass.name + "@vulkan");
        EXPECT_TRUE(ctx.is_deferred(out)) << "the result stays on the device until asked for";
        auto g = ctx.get<std::shared_ptr<const pv::Voxels>>(out);
        ASSERT_NE(c, g);
        if (pass.name == "voxelize") compare_voxelize(*c, *g);
        else compare_vpls(*c, *g);
        ctx.put<std::shared_ptr<const pv::Voxels>>(out, c);
      } else if (pass.name == "march" || pass.name == "filter") {
        const bool filter = pass.name == "filter";
        auto c = ctx.get<std::shared_ptr<const pv::Marched>>(out);
        std::shared_ptr<const pv::SkyLight> c_sky = filter ? ctx.get<std::shared_ptr<const pv::SkyLight>>(pv::kFilteredSky) : nullptr;
        frame.run(pass, vk_name, pass.name + "@vulkan");
        auto g = ctx.get<std::shared_ptr<const pv::Marched>>(out);
        ASSERT_NE(c, g);
        compare_marched(*c, *g, filter ? kFilterFlipShare : kListFlipShare, pass.name.c_str());
        if (filter) {
          EXPECT_TRUE(ctx.is_deferred(pv::kFilteredSky));
          auto g_sky = ctx.get<std::shared_ptr<const pv::SkyLight>>(pv::kFilteredSky);
          const double d = compare_sky(*c_sky, *g_sky);
          EXPECT_LE(d, kFieldRelTol) << "filtered sky light";
          std::printf("[pv parity]   filter: sky light %.3g\n", d);
          ctx.put<std::shared_ptr<const pv::SkyLight>>(pv::kFilteredSky, c_sky);
        } else {
          // The sky light of the escaped rays: the same rays, one grazing flip moves a pixel's by a
          // ray's share, so it is compared where the lists agree (kListFlipShare bounds the others).
          pv::SkyLight cs = c->sky, gs = g->sky;
          std::size_t kept = 0;
          for (std::size_t p = 0; p + 1 < c->lists.offset.size(); ++p) {
            const bool same = std::equal(c->lists.voxel.begin() + c->lists.offset[p], c->lists.voxel.begin() + c->lists.offset[p + 1],
                                         g->lists.voxel.begin() + g->lists.offset[p], g->lists.voxel.begin() + g->lists.offset[p + 1]);
            if (!same) continue;
            cs.irradiance[kept] = c->sky.irradiance[p], cs.escaped[kept] = c->sky.escaped[p];
            gs.irradiance[kept] = g->sky.irradiance[p], gs.escaped[kept] = g->sky.escaped[p];
            ++kept;
          }
          for (auto* x : {&cs, &gs}) x->irradiance.resize(kept), x->escaped.resize(kept);
          const double d = compare_sky(cs, gs);
          EXPECT_LE(d, kMarchSkyRelTol) << "sky light of the escaped rays";
          std::printf("[pv parity]   march: sky light %.3g\n", d);
        }
        ctx.put<std::shared_ptr<const pv::Marched>>(out, c);
      } else {
        auto c = ctx.get<std::shared_ptr<const std::vector<pv::Gathered>>>(out);
        frame.run(pass, vk_name, pass.name + "@vulkan");
        auto g = ctx.get<std::shared_ptr<const std::vector<pv::Gathered>>>(out);
        ASSERT_NE(c, g);
        compare_gathered(*c, *g);
        ctx.put<std::shared_ptr<const std::vector<pv::Gathered>>>(out, c);
      }
      // The same counters on both backends.
      const auto& cc = frame.result().passes[frame.result().passes.size() - 2].counters;
      const auto& gc = frame.result().passes.back().counters;
      for (const char* k : {"voxels_occupied", "vpls", "env_rays", "pixels", "rays", "unmatched"})
        if (cc.count(k)) {
          EXPECT_EQ(cc.at(k), gc.at(k)) << k;
        }
      ++compared;
    }
    EXPECT_EQ(compared, kGpuPasses.size()) << "every GPU pass compared";
    cpu_final = ctx.get<Image>(render::kFinal);
    cpu_direct = ctx.get<Image>(render::kDirect);
    cpu_indirect = ctx.get<Image>(render::kIndirect);
  }
  // Frame 2: every GPU pass on Vulkan, intermediates left on the device.
  {
    render::SteppedFrame frame(*tech, sc, params, request(sc_case->time), ctx_.get());
    for (const render::PassDesc* pp : frame.passes()) {
      const bool gpu = pp->impl.count(vk_name) && std::find(kGpuPasses.begin(), kGpuPasses.end(), pp->name) != kGpuPasses.end();
      frame.run(*pp, gpu ? vk_name : host_backend(*pp));
    }
    render::FrameContext& ctx = frame.context();
    // Nothing on the host asked for the voxels, the VPLs or the lists: never read back (the direct
    // pass, a host pass, read the depth maps and the filtered sky light).
    for (const char* r : {pv::kVoxels, pv::kVpls, pv::kLists, pv::kFiltered}) EXPECT_TRUE(ctx.is_deferred(r)) << r;
    const double e_final = rel_mse(cpu_final, ctx.get<Image>(render::kFinal));
    const double e_direct = rel_mse(cpu_direct, ctx.get<Image>(render::kDirect));
    const double e_indirect = rel_mse(cpu_indirect, ctx.get<Image>(render::kIndirect));
    EXPECT_LE(e_final, kFrameRelMse);
    EXPECT_LE(e_direct, kFrameRelMse);
    EXPECT_LE(e_indirect, kFrameRelMse);
    std::printf("[pv parity] %-14s whole frame on vulkan: relMSE final %.3g, direct %.3g, indirect %.3g (bound %.1g)\n", name.c_str(), e_final,
                e_direct, e_indirect, kFrameRelMse);
  }
}

INSTANTIATE_TEST_SUITE_P(BuiltinScenes, PointVoxelsParity, ::testing::Values("cornell_glossy", "spheres", "character", "atrium", "glossy_sweep"));

// Marching and gathering under a tight loop-iteration limit (set for the test, so that it runs on
// every driver) resume over several dispatches from the state each invocation saved; the split
// changes no arithmetic, so the lists and the images are identical, bit for bit: nothing in the
// frame depends on the order in which the device runs invocations (the voxels are sorted by
// (key, sampling index) and each voxel's SH summed in that order, in runs of vpl_finish dispatches
// under the limit). Both marching variants: one ray per invocation
// under a limit of 300 (a budget of 150), and each ray's discs across a subgroup's lanes under a
// limit that leaves it a few disc steps beyond what a resumed ray needs to progress (the rays before
// it in its subgroup and its DDA replay: run_march's check), since the lanes variant spends about a
// lane's share of the other's iterations. The two variants mark the same voxels, bit for bit. On
// cornell_glossy (6^3 voxels of ~30 proxies: the shadow rays and gathering pixels run out of budget)
// and spheres (the VPLs' environment rays).
TEST(PointVoxelsVulkan, ResumedDispatchesGiveTheSameFrame) {
  backends::register_cpu_backend();
  std::uint32_t subgroup = 0;
  {
    backends::vulkan::ContextOptions o;
    o.validation = 0;
    subgroup = backends::vulkan::Context(o).device_info().subgroup_size;
  }
  // The host runs the lanes variant where subgroups tile march.comp's workgroup.
  const bool lanes_fit = subgroup > 0 && subgroup <= gpu::kPvGroup && gpu::kPvGroup % subgroup == 0;
  for (const auto& [name, extra] : std::vector<std::pair<std::string, std::string>>{{"cornell_glossy", "6"}, {"spheres", "8"}}) {
    SCOPED_TRACE(name);
    const scene::Scene sc = scene::make_builtin(name);
    std::unique_ptr<render::Technique> tech = pv::create();
    struct Run {
      render::FrameResult frame;
      std::map<std::string, double> dispatches;
      double lanes = -1.0;
      double finish = 0.0;  // light_vpls' vpl_finish dispatches
    };
    auto run = [&](const std::string& lanes, std::uint32_t limit) {
      render::ParamSet params = render::default_params(*tech);
      params.set("proxy_count", "6000");
      params.set("grid", extra);
      params.set("rays", "16");
      params.set("shadow_map_size", "64");
      params.set("march_lanes", lanes);
      render::RenderRequest req;
      req.width = req.height = 48;
      req.outputs = {render::kFinal, pv::kLists};
      backends::vulkan::ContextOptions o;
      o.validation = 1;
      o.loop_iteration_limit = limit;
      auto ctx = std::make_shared<backends::vulkan::Context>(o);
      const auto log = ctx->validation_log();
      Run r;
      {
        backends::VulkanBackend vk(ctx);
        ctx.reset();
        r.frame = vk.render(*tech, sc, params, req);
      }
      EXPECT_EQ(log->problems(), 0u) << log->summary();
      for (const auto& p : r.frame.passes) {
        for (const char* k : {"march_dispatches", "dispatches"})
          if (p.counters.count(k)) r.dispatches[p.name] = p.counters.at(k);
        if (p.name == "march" && p.counters.count("march_lanes_discs")) r.lanes = p.counters.at("march_lanes_discs");
        if (p.name == "light_vpls" && p.counters.count("finish_dispatches")) r.finish = p.counters.at("finish_dispatches");
      }
      return r;
    };
    const auto lists = [](const Run& r) -> const pv::Marched& {
      return *std::any_cast<std::shared_ptr<const pv::Marched>>(r.frame.resources.at(pv::kLists));
    };
    std::map<std::string, Run> whole_of;
    // The lanes variant's limit: twice (loop_budget halves limits this small) the iterations a
    // resumed ray needs on the 8^3 grid (subgroup + 24 + 2), and 8 disc steps.
    for (const auto& [lanes, limit] : std::vector<std::pair<std::string, std::uint32_t>>{{"rays", 300u}, {"discs", 2u * (subgroup + 26u + 8u)}}) {
      SCOPED_TRACE(lanes);
      Run split = run(lanes, limit), whole = run(lanes, 0);  // 0: the driver's own limit
      if (whole.frame.backend != "vulkan") continue;
      EXPECT_EQ(whole.lanes, lanes == "discs" && lanes_fit ? 1.0 : 0.0) << "the marching variant that ran";
      if (name == "cornell_glossy") {
        EXPECT_GT(split.dispatches.at("march"), 2.0) << "a limit of " << limit << " iterations splits the shadow rays over dispatches";
        EXPECT_GT(split.dispatches.at("gather"), 2.0) << "and the gathering";
      } else {
        EXPECT_GT(split.dispatches.at("light_vpls"), 2.0) << "and the VPLs' environment rays";
      }
      for (const auto& [pass, n] : whole.dispatches)
        if (split.dispatches.count(pass)) {
          EXPECT_LE(n, split.dispatches.at(pass)) << pass;
        }
      const auto& la = lists(split);
      const auto& lb = lists(whole);
      EXPECT_EQ(la.lists.offset, lb.lists.offset);
      EXPECT_EQ(la.lists.voxel, lb.lists.voxel);
      EXPECT_GT(la.lists.voxel.size(), 0u);
      const double e = rel_mse(split.frame.final_image, whole.frame.final_image);
      EXPECT_TRUE(split.frame.final_image.rgb == whole.frame.final_image.rgb) << "final image, relMSE " << e;
      // Under the second limit vpl_finish sums 10 VPLs of a cell per dispatch (its budget less its
      // own 32 iterations), fewer than the cells of either scene hold.
      if (lanes == "discs") {
        EXPECT_GT(split.finish, 1.0) << "a limit of " << limit << " iterations splits the voxels' sums over dispatches";
      }
      EXPECT_EQ(whole.finish, 1.0);
      std::printf("[pv resume] %-14s %-5s march %g / %g dispatches, gather %g / %g, light_vpls %g / %g, vpl_finish %g / %g; relMSE %.3g\n",
                  name.c_str(), lanes.c_str(), split.dispatches["march"], whole.dispatches["march"], split.dispatches["gather"],
                  whole.dispatches["gather"], split.dispatches["light_vpls"], whole.dispatches["light_vpls"], split.finish, whole.finish, e);
      whole_of[lanes] = std::move(whole);
    }
    if (whole_of.size() == 2) {
      EXPECT_EQ(lists(whole_of["rays"]).lists.offset, lists(whole_of["discs"]).lists.offset) << "both variants mark the same voxels";
      EXPECT_EQ(lists(whole_of["rays"]).lists.voxel, lists(whole_of["discs"]).lists.voxel) << "both variants mark the same voxels";
      EXPECT_TRUE(whole_of["rays"].frame.final_image.rgb == whole_of["discs"].frame.final_image.rgb) << "and give the same frame";
    }
  }
}

}  // namespace
