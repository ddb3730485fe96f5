// Point-proxy voxels' GPU passes on the Vulkan backend (paper 002, Chen et al. 2014): voxelisation
// (eq. 1's keys, a histogram, a scan, a sort of (key, sampling index) pairs and a scatter into cell
// ranges: shaders/point_voxels/voxel_*.comp), the VPLs' light and eqs. 2-3 summed per cell in sorted
// order (march.comp for the environment rays, vpl_light.comp, vpl_finish.comp), sparse ray marching (march.comp, march_lists.comp), the visibility filter
// (filter_lists.comp, filter_fields.comp) and gathering (gather.comp). They read and write the same
// frame resources as the host passes (point_voxels.cpp): each result stays on the device for the
// next GPU pass and is read back only when a host pass or the caller asks for it. Per-pixel visible
// voxel lists are bitsets over the grid's cells on the device (sorted and free of duplicates by
// construction) and compressed rows on the host. Under a driver's loop-iteration limit (llvmpipe),
// marching and gathering resume over several dispatches from the state each invocation saved. The
// sort and the per-cell sums follow the CPU's order, so that a frame is the same from run to run.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "pv_passes.hpp"
#include "pv_vulkan.hpp"
#include "../common/accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "pv_shared.h"

namespace spv {
#include "softgi/shaders/point_voxels/filter_fields_comp.h"
#include "softgi/shaders/point_voxels/filter_lists_comp.h"
#include "softgi/shaders/point_voxels/gather_comp.h"
#include "softgi/shaders/point_voxels/march_comp.h"
#include "softgi/shaders/point_voxels/march_lists_comp.h"
#include "softgi/shaders/point_voxels/voxel_keys_comp.h"
#include "softgi/shaders/point_voxels/voxel_scan_comp.h"
#include "softgi/shaders/point_voxels/voxel_scatter_comp.h"
#include "softgi/shaders/point_voxels/voxel_sort_comp.h"
#include "softgi/shaders/point_voxels/vpl_finish_comp.h"
#include "softgi/shaders/point_voxels/vpl_light_comp.h"
}  // namespace spv

namespace softgi::techniques::point_voxels {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;
using render::FrameContext;
using render::GBuffer;

namespace {

constexpr float kPi = 3.14159265358979323846f;

// The shaders' records (pv_common.glsl, gather.comp), std430.
struct GpuProxy {
  glm::vec4 position, normal, albedo;
  glm::uvec4 meta;  // environment ray seed, sampling index, voxel key, 0
};
struct GpuMarchPixel {
  glm::vec4 pos_hit, normal_depth;
  glm::uvec4 seed;
};
struct GpuItem {
  glm::uvec4 state;
  glm::vec4 radiance;
};
struct GpuGatherPixel {
  glm::vec4 pos_depth, normal_glossy, reflect_ns, extra;
};
struct GpuGathered {
  glm::vec4 irradiance, glossy, weighted;
};
struct GpuGatherState {
  glm::uvec4 s;
  glm::vec4 esum;
};
struct GpuGrid {
  glm::vec4 lo_r, cell_a, inv_cell;
  glm::ivec4 dims;
  glm::uvec4 counts;
};
static_assert(sizeof(GpuProxy) == 64 && sizeof(GpuMarchPixel) == 48 && sizeof(GpuItem) == 32 && sizeof(GpuGatherPixel) == 64 &&
              sizeof(GpuGathered) == 48 && sizeof(GpuGatherState) == 32 && sizeof(GpuGrid) == 80);

// What the device holds of a frame's voxels (the device copy of kVoxels or kVpls): the grid's frame
// (lo, cell, dims; no arrays) and the scalars of Voxels.
struct DeviceVoxels {
  VoxelGrid frame;
  std::size_t proxies = 0;
  float radius = 0.0f, patch_area = 0.0f;
  double density = 0.0;
  float diagonal = 0.0f;
  std::uint32_t largest = 0;  // the most proxies in one cell
};
// The device copy of kLightMaps: the lights without their depths (those are in GpuState::maps).
struct DeviceLights {
  std::shared_ptr<const Lights> meta;
};
// The device copy of kLists or kFiltered.
struct DeviceMarched {
  int width = 0, height = 0;
  std::uint32_t words = 0;
  std::size_t entries = 0;  // list entries over all pixels
};

// Per-device state: pipelines, and buffers reused from frame to frame (grown when needed). Each
// frame resource owns its buffers (kVoxels: sprox, start; kVpls: vprox, vstart, radiance, vsh;
// kLists: bits[0], fields[0]; kFiltered: bits[1], fields[1]), so that uploading one from the host
// never overwrites another's device copy. A buffer a shader writes has its content hash reset, so
// that the next host upload into it is never skipped.
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer grid;
  std::uint64_t grid_hash = 0;
  vk::Buffer uprox, count, pairs, scan_status;
  std::uint64_t uprox_hash = 0;
  vk::Buffer sprox, start;
  std::uint64_t sprox_hash = 0, start_hash = 0;
  vk::Buffer vprox, vstart, radiance, vsh;
  std::uint64_t vprox_hash = 0, vstart_hash = 0, radiance_hash = 0, vsh_hash = 0;
  vk::Buffer lights, sky;
  std::uint64_t lights_hash = 0, sky_hash = 0;
  LightBuffers maps;
  vk::Buffer items, march_status;
  vk::Buffer pixels, sources, gsources;
  std::uint64_t pixels_hash = 0, sources_hash = 0, gsources_hash = 0;
  vk::Buffer bits[2], fields[2];
  std::uint64_t bits_hash[2] = {0, 0}, fields_hash[2] = {0, 0};
  vk::Buffer list_status;
  vk::Buffer receivers, gathered, gstate, gather_status;
  std::uint64_t receivers_hash = 0;
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("point_voxels.gpu", [] { return std::make_shared<GpuState>(); });
}

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  common::gpu_passes::check_fits(dev, bytes, what, "point_voxels " + pass,
                                 "use fewer proxies, a coarser grid, fewer rays or a coarser marching buffer, or --backend cpu");
}

void check_index(std::size_t count, const std::string& what, const std::string& pass) {
  if (count > std::numeric_limits<std::uint32_t>::max() / 2)
    throw std::invalid_argument("point_voxels " + pass + " on vulkan: " + std::to_string(count) + " " + what + " exceed the 32-bit indexing");
}

void ensure(vk::Context& dev, vk::Buffer& b, std::size_t bytes, const std::string& name) {
  dev.ensure_buffer(b, std::max<std::size_t>(16, bytes), kStorage, vk::MemoryKind::Device, name);
}

template <class T>
std::vector<T> download(vk::Context& dev, const vk::Buffer& b, std::size_t count) {
  std::vector<T> v(count);
  if (count) dev.download(b, v.data(), count * sizeof(T));
  return v;
}

std::uint32_t words_of(const VoxelGrid& frame) { return static_cast<std::uint32_t>((frame.cells() + 31) / 32); }

GpuGrid gpu_grid(const VoxelGrid& frame, float radius, float patch_area, std::size_t proxies) {
  GpuGrid g;
  g.lo_r = glm::vec4(frame.lo, radius);
  g.cell_a = glm::vec4(frame.cell, patch_area);
  g.inv_cell = glm::vec4(frame.inv_cell, 0.0f);
  g.dims = glm::ivec4(frame.dims, static_cast<int>(frame.cells()));
  g.counts = glm::uvec4(static_cast<std::uint32_t>(proxies), 0u, 0u, 0u);
  return g;
}

void put_grid(vk::Context& dev, GpuState& g, const DeviceVoxels& d) {
  const std::vector<GpuGrid> grid = {gpu_grid(d.frame, d.radius, d.patch_area, d.proxies)};
  put_if_changed(dev, g.grid, g.grid_hash, grid, "point_voxels grid");
}

DeviceVoxels device_voxels(const Voxels& v) {
  DeviceVoxels d;
  d.frame.lo = v.grid.lo;
  d.frame.cell = v.grid.cell;
  d.frame.inv_cell = v.grid.inv_cell;
  d.frame.dims = v.grid.dims;
  d.proxies = v.proxies.size();
  d.radius = v.proxies.radius;
  d.patch_area = v.proxies.patch_area;
  d.density = v.density;
  d.diagonal = v.diagonal;
  for (std::size_t k = 0; k + 1 < v.grid.start.size(); ++k) d.largest = std::max(d.largest, v.grid.start[k + 1] - v.grid.start[k]);
  return d;
}

std::vector<GpuProxy> gpu_proxies(const Voxels& v) {
  std::vector<GpuProxy> out(v.proxies.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = {glm::vec4(v.proxies.position[i], 0.0f), glm::vec4(v.proxies.normal[i], 0.0f), glm::vec4(v.proxies.albedo[i], 0.0f),
              glm::uvec4(v.ray_seed[i], v.sample[i], v.grid.key[i], 0u)};
  return out;
}

// The host copy of voxels the device holds: sorted proxies and cell ranges, with the radiance and
// the voxels' SH and centroids when `lit`.
std::shared_ptr<const Voxels> read_voxels(vk::Context& dev, const DeviceVoxels& d, const vk::Buffer& prox, const vk::Buffer& start,
                                          const vk::Buffer* radiance, const vk::Buffer* vsh) {
  auto v = std::make_shared<Voxels>();
  v->density = d.density;
  v->diagonal = d.diagonal;
  v->grid.lo = d.frame.lo;
  v->grid.cell = d.frame.cell;
  v->grid.inv_cell = d.frame.inv_cell;
  v->grid.dims = d.frame.dims;
  const std::size_t n = d.proxies, cells = d.frame.cells();
  const auto p = download<GpuProxy>(dev, prox, n);
  PosedProxies& P = v->proxies;
  P.radius = d.radius;
  P.patch_area = d.patch_area;
  P.position.resize(n);
  P.normal.resize(n);
  P.albedo.resize(n);
  P.radiance.assign(n, glm::vec3(0.0f));
  v->grid.key.resize(n);
  v->sample.resize(n);
  v->ray_seed.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    P.position[i] = glm::vec3(p[i].position);
    P.normal[i] = glm::vec3(p[i].normal);
    P.albedo[i] = glm::vec3(p[i].albedo);
    v->ray_seed[i] = p[i].meta.x;
    v->sample[i] = p[i].meta.y;
    v->grid.key[i] = p[i].meta.z;
  }
  v->grid.start = download<std::uint32_t>(dev, start, cells + 1);
  if (radiance && vsh) {
    const auto r = download<glm::vec4>(dev, *radiance, n);
    for (std::size_t i = 0; i < n; ++i) P.radiance[i] = glm::vec3(r[i]);
    const auto s = download<float>(dev, *vsh, cells * gpu::kPvVoxelFloats);
    v->grid.sh.resize(cells);
    v->grid.centroid.resize(cells);
    for (std::size_t k = 0; k < cells; ++k) {
      const float* c = s.data() + k * gpu::kPvVoxelFloats;
      for (int m = 0; m < 4; ++m) v->grid.sh[k][m] = glm::vec3(c[3 * m], c[3 * m + 1], c[3 * m + 2]);
      v->grid.centroid[k] = glm::vec3(c[12], c[13], c[14]);
    }
  }
  v->planes = proxy_planes(P);
  return v;
}

// The voxels of `resource` on the device: kVoxels in sprox and start, kVpls (lit) in vprox, vstart,
// radiance and vsh. The device copy this frame's GPU pass left there, else the host copy, uploaded
// where its content changed.
DeviceVoxels voxels_on_device(FrameContext& ctx, vk::Context& dev, GpuState& g, const char* resource, const std::string& pass) {
  if (const auto* d = ctx.device_copy<DeviceVoxels>(resource)) {
    put_grid(dev, g, *d);
    return *d;
  }
  const bool lit = std::string(resource) == kVpls;
  const auto& V = *ctx.get<std::shared_ptr<const Voxels>>(resource);
  const std::size_t n = V.proxies.size(), cells = V.grid.cells();
  check_fits(dev, n * sizeof(GpuProxy), std::to_string(n) + " proxies", pass);
  const DeviceVoxels d = device_voxels(V);
  put_if_changed(dev, lit ? g.vprox : g.sprox, lit ? g.vprox_hash : g.sprox_hash, gpu_proxies(V), "point_voxels sorted proxies");
  put_if_changed(dev, lit ? g.vstart : g.start, lit ? g.vstart_hash : g.start_hash, V.grid.start, "point_voxels cell ranges");
  put_grid(dev, g, d);
  if (!lit) return d;
  check_fits(dev, cells * gpu::kPvVoxelFloats * sizeof(float), "the SH of " + std::to_string(cells) + " voxels", pass);
  std::vector<glm::vec4> rad(n);
  for (std::size_t i = 0; i < n; ++i) rad[i] = glm::vec4(V.proxies.radiance[i], 0.0f);
  std::vector<float> sh(cells * gpu::kPvVoxelFloats, 0.0f);
  for (std::size_t k = 0; k < cells && k < V.grid.sh.size(); ++k) {
    float* c = sh.data() + k * gpu::kPvVoxelFloats;
    for (int m = 0; m < 4; ++m)
      for (int ch = 0; ch < 3; ++ch) c[3 * m + ch] = V.grid.sh[k][m][ch];
    for (int ch = 0; ch < 3; ++ch) c[12 + ch] = V.grid.centroid[k][ch];
  }
  put_if_changed(dev, g.radiance, g.radiance_hash, rad, "point_voxels VPL radiance");
  put_if_changed(dev, g.vsh, g.vsh_hash, sh, "point_voxels voxel SH");
  return d;
}

// The marching G-buffer as march.comp reads it, with each pixel's ray seed, and the pixels that see
// a surface (march.comp's sources, in pixel order). Returns how many of those there are.
std::size_t put_pixels(vk::Context& dev, GpuState& g, const GBuffer& mg) {
  const std::size_t np = static_cast<std::size_t>(mg.width) * mg.height;
  std::vector<GpuMarchPixel> px(np);
  std::vector<std::uint32_t> sources;
  sources.reserve(np);
  for (std::size_t i = 0; i < np; ++i) {
    const bool hit = mg.hit(i);
    px[i].pos_hit = glm::vec4(mg.position[i], hit ? 1.0f : 0.0f);
    px[i].normal_depth = glm::vec4(mg.normal[i], hit ? mg.depth[i] : 0.0f);
    px[i].seed = glm::uvec4(pixel_ray_seed(i), 0u, 0u, 0u);
    if (hit) sources.push_back(static_cast<std::uint32_t>(i));
  }
  put_if_changed(dev, g.pixels, g.pixels_hash, px, "point_voxels marching pixels");
  const std::size_t n = sources.size();
  if (sources.empty()) sources.push_back(0u);  // a buffer is never empty; no source reads it
  put_if_changed(dev, g.sources, g.sources_hash, sources, "point_voxels march sources");
  return n;
}

// Lists of kLists (slot 0) or kFiltered (slot 1) on the device: the device copy, else the host
// copy's lists as bitsets and its sky fields, uploaded.
DeviceMarched marched_on_device(FrameContext& ctx, vk::Context& dev, GpuState& g, const char* resource, int slot, std::uint32_t words,
                                const std::string& pass) {
  if (const auto* d = ctx.device_copy<DeviceMarched>(resource)) {
    if (d->words != words)
      throw std::logic_error("point_voxels " + pass + " on vulkan: lists of " + std::to_string(d->words) + " words per pixel for " +
                             std::to_string(words));
    return *d;
  }
  const auto& M = *ctx.get<std::shared_ptr<const Marched>>(resource);
  const std::size_t np = static_cast<std::size_t>(M.lists.width) * M.lists.height;
  check_fits(dev, np * words * sizeof(std::uint32_t), "the voxel bitsets of " + std::to_string(np) + " marching pixels", pass);
  std::vector<std::uint32_t> bits(np * words, 0u);
  for (std::size_t p = 0; p < np; ++p)
    for (std::uint32_t e = M.lists.offset[p]; e < M.lists.offset[p + 1]; ++e) {
      const auto v = static_cast<std::uint32_t>(M.lists.voxel[e]);
      if (v / 32 >= words) throw std::logic_error("point_voxels " + pass + " on vulkan: voxel " + std::to_string(v) + " outside the grid");
      bits[p * words + v / 32] |= 1u << (v % 32);
    }
  put_if_changed(dev, g.bits[slot], g.bits_hash[slot], bits, "point_voxels voxel bitsets");
  if (M.sky.irradiance.size() == np && M.sky.escaped.size() == np) {
    std::vector<glm::vec4> fields(np);
    for (std::size_t p = 0; p < np; ++p) fields[p] = glm::vec4(M.sky.irradiance[p], M.sky.escaped[p]);
    put_if_changed(dev, g.fields[slot], g.fields_hash[slot], fields, "point_voxels sky fields");
  } else if (slot == 0) {
    throw std::logic_error("point_voxels " + pass + " on vulkan: the marched lists carry no sky light");
  }
  return DeviceMarched{M.lists.width, M.lists.height, words, M.lists.voxel.size()};
}

std::shared_ptr<const SkyLight> read_sky(vk::Context& dev, std::size_t np, const vk::Buffer& fields) {
  const auto f = download<glm::vec4>(dev, fields, np);
  auto sky = std::make_shared<SkyLight>();
  sky->irradiance.resize(np);
  sky->escaped.resize(np);
  for (std::size_t p = 0; p < np; ++p) {
    sky->irradiance[p] = glm::vec3(f[p]);
    sky->escaped[p] = f[p].w;
  }
  return sky;
}

// The host copy of lists the device holds (bitsets to compressed rows), with the sky light of
// `fields` when given.
std::shared_ptr<const Marched> read_marched(vk::Context& dev, const DeviceMarched& d, const vk::Buffer& bits, const vk::Buffer* fields) {
  const std::size_t np = static_cast<std::size_t>(d.width) * d.height;
  const auto b = download<std::uint32_t>(dev, bits, np * d.words);
  auto m = std::make_shared<Marched>();
  m->lists.width = d.width;
  m->lists.height = d.height;
  m->lists.offset.assign(np + 1, 0);
  for (std::size_t p = 0; p < np; ++p) {
    for (std::uint32_t w = 0; w < d.words; ++w)
      for (std::uint32_t word = b[p * d.words + w]; word != 0; word &= word - 1)
        m->lists.voxel.push_back(static_cast<std::int32_t>(w * 32 + static_cast<std::uint32_t>(__builtin_ctz(word))));
    m->lists.offset[p + 1] = static_cast<std::uint32_t>(m->lists.voxel.size());
  }
  if (fields) m->sky = *read_sky(dev, np, *fields);
  return m;
}

template <class Push>
void dispatch(vk::Recorder& rec, const vk::ComputePipeline& p, const std::vector<vk::Bind>& binds, std::size_t count, Push push) {
  dispatch_chunks<Push>(rec, p, binds, count, gpu::kPvGroup, [&](std::uint32_t first, std::uint32_t end) {
    Push q = push;
    q.first = first;
    q.end = end;
    return q;
  });
}

// Items (source, ray) a batch of march.comp holds: its buffer stays within the device's storage
// buffer range and 128 MiB.
std::size_t batch_items(const vk::Context& dev) {
  const std::size_t range = dev.device_info().limits.maxStorageBufferRange;
  return std::max<std::size_t>(1, std::min<std::size_t>(range, std::size_t{128} << 20) / sizeof(GpuItem));
}

struct MarchRun {
  double seconds = 0.0;
  int dispatches = 0;
};

// march.comp over the `rays` rays of sources [first, end) (one batch): dispatched again while
// invocations ran out of loop budget, each resuming where it stopped.
void run_march(vk::Context& dev, GpuState& g, vk::ComputePipeline& p, const std::vector<vk::Bind>& binds, std::size_t first, std::size_t end,
               std::uint32_t rays, bool sky, bool lanes, const glm::ivec3& dims, MarchRun& run, const std::string& what) {
  struct Push {
    std::uint32_t first_source, sources, rays, sky, budget, first, end;
  };
  const std::size_t items = (end - first) * rays;
  const std::uint32_t budget = loop_budget(dev.device_info());
  // A resumed ray replays its DDA steps (at most the sum of the grid's dims), in the lanes variant
  // after the rays before it in its subgroup (one iteration each), before it tests discs again: a
  // budget below that would resume it at the same place forever.
  const std::uint64_t ahead = lanes ? dev.device_info().subgroup_size : 0u;
  const std::uint64_t progress = ahead + static_cast<std::uint64_t>(dims.x) + dims.y + dims.z + 2;
  if (budget < progress)
    throw std::invalid_argument("point_voxels " + what + " on vulkan: a loop budget of " + std::to_string(budget) +
                                " iterations is below the " + std::to_string(progress) + " a resumed ray may need to progress on a " +
                                std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" + std::to_string(dims.z) + " grid");
  Push push{static_cast<std::uint32_t>(first), static_cast<std::uint32_t>(end - first), rays, sky ? 1u : 0u, budget, 0, 0};
  std::uint32_t status[gpu::kPvStatusWords];
  for (int pass = 0;; ++pass) {
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      if (pass == 0) rec.fill(g.items, 0u);  // every item kPvPhaseNew
      rec.fill(g.march_status, 0u);
      rec.barrier();
      rec.begin_timer("march");
      dispatch(rec, p, binds, items, push);
      rec.end_timer();
      rec.barrier();
    }, what);
    run.seconds += std::max(0.0, res.gpu_seconds);
    ++run.dispatches;
    dev.download(g.march_status, status, sizeof status);
    if (status[gpu::kPvStatusUnfinished] == 0) break;
    // Every dispatch takes each unfinished ray at least one disc further: the budget (tens of
    // thousands of iterations) exceeds the replay of its DDA steps (at most the sum of the grid's dims).
    if (pass > 1 << 20) throw std::logic_error("point_voxels " + what + " on vulkan: rays still unfinished after " + std::to_string(pass) + " dispatches");
  }
}

// march.comp for `source`: with Settings::march_lanes_discs, the variant that tests each ray's discs
// across a subgroup's lanes (pv_march_lanes), where the device's subgroups tile the workgroup (their
// size divides kPvGroup); one ray per invocation otherwise. `lanes_used` says which ran.
vk::ComputePipeline& march_pipeline(vk::Context& dev, GpuState& g, const Settings& s, std::uint32_t source, bool& lanes_used) {
  const std::uint32_t sg = dev.device_info().subgroup_size;
  lanes_used = s.march_lanes_discs && sg > 0 && sg <= gpu::kPvGroup && gpu::kPvGroup % sg == 0;
  const std::string name = std::string(source == gpu::kPvSourcePixels ? "pv.march.pixels" : "pv.march.proxies") +
                           (lanes_used ? ".discs" : ".rays");
  return pipeline(dev, g.pipelines, name, words(spv::point_voxels_march_comp), {{0, source}, {1, lanes_used ? 1u : 0u}});
}

// --- passes --------------------------------------------------------------------------------------------

void vulkan_voxelize(const Settings& s, FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& P = *ctx.get<std::shared_ptr<const Posed>>(kProxies);
  const std::size_t n = P.proxies.size();
  DeviceVoxels d;
  d.frame = grid_frame(P.proxies, glm::ivec3(s.grid));
  d.proxies = n;
  d.radius = P.proxies.radius;
  d.patch_area = P.proxies.patch_area;
  d.density = P.density;
  d.diagonal = glm::length(d.frame.cell * glm::vec3(d.frame.dims));
  const std::size_t cells = d.frame.cells();
  check_index(n, "proxies", "voxelize");
  check_fits(dev, n * sizeof(GpuProxy), std::to_string(n) + " proxies", "voxelize");
  check_fits(dev, (cells + 1) * sizeof(std::uint32_t), "the ranges of " + std::to_string(cells) + " voxels", "voxelize");

  std::vector<GpuProxy> up(n);
  for (std::size_t i = 0; i < n; ++i)
    up[i] = {glm::vec4(P.proxies.position[i], 0.0f), glm::vec4(P.proxies.normal[i], 0.0f), glm::vec4(P.proxies.albedo[i], 0.0f),
             glm::uvec4(P.ray_seed[i], static_cast<std::uint32_t>(i), 0u, 0u)};
  const std::size_t before = dev.transfer_bytes().upload;
  put_if_changed(dev, g.uprox, g.uprox_hash, up, "point_voxels proxies");
  put_grid(dev, g, d);
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  // The sort's pairs: a power of two, at least one workgroup's block.
  const std::size_t block = 2 * gpu::kPvSortGroup * gpu::kPvSortPairs;
  std::size_t sorted = block;
  while (sorted < n) sorted *= 2;
  check_fits(dev, sorted * 2 * sizeof(std::uint32_t), "the sort keys of " + std::to_string(n) + " proxies", "voxelize");
  const std::size_t max_groups = dev.device_info().limits.maxComputeWorkGroupCount[0];
  if (sorted / block > max_groups)
    throw std::invalid_argument("point_voxels voxelize on vulkan: sorting " + std::to_string(n) + " proxies needs " +
                                std::to_string(sorted / block) + " workgroups in one dispatch, beyond the device's " +
                                std::to_string(max_groups) + " (use fewer proxies, or --backend cpu)");
  ensure(dev, g.count, cells * 4, "point_voxels voxel counts");
  ensure(dev, g.pairs, sorted * 2 * sizeof(std::uint32_t), "point_voxels sort keys");
  ensure(dev, g.start, (cells + 1) * 4, "point_voxels cell ranges");
  ensure(dev, g.sprox, n * sizeof(GpuProxy), "point_voxels sorted proxies");
  ensure(dev, g.scan_status, gpu::kPvStatusWords * 4, "point_voxels scan status");
  g.sprox_hash = g.start_hash = 0;

  vk::ComputePipeline& keys = pipeline(dev, g.pipelines, "pv.voxel_keys", words(spv::point_voxels_voxel_keys_comp), {});
  vk::ComputePipeline& scan = pipeline(dev, g.pipelines, "pv.voxel_scan", words(spv::point_voxels_voxel_scan_comp), {});
  vk::ComputePipeline& scatter = pipeline(dev, g.pipelines, "pv.voxel_scatter", words(spv::point_voxels_voxel_scatter_comp), {});
  vk::ComputePipeline& sort = pipeline(dev, g.pipelines, "pv.voxel_sort", words(spv::point_voxels_voxel_sort_comp), {});
  struct Range {
    std::uint32_t first, end;
  };
  struct SortStep {
    std::uint32_t k, j;
  };
  const std::vector<vk::Bind> sort_binds = {vk::Bind::buffer_at(gpu::kPvSortBindPairs, g.pairs)};
  const std::uint32_t blocks = static_cast<std::uint32_t>(sorted / block);
  std::uint32_t sort_dispatches = 0;
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.fill(g.count, 0u);
    rec.fill(g.pairs, 0xffffffffu);  // the padding sorts last
    rec.fill(g.scan_status, 0u);
    rec.barrier();
    rec.begin_timer("voxelize");
    dispatch(rec, keys, {vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid), vk::Bind::buffer_at(gpu::kPvKeyBindProxies, g.uprox),
                         vk::Bind::buffer_at(gpu::kPvKeyBindCount, g.count), vk::Bind::buffer_at(gpu::kPvKeyBindPairs, g.pairs)},
             n, Range{});
    rec.barrier();
    rec.dispatch(scan,
                 {vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid), vk::Bind::buffer_at(gpu::kPvScanBindCount, g.count),
                  vk::Bind::buffer_at(gpu::kPvScanBindStart, g.start), vk::Bind::buffer_at(gpu::kPvScanBindStatus, g.scan_status)},
                 static_cast<const void*>(nullptr), 0u, 1u);
    // voxel_sort.comp's network: each block sorted in shared memory, then per merge k the steps
    // j >= block one dispatch each and the rest in the blocks again.
    const auto sort_step = [&](std::uint32_t k, std::uint32_t j) {
      rec.dispatch(sort, sort_binds, SortStep{k, j}, blocks);  // a block's pairs per workgroup
      rec.barrier();
      ++sort_dispatches;
    };
    sort_step(0, 0);
    for (std::size_t k = 2 * block; k <= sorted; k *= 2) {
      for (std::size_t j = k / 2; j >= block; j /= 2) sort_step(static_cast<std::uint32_t>(k), static_cast<std::uint32_t>(j));
      sort_step(static_cast<std::uint32_t>(k), 0);
    }
    dispatch(rec, scatter, {vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid), vk::Bind::buffer_at(gpu::kPvScatBindIn, g.uprox),
                            vk::Bind::buffer_at(gpu::kPvScatBindPairs, g.pairs), vk::Bind::buffer_at(gpu::kPvScatBindOut, g.sprox)},
             n, Range{});
    rec.end_timer();
    rec.barrier();
  }, "point_voxels voxelize");
  // The keys pass wrote each proxy's key into the unsorted copy; it writes the same keys from the same
  // positions every frame, so the host copy's hash still stands for what the next frame needs.
  std::uint32_t status[gpu::kPvStatusWords];
  dev.download(g.scan_status, status, sizeof status);
  d.largest = status[gpu::kPvStatusLargest];

  auto& rec = ctx.record();
  rec.counters["voxels"] = static_cast<double>(cells);
  rec.counters["voxels_occupied"] = status[gpu::kPvStatusCount];
  rec.counters["largest_voxel"] = d.largest;
  rec.counters["sort_dispatches"] = sort_dispatches;
  rec.counters["kernel_gpu_seconds"] = res.gpu_seconds;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = n * sizeof(GpuProxy) * 2 + (cells * 2 + 1) * 4 + sorted * 8;
  ctx.put_deferred<std::shared_ptr<const Voxels>>(kVoxels, [d, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    return read_voxels(dev, d, g.sprox, g.start, nullptr, nullptr);
  });
  ctx.put_device<DeviceVoxels>(kVoxels, d);
}

void vulkan_light_vpls(const Settings& s, FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const DeviceVoxels d = voxels_on_device(ctx, dev, g, kVoxels, "light_vpls");
  const DeviceLights* dl = ctx.device_copy<DeviceLights>(kLightMaps);
  const std::shared_ptr<const Lights> lights_ptr = dl ? dl->meta : ctx.get<std::shared_ptr<const Lights>>(kLightMaps);
  const Lights& L = *lights_ptr;
  const std::size_t n = d.proxies, cells = d.frame.cells();
  const std::uint32_t k_rays = L.sky ? static_cast<std::uint32_t>(s.vpl_env_rays) : 0u;
  check_fits(dev, cells * gpu::kPvVoxelFloats * sizeof(float), "the SH of " + std::to_string(cells) + " voxels", "light_vpls");

  const std::size_t before = dev.transfer_bytes().upload;
  // The lights: per local light its centre, radius and radiance; the sky's SH; the depth maps where
  // the light_maps pass did not leave them on the device (a host pass made them): every local
  // light's cube map, the sun's directional map after its header.
  std::vector<glm::vec4> lights;
  const int size = L.local.empty() ? 1 : L.local[0].size;
  for (std::size_t l = 0; l < L.local.size(); ++l) {
    if (L.local[l].size != size) throw std::logic_error("point_voxels light_vpls on vulkan: the cube maps differ in size");
    lights.push_back(glm::vec4(L.local_lights[l].position, L.local_lights[l].radius));
    lights.push_back(glm::vec4(L.local_lights[l].radiance, 0.0f));
  }
  if (!dl) {
    std::vector<float> cube;
    for (const auto& m : L.local) cube.insert(cube.end(), m.depth.begin(), m.depth.end());
    check_fits(dev, cube.size() * sizeof(float), "the cube depth maps of " + std::to_string(L.local.size()) + " lights", "light_vpls");
    std::vector<float> sun = sun_header(L);
    if (L.sun) sun.insert(sun.end(), L.sun_map.depth.begin(), L.sun_map.depth.end());
    check_fits(dev, sun.size() * sizeof(float), "the sun's depth map", "light_vpls");
    put_if_changed(dev, g.maps.cube, g.maps.cube_hash, cube, "point_voxels cube depth maps");
    put_if_changed(dev, g.maps.sun, g.maps.sun_hash, sun, "point_voxels sun depth map");
  }
  std::vector<glm::vec4> sky(kSkyOrder * kSkyOrder, glm::vec4(0.0f));
  for (std::size_t i = 0; i < sky.size() && i < L.sky_sh.size(); ++i) sky[i] = glm::vec4(L.sky_sh[i], 0.0f);
  put_if_changed(dev, g.lights, g.lights_hash, lights, "point_voxels lights");
  put_if_changed(dev, g.sky, g.sky_hash, sky, "point_voxels sky SH");
  const std::size_t uploaded = dev.transfer_bytes().upload - before;

  // kVpls owns copies of the sorted proxies and ranges, so that kVoxels may be replaced later.
  ensure(dev, g.vprox, n * sizeof(GpuProxy), "point_voxels VPLs");
  ensure(dev, g.vstart, (cells + 1) * 4, "point_voxels VPL cell ranges");
  ensure(dev, g.radiance, n * sizeof(glm::vec4), "point_voxels VPL radiance");
  ensure(dev, g.vsh, cells * gpu::kPvVoxelFloats * 4, "point_voxels voxel SH");
  ensure(dev, g.march_status, gpu::kPvStatusWords * 4, "point_voxels march status");
  g.vprox_hash = g.vstart_hash = g.radiance_hash = g.vsh_hash = 0;
  MarchRun run;
  {
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      if (n) rec.copy(g.sprox, g.vprox, n * sizeof(GpuProxy));
      rec.copy(g.start, g.vstart, (cells + 1) * 4);
      rec.fill(g.vsh, 0u);
      rec.barrier();
    }, "point_voxels light_vpls copies");
    run.seconds += std::max(0.0, res.gpu_seconds);
  }
  bool lanes = false;
  vk::ComputePipeline& march = march_pipeline(dev, g, s, gpu::kPvSourceProxies, lanes);
  vk::ComputePipeline& light = pipeline(dev, g.pipelines, "pv.vpl_light", words(spv::point_voxels_vpl_light_comp), {});
  vk::ComputePipeline& finish = pipeline(dev, g.pipelines, "pv.vpl_finish", words(spv::point_voxels_vpl_finish_comp), {});
  const std::size_t per_batch = k_rays ? std::max<std::size_t>(1, batch_items(dev) / k_rays) : std::max<std::size_t>(1, n);
  ensure(dev, g.items, std::min(n, per_batch) * std::max<std::uint32_t>(1, k_rays) * sizeof(GpuItem), "point_voxels march items");
  struct LightPush {
    std::uint32_t first, end, first_item, local_lights, cube_size, env_rays;
    float env_scale;
    std::uint32_t has_sun;
    glm::vec4 sun_irradiance;
  };
  const LightPush lp{0, 0, 0, static_cast<std::uint32_t>(L.local.size()), static_cast<std::uint32_t>(size), k_rays,
                     k_rays ? kPi / static_cast<float>(k_rays) : 0.0f, L.sun ? 1u : 0u, glm::vec4(L.sun_irradiance, 0.0f)};
  const std::vector<vk::Bind> march_binds = {
      vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid),          vk::Bind::buffer_at(gpu::kPvMarchBindProxies, g.vprox),
      vk::Bind::texels_at(gpu::kPvMarchBindStart, g.vstart, VK_FORMAT_R32_UINT), vk::Bind::buffer_at(gpu::kPvMarchBindPixels, g.vprox),
      vk::Bind::buffer_at(gpu::kPvMarchBindSky, g.sky),       vk::Bind::buffer_at(gpu::kPvMarchBindItems, g.items),
      vk::Bind::buffer_at(gpu::kPvMarchBindStatus, g.march_status),
      vk::Bind::texels_at(gpu::kPvMarchBindDiscs, g.vprox, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::buffer_at(gpu::kPvMarchBindSources, g.vstart)};  // as the pixels: not read for proxy sources
  const std::vector<vk::Bind> light_binds = {
      vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid),          vk::Bind::buffer_at(gpu::kPvLitBindProxies, g.vprox),
      vk::Bind::buffer_at(gpu::kPvLitBindItems, g.items),     vk::Bind::buffer_at(gpu::kPvLitBindLights, g.lights),
      vk::Bind::buffer_at(gpu::kPvLitBindCube, g.maps.cube),  vk::Bind::buffer_at(gpu::kPvLitBindSun, g.maps.sun),
      vk::Bind::buffer_at(gpu::kPvLitBindRadiance, g.radiance)};
  for (std::size_t first = 0; first < n; first += per_batch) {
    const std::size_t end = std::min(n, first + per_batch);
    if (k_rays) run_march(dev, g, march, march_binds, first, end, k_rays, true, lanes, d.frame.dims, run, "point_voxels light_vpls environment rays");
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      rec.begin_timer("vpl_light");
      LightPush q = lp;
      q.first_item = static_cast<std::uint32_t>(first);
      dispatch_chunks<LightPush>(rec, light, light_binds, end - first, gpu::kPvGroup, [&](std::uint32_t a, std::uint32_t b) {
        LightPush x = q;
        x.first = static_cast<std::uint32_t>(first) + a;
        x.end = static_cast<std::uint32_t>(first) + b;
        return x;
      });
      rec.end_timer();
      rec.barrier();
    }, "point_voxels vpl_light");
    run.seconds += std::max(0.0, res.gpu_seconds);
  }
  // Each cell's VPLs in runs the driver's loop limit allows (the VPL loop, and vpl_finish's 20
  // iterations of writes), one dispatch per run, each going on from the sums of the one before.
  std::uint32_t finish_dispatches = 0;
  {
    struct FinishPush {
      std::uint32_t first, end, from, len;
    };
    const std::uint32_t budget = loop_budget(dev.device_info());
    const std::uint32_t len = budget == std::numeric_limits<std::uint32_t>::max() ? budget : std::max<std::uint32_t>(1, budget - 32);
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      rec.begin_timer("vpl_finish");
      std::uint32_t from = 0;
      do {
        dispatch(rec, finish, {vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid), vk::Bind::buffer_at(gpu::kPvFinBindStart, g.vstart),
                               vk::Bind::buffer_at(gpu::kPvFinBindSh, g.vsh), vk::Bind::buffer_at(gpu::kPvFinBindProxies, g.vprox),
                               vk::Bind::buffer_at(gpu::kPvFinBindRadiance, g.radiance)},
                 cells, FinishPush{0, 0, from, len});
        rec.barrier();
        ++finish_dispatches;
        from = len > d.largest - from ? d.largest : from + len;
      } while (from < d.largest);
      rec.end_timer();
    }, "point_voxels vpl_finish");
    run.seconds += std::max(0.0, res.gpu_seconds);
  }
  auto& rec = ctx.record();
  rec.counters["vpls"] = static_cast<double>(n);
  rec.counters["env_rays"] = static_cast<double>(n) * k_rays;
  rec.counters["march_dispatches"] = run.dispatches;
  rec.counters["march_lanes_discs"] = lanes ? 1.0 : 0.0;
  rec.counters["finish_dispatches"] = finish_dispatches;
  rec.counters["kernel_gpu_seconds"] = run.seconds;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = n * (sizeof(GpuProxy) + sizeof(glm::vec4)) + cells * (gpu::kPvVoxelFloats + 1) * 4;
  ctx.put_deferred<std::shared_ptr<const Voxels>>(kVpls, [d, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    return read_voxels(dev, d, g.vprox, g.vstart, &g.radiance, &g.vsh);
  });
  ctx.put_device<DeviceVoxels>(kVpls, d);
}

void vulkan_march(const Settings& s, FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& mg = ctx.get<GBuffer>(kMarchGBuffer);
  const DeviceVoxels d = voxels_on_device(ctx, dev, g, kVoxels, "march");
  std::shared_ptr<const Lights> lp;
  if (const auto* dl = ctx.device_copy<DeviceLights>(kLightMaps)) lp = dl->meta;
  else if (ctx.has(kLightMaps)) lp = ctx.get<std::shared_ptr<const Lights>>(kLightMaps);
  const Lights* L = lp.get();
  const bool sky = L && L->sky;
  const std::size_t np = static_cast<std::size_t>(mg.width) * mg.height;
  const std::uint32_t W = words_of(d.frame), rays = static_cast<std::uint32_t>(s.rays);
  check_index(np * W, "bitset words", "march");
  check_fits(dev, np * W * sizeof(std::uint32_t), "the voxel bitsets of " + std::to_string(np) + " marching pixels over " +
                                                       std::to_string(d.frame.cells()) + " voxels", "march");
  check_fits(dev, np * sizeof(GpuMarchPixel), "the " + std::to_string(np) + " marching pixels", "march");

  const std::size_t before = dev.transfer_bytes().upload;
  const std::size_t nh = put_pixels(dev, g, mg);
  std::vector<glm::vec4> sky_sh(kSkyOrder * kSkyOrder, glm::vec4(0.0f));
  if (sky)
    for (std::size_t i = 0; i < sky_sh.size() && i < L->sky_sh.size(); ++i) sky_sh[i] = glm::vec4(L->sky_sh[i], 0.0f);
  put_if_changed(dev, g.sky, g.sky_hash, sky_sh, "point_voxels sky SH");
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  ensure(dev, g.bits[0], np * W * 4, "point_voxels voxel bitsets");
  ensure(dev, g.fields[0], np * sizeof(glm::vec4), "point_voxels sky fields");
  ensure(dev, g.march_status, gpu::kPvStatusWords * 4, "point_voxels march status");
  ensure(dev, g.list_status, gpu::kPvStatusWords * 4, "point_voxels list status");
  g.bits_hash[0] = g.fields_hash[0] = 0;
  const std::size_t per_batch = std::max<std::size_t>(1, batch_items(dev) / rays);
  ensure(dev, g.items, std::min(std::max<std::size_t>(nh, 1), per_batch) * rays * sizeof(GpuItem), "point_voxels march items");

  bool lanes = false;
  vk::ComputePipeline& march = march_pipeline(dev, g, s, gpu::kPvSourcePixels, lanes);
  vk::ComputePipeline& lists = pipeline(dev, g.pipelines, "pv.march_lists", words(spv::point_voxels_march_lists_comp), {});
  const std::vector<vk::Bind> march_binds = {
      vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid),         vk::Bind::buffer_at(gpu::kPvMarchBindProxies, g.sprox),
      vk::Bind::texels_at(gpu::kPvMarchBindStart, g.start, VK_FORMAT_R32_UINT), vk::Bind::buffer_at(gpu::kPvMarchBindPixels, g.pixels),
      vk::Bind::buffer_at(gpu::kPvMarchBindSky, g.sky),      vk::Bind::buffer_at(gpu::kPvMarchBindItems, g.items),
      vk::Bind::buffer_at(gpu::kPvMarchBindStatus, g.march_status),
      vk::Bind::texels_at(gpu::kPvMarchBindDiscs, g.sprox, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::buffer_at(gpu::kPvMarchBindSources, g.sources)};
  const std::vector<vk::Bind> list_binds = {
      vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid),          vk::Bind::buffer_at(gpu::kPvListBindSources, g.sources),
      vk::Bind::buffer_at(gpu::kPvListBindItems, g.items),    vk::Bind::buffer_at(gpu::kPvListBindBits, g.bits[0]),
      vk::Bind::buffer_at(gpu::kPvListBindFields, g.fields[0]), vk::Bind::buffer_at(gpu::kPvListBindStatus, g.list_status)};
  struct ListPush {
    std::uint32_t first, end, rays, words;
    float sky_scale;
  };
  MarchRun run;
  {
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      rec.fill(g.bits[0], 0u);  // and the background's fields, which march_lists leaves alone
      rec.fill(g.fields[0], 0u);
      rec.fill(g.list_status, 0u);
      rec.barrier();
    }, "point_voxels march clear");
    run.seconds += std::max(0.0, res.gpu_seconds);
  }
  for (std::size_t first = 0; first < nh; first += per_batch) {
    const std::size_t end = std::min(nh, first + per_batch);
    run_march(dev, g, march, march_binds, first, end, rays, sky, lanes, d.frame.dims, run, "point_voxels march");
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      rec.begin_timer("march_lists");
      dispatch_chunks<ListPush>(rec, lists, list_binds, end - first, gpu::kPvGroup, [&](std::uint32_t a, std::uint32_t b) {
        return ListPush{static_cast<std::uint32_t>(first) + a, static_cast<std::uint32_t>(first) + b, rays, W, kPi / static_cast<float>(rays)};
      });
      rec.end_timer();
      rec.barrier();
    }, "point_voxels march_lists");
    run.seconds += std::max(0.0, res.gpu_seconds);
  }
  std::uint32_t status[gpu::kPvStatusWords];
  dev.download(g.list_status, status, sizeof status);
  const DeviceMarched dm{mg.width, mg.height, W, status[gpu::kPvStatusCount]};
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(nh);
  rec.counters["rays"] = static_cast<double>(nh) * s.rays;
  rec.counters["list_mean"] = nh ? static_cast<double>(dm.entries) / nh : 0.0;
  rec.counters["march_dispatches"] = run.dispatches;
  rec.counters["march_lanes_discs"] = lanes ? 1.0 : 0.0;
  rec.counters["kernel_gpu_seconds"] = run.seconds;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = np * (W * 4 + sizeof(glm::vec4) + sizeof(GpuMarchPixel)) + nh * sizeof(std::uint32_t) +
              std::min(nh, per_batch) * rays * sizeof(GpuItem);
  ctx.put_deferred<std::shared_ptr<const Marched>>(kLists, [dm, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    return read_marched(dev, dm, g.bits[0], &g.fields[0]);
  });
  ctx.put_device<DeviceMarched>(kLists, dm);
}

void vulkan_filter(const Settings& s, FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& mg = ctx.get<GBuffer>(kMarchGBuffer);
  const std::size_t np = static_cast<std::size_t>(mg.width) * mg.height;
  VoxelGrid cube;
  cube.dims = glm::ivec3(s.grid);
  const std::uint32_t W = words_of(cube);
  const std::size_t before = dev.transfer_bytes().upload;
  const DeviceMarched in = marched_on_device(ctx, dev, g, kLists, 0, W, "filter");
  const std::size_t hits = put_pixels(dev, g, mg);
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  check_fits(dev, np * W * sizeof(std::uint32_t), "the voxel bitsets of " + std::to_string(np) + " marching pixels", "filter");
  ensure(dev, g.bits[1], np * W * 4, "point_voxels filtered bitsets");
  ensure(dev, g.fields[1], np * sizeof(glm::vec4), "point_voxels filtered sky fields");
  ensure(dev, g.list_status, gpu::kPvStatusWords * 4, "point_voxels list status");
  g.bits_hash[1] = g.fields_hash[1] = 0;
  // filter_lists: one invocation per (pixel, run of `run` words).
  const std::uint32_t run = std::min(W, gpu::kPvFilterWords), runs = (W + run - 1) / run;
  vk::ComputePipeline& lists = pipeline(dev, g.pipelines, "pv.filter_lists.w" + std::to_string(run), words(spv::point_voxels_filter_lists_comp),
                                        {{0, run}});
  vk::ComputePipeline& fields = pipeline(dev, g.pipelines, "pv.filter_fields", words(spv::point_voxels_filter_fields_comp), {});
  struct Push {
    std::uint32_t first, end;
    std::int32_t width, height;
    std::uint32_t words;
    std::int32_t radius_x, radius_y;
    float depth_threshold, normal_threshold;
  };
  const Push push{0, 0, mg.width, mg.height, W, s.filter.radius_x, s.filter.radius_y, static_cast<float>(s.filter.depth_threshold),
                  static_cast<float>(s.filter.normal_threshold)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.fill(g.list_status, 0u);
    rec.barrier();
    rec.begin_timer("filter");
    dispatch(rec, lists,
             {vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid), vk::Bind::buffer_at(gpu::kPvFiltBindPixels, g.pixels),
              vk::Bind::buffer_at(gpu::kPvFiltBindIn, g.bits[0]), vk::Bind::buffer_at(gpu::kPvFiltBindOut, g.bits[1]),
              vk::Bind::buffer_at(gpu::kPvFiltBindStatus, g.list_status)},
             np * runs, push);
    dispatch(rec, fields,
             {vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid), vk::Bind::buffer_at(gpu::kPvFiltBindPixels, g.pixels),
              vk::Bind::buffer_at(gpu::kPvFiltBindIn, g.fields[0]), vk::Bind::buffer_at(gpu::kPvFiltBindOut, g.fields[1])},
             np, push);
    rec.end_timer();
    rec.barrier();
  }, "point_voxels filter");
  std::uint32_t status[gpu::kPvStatusWords];
  dev.download(g.list_status, status, sizeof status);
  const DeviceMarched dm{mg.width, mg.height, W, status[gpu::kPvStatusCount]};
  auto& rec = ctx.record();
  rec.counters["list_mean_before"] = hits ? static_cast<double>(in.entries) / hits : 0.0;
  rec.counters["list_mean"] = hits ? static_cast<double>(dm.entries) / hits : 0.0;
  rec.counters["kernel_gpu_seconds"] = res.gpu_seconds;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = np * (W * 4 + sizeof(glm::vec4));
  ctx.put_deferred<std::shared_ptr<const Marched>>(kFiltered, [dm, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    return read_marched(dev, dm, g.bits[1], nullptr);
  });
  ctx.put_deferred<std::shared_ptr<const SkyLight>>(kFilteredSky, [np, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    return read_sky(dev, np, g.fields[1]);
  });
  ctx.put_device<DeviceMarched>(kFiltered, dm);
}

void vulkan_gather(const Settings& s, FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& gg = ctx.get<GBuffer>(kGatherGBuffer);
  const auto& mg = ctx.get<GBuffer>(kMarchGBuffer);
  const std::size_t np = static_cast<std::size_t>(gg.width) * gg.height;
  const std::size_t before = dev.transfer_bytes().upload;
  const DeviceVoxels d = voxels_on_device(ctx, dev, g, kVpls, "gather");
  const std::uint32_t W = words_of(d.frame);
  marched_on_device(ctx, dev, g, kFiltered, 1, W, "gather");
  put_pixels(dev, g, mg);
  check_index(np, "gathering pixels", "gather");
  check_fits(dev, np * sizeof(GpuGatherPixel), "the " + std::to_string(np) + " gathering pixels", "gather");
  std::vector<GpuGatherPixel> recv(np);
  std::vector<std::uint32_t> sources;  // the pixels that see a surface: gather.comp's invocations
  sources.reserve(np);
  bool glossy = false, eq7 = false;
  for (std::size_t i = 0; i < np; ++i) {
    if (!gg.hit(i)) continue;
    sources.push_back(static_cast<std::uint32_t>(i));
    Receiver r = receiver_at(ctx, gg, i);
    if (s.eq7 && r.glossy > 0.0f) r.eq7_sigma = eq7_sigma(r.ns, static_cast<float>(s.eq7_sigma_scale));
    glossy = glossy || r.glossy > 0.0f;
    eq7 = eq7 || (r.glossy > 0.0f && r.eq7_sigma > 0.0f);
    recv[i] = {glm::vec4(r.position, gg.depth[i]), glm::vec4(r.normal, r.glossy), glm::vec4(r.reflect, r.ns),
               glm::vec4(r.eq7_sigma, 0.0f, (r.ns + 2.0f) / (2.0f * kPi), 0.0f)};
  }
  put_if_changed(dev, g.receivers, g.receivers_hash, recv, "point_voxels gathering pixels");
  const std::size_t hits = sources.size();
  if (sources.empty()) sources.push_back(0u);  // a buffer is never empty; no invocation reads it
  put_if_changed(dev, g.gsources, g.gsources_hash, sources, "point_voxels gathering sources");
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  ensure(dev, g.gathered, np * sizeof(GpuGathered), "point_voxels gathered light");
  ensure(dev, g.gstate, np * sizeof(GpuGatherState), "point_voxels gathering state");
  ensure(dev, g.gather_status, gpu::kPvStatusWords * 4, "point_voxels gather status");

  const float near_range = static_cast<float>(s.near_range) * d.diagonal;
  // The glossy lobe's and eq. 7's code only where some pixel of this frame needs it (gather.comp).
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, std::string("pv.gather") + (glossy ? ".glossy" : "") + (eq7 ? ".eq7" : ""),
                                    words(spv::point_voxels_gather_comp), {{0, glossy ? 1u : 0u}, {1, eq7 ? 1u : 0u}});
  struct Push {
    std::uint32_t first, end;
    std::int32_t gw, mw, mh;
    std::uint32_t words;
    float ratio, sigma_depth, sigma_normal, near2, reg, eq7_norm;
    std::uint32_t budget;
  };
  const Push push{0, 0, gg.width, mg.width, mg.height, W, static_cast<float>(gg.scale) / static_cast<float>(mg.scale),
                  static_cast<float>(s.sigma_depth), static_cast<float>(s.sigma_normal), near_range * near_range, d.patch_area / kPi,
                  std::sqrt(2.0f * kPi), loop_budget(dev.device_info())};
  const std::vector<vk::Bind> binds = {
      vk::Bind::buffer_at(gpu::kPvBindGrid, g.grid),
      vk::Bind::texels_at(gpu::kPvGathBindProxies, g.vprox, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kPvGathBindRadiance, g.radiance, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kPvGathBindStart, g.vstart, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kPvGathBindSh, g.vsh, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kPvGathBindMarch, g.pixels, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kPvGathBindBits, g.bits[1], VK_FORMAT_R32_UINT),
      vk::Bind::buffer_at(gpu::kPvGathBindReceivers, g.receivers),
      vk::Bind::buffer_at(gpu::kPvGathBindOut, g.gathered),      vk::Bind::buffer_at(gpu::kPvGathBindState, g.gstate),
      vk::Bind::buffer_at(gpu::kPvGathBindStatus, g.gather_status), vk::Bind::buffer_at(gpu::kPvGathBindSources, g.gsources)};
  double secs = 0.0;
  int dispatches = 0;
  std::uint32_t status[gpu::kPvStatusWords];
  std::uint32_t gathered = 0, unmatched = 0;
  for (;; ++dispatches) {
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      if (dispatches == 0) {
        rec.fill(g.gathered, 0u);
        rec.fill(g.gstate, 0u);
      }
      rec.fill(g.gather_status, 0u);
      rec.barrier();
      rec.begin_timer("gather");
      dispatch(rec, p, binds, hits, push);
      rec.end_timer();
      rec.barrier();
    }, "point_voxels gather");
    secs += std::max(0.0, res.gpu_seconds);
    dev.download(g.gather_status, status, sizeof status);
    gathered += status[gpu::kPvStatusCount];
    unmatched += status[gpu::kPvStatusUnmatched];
    if (status[gpu::kPvStatusUnfinished] == 0) break;
    if (dispatches > 1 << 20) throw std::logic_error("point_voxels gather on vulkan: pixels still unfinished after " + std::to_string(dispatches) + " dispatches");
  }
  ++dispatches;
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(hits);
  rec.counters["unmatched"] = unmatched;
  rec.counters["voxels_per_pixel"] = hits ? static_cast<double>(gathered) / hits : 0.0;
  rec.counters["near_range"] = near_range;
  rec.counters["dispatches"] = dispatches;
  rec.counters["glossy_code"] = glossy ? 1.0 : 0.0;
  rec.counters["eq7_code"] = eq7 ? 1.0 : 0.0;
  rec.counters["kernel_gpu_seconds"] = secs;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = np * (sizeof(GpuGatherPixel) + sizeof(GpuGathered) + sizeof(GpuGatherState));
  ctx.put_deferred<std::shared_ptr<const std::vector<Gathered>>>(kGathered, [np, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    const auto raw = download<GpuGathered>(dev, g.gathered, np);
    auto out = std::make_shared<std::vector<Gathered>>(np);
    for (std::size_t i = 0; i < np; ++i) {
      (*out)[i].irradiance = glm::vec3(raw[i].irradiance);
      (*out)[i].glossy = glm::vec3(raw[i].glossy);
      (*out)[i].weighted = glm::vec3(raw[i].weighted);
      (*out)[i].eq7 = raw[i].weighted.w != 0.0f;
    }
    return std::shared_ptr<const std::vector<Gathered>>(out);
  });
}

// Figure 2a's depth maps rasterised on the device (pv_depth_vulkan.cpp); they stay there for the VPL
// lighting, and the host copy (the direct pass's) is read back when asked for.
void vulkan_light_maps_pass(const Settings& s, FrameContext& ctx, std::shared_ptr<Lights> L) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  vulkan_light_maps(s, ctx, L, g.maps);
  std::shared_ptr<const Lights> meta = L;
  ctx.put_deferred<std::shared_ptr<const Lights>>(kLightMaps, [meta, &g, &dev]() {
    std::lock_guard<std::mutex> l(g.m);
    auto full = std::make_shared<Lights>(*meta);
    std::size_t offset = 0;
    for (auto& m : full->local) {
      const std::size_t texels = 6 * static_cast<std::size_t>(m.size) * m.size;
      m.depth.resize(texels);
      dev.download(g.maps.cube, m.depth.data(), texels * sizeof(float), offset * sizeof(float));
      offset += texels;
    }
    if (full->sun) {
      const std::size_t texels = static_cast<std::size_t>(full->sun_map.size) * full->sun_map.size;
      full->sun_map.depth.resize(texels);
      dev.download(g.maps.sun, full->sun_map.depth.data(), texels * sizeof(float), gpu::kPvSunHeader * sizeof(float));
    }
    return std::shared_ptr<const Lights>(full);
  });
  ctx.put_device<DeviceLights>(kLightMaps, DeviceLights{meta});
}

}  // namespace

void register_vulkan_kernels() {
  DeviceKernels k;
  k.voxelize = vulkan_voxelize;
  k.light_vpls = vulkan_light_vpls;
  k.march = vulkan_march;
  k.filter = vulkan_filter;
  k.gather = vulkan_gather;
  k.light_maps = vulkan_light_maps_pass;
  register_device_kernels(vk::kBackendName, std::move(k));
}

}  // namespace softgi::techniques::point_voxels
