// The diffuse shading of receivers on the Vulkan backend (shaders/common/shade.comp): SHEXP's shade
// pass and image_splat's shade_direct (with paper 000's eq. 11 gather) run this one dispatch. The
// product plan, basis constants and light-lobe table are the CPU's own floats, uploaded once per
// device (the table again when it changes) and kept in the context's cache.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/frame.hpp"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/common/shade_comp.h"
}  // namespace spv

namespace softgi::techniques::common {

namespace vk = backends::vulkan;
using namespace gpu_passes;

namespace {

// Per-device state of the shading dispatch: pipelines by specialisation, buffers reused from frame to frame (grown when a frame needs more).
struct ShadeState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer shade_rec, shade_vis, shade_consts, shade_out, shade_status, shade_lights;
  vk::Buffer shade_tap_pixel, shade_tap_index, shade_tap_weight, shade_coarse_row;  // eq. 11 gather (paper 000)
  std::uint64_t rec_hash = 0;     // what shade_rec holds (upload_receivers)
  vk::Buffer light_table;         // LightLobeTable psi then k
  std::vector<float> light_host;  // the floats in light_table (upload_if_changed)
  std::vector<float> consts_host; // the floats in shade_consts (upload_if_changed)
};

ShadeState& shade_state(vk::Context& dev) {
  return *dev.cached<ShadeState>("common.shade", [] { return std::make_shared<ShadeState>(); });
}

void check_fits_shade(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  gpu_passes::check_fits(dev, bytes, what, pass, "use fewer receivers or a smaller frame, or --backend cpu");
}

}  // namespace

namespace {

// vulkan_shade for receivers from `soa`, or (pixels non-null) for `pixel_count` display pixels of the
// G-buffer planes on the device.
long long shade(render::FrameContext& ctx, const GpuShade& in, const ReceiverSoA& soa, const vk::DeviceGBuffer* pixels,
                std::size_t pixel_count, glm::vec3* out) {
  if (!in.b) throw std::logic_error("shade on vulkan: no shading constants");
  const BatchShade& b = *in.b;
  vk::Context& dev = vk::context_of(ctx);
  ShadeState& g = shade_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const int n = b.order, n2 = n * n;
  const std::size_t count = pixels ? pixel_count : soa.size();
  if (count == 0) return 0;
  if (pixels && !(in.gather && in.gather->pixel))
    throw std::logic_error("shade on vulkan: receivers at display pixels without the gather's pixel list");
  if (count > std::numeric_limits<std::uint32_t>::max() / 8)
    throw std::invalid_argument("shade on vulkan: " + std::to_string(count) + " receivers exceed the 32-bit indexing");
  check_fits_shade(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", "shade");
  const bool lights = in.lights_table && in.lights && !in.lights->empty();
  const GpuShade::Gather* ga = in.gather;
  const DeviceField* dvis = !ga && in.visibility_resource ? device_field(ctx, in.visibility_resource) : nullptr;
  if (dvis && dvis->floats != count * static_cast<std::size_t>(n2))
    throw std::logic_error("shade on vulkan: the device visibility does not match the " + std::to_string(count) + " receivers");
  // A gather's coarse field on the device (image_splat's O_p, left there by exponentiate).
  const DeviceField* dcoarse = ga && ga->coarse_resource ? device_field(ctx, ga->coarse_resource) : nullptr;
  if (ga && ga->coarse_resource && !dcoarse)
    throw std::logic_error(std::string("shade on vulkan: no device copy of '") + ga->coarse_resource + "' to gather from");
  if (dcoarse && (dcoarse->order != n || dcoarse->floats % static_cast<std::size_t>(n2) != 0))
    throw std::logic_error("shade on vulkan: the device field to gather from is not of order " + std::to_string(n));
  const std::uint32_t vis_mode = ga ? gpu::kShadeVisGather : (b.g || dvis ? gpu::kShadeVisReceiver : gpu::kShadeVisNone);
  const vk::Buffer& basis = basis_constants(dev);
  if (pixels) {
    // Every receiver's pixel, checked here: the shader reads the planes unchecked.
    const std::size_t np = static_cast<std::size_t>(pixels->width) * static_cast<std::size_t>(pixels->height);
    const std::int32_t* px = in.gather->pixel;
    const std::size_t bad = first_bad_in_blocks(count, std::size_t{1} << 14, [&](std::size_t begin, std::size_t e) {
      for (std::size_t i = begin; i < e; ++i)
        if (px[i] < 0 || static_cast<std::size_t>(px[i]) >= np) return i;
      return e;
    });
    if (bad < count)
      throw std::logic_error("shade on vulkan: receiver " + std::to_string(bad) + " is display pixel " + std::to_string(px[bad]) + " of " +
                             std::to_string(np));
    // Bound, unread; a buffer from an earlier dispatch keeps its receivers (and rec_hash, their hash).
    if (!g.shade_rec) dev.ensure_buffer(g.shade_rec, 6 * sizeof(float), kStorage, vk::MemoryKind::Device, "shade receivers");
  } else {
    upload_receivers(dev, g.shade_rec, soa, "shade receivers", &g.rec_hash);
  }
  // Visibility: per receiver, or the coarse field of a gather (uploaded unless it is on the device).
  const float* vsrc = ga ? (dcoarse ? nullptr : ga->coarse) : dvis ? nullptr : b.g;
  const std::size_t vrows = ga ? (dcoarse ? dcoarse->floats / n2 : ga->coarse_count) : count;
  const std::size_t vis_bytes = vsrc ? vrows * n2 * sizeof(float) : 0;
  check_fits_shade(dev, vis_bytes, "the visibility of " + std::to_string(vrows) + (ga ? " coarse samples" : " receivers"), "shade");
  // At least one RGBA32F texel: the buffer is bound as both views.
  dev.ensure_buffer(g.shade_vis, std::max<std::size_t>(16, vis_bytes), kStorage, vk::MemoryKind::Device, "shade visibility");
  if (vis_bytes) dev.upload(g.shade_vis, vsrc, vis_bytes);
  ResidentTaps taps;
  if (ga) {
    if (!ga->pixel || !ga->index || !ga->weight || (!dcoarse && ga->coarse_count && !ga->coarse))
      throw std::logic_error("shade on vulkan: incomplete gather");
    // Every tap's row of the field, checked here: the shader reads it unchecked.
    const std::size_t samples = ga->coarse_row ? ga->coarse_rows : vrows;
    for (std::size_t q = 0; ga->coarse_row && q < ga->coarse_rows; ++q)
      if (ga->coarse_row[q] >= 0 && static_cast<std::size_t>(ga->coarse_row[q]) >= vrows)
        throw std::logic_error("shade on vulkan: coarse sample " + std::to_string(q) + " reads row " + std::to_string(ga->coarse_row[q]) +
                               " of " + std::to_string(vrows));
    auto bad_tap = [&](std::int32_t t) {
      return t >= 0 && (static_cast<std::size_t>(t) >= samples || (ga->coarse_row && ga->coarse_row[t] < 0));
    };
    // Over the display's pixels on every core; the error names the first pixel with a bad tap.
    const std::size_t first_bad = first_bad_in_blocks(ga->pixels, std::size_t{1} << 14, [&](std::size_t begin, std::size_t e) {
      for (std::size_t p = begin; p < e; ++p)
        if (bad_tap(ga->index[p][0]) || bad_tap(ga->index[p][1]) || bad_tap(ga->index[p][2]) || bad_tap(ga->index[p][3])) return p;
      return e;
    });
    if (const std::size_t p = first_bad; p < ga->pixels)
      for (std::int32_t t : ga->index[p])
        if (bad_tap(t))
          throw std::logic_error("shade on vulkan: display pixel " + std::to_string(p) + " gathers coarse sample " + std::to_string(t) +
                                 (ga->coarse_row ? ", which has no row of the field" : " of " + std::to_string(vrows)));
    dev.ensure_buffer(g.shade_tap_pixel, count * sizeof(std::int32_t), kStorage, vk::MemoryKind::Device, "shade tap pixels");
    dev.upload(g.shade_tap_pixel, ga->pixel, count * sizeof(std::int32_t));
    // The taps and weights upsample left on the device are bound as they are; others are uploaded.
    taps = resident_upsample_taps(dev, ga->index, ga->pixels);
    if (!taps.index) {
      dev.ensure_buffer(g.shade_tap_index, ga->pixels * 16, kStorage, vk::MemoryKind::Device, "shade tap index");
      dev.upload(g.shade_tap_index, ga->index, ga->pixels * 16);
      dev.ensure_buffer(g.shade_tap_weight, ga->pixels * 16, kStorage, vk::MemoryKind::Device, "shade tap weights");
      dev.upload(g.shade_tap_weight, ga->weight, ga->pixels * 16);
    }
    dev.ensure_buffer(g.shade_coarse_row, std::max<std::size_t>(16, ga->coarse_rows * sizeof(std::int32_t)), kStorage, vk::MemoryKind::Device,
                      "shade coarse rows");
    if (ga->coarse_row) dev.upload(g.shade_coarse_row, ga->coarse_row, ga->coarse_rows * sizeof(std::int32_t));
  } else {
    for (vk::Buffer* buf : {&g.shade_tap_pixel, &g.shade_tap_index, &g.shade_tap_weight, &g.shade_coarse_row})
      dev.ensure_buffer(*buf, 16, kStorage, vk::MemoryKind::Device, "shade taps (unused)");
  }
  // The uniform block's whole size (std140, vec4s), the floats past 5 n^2 unread.
  std::vector<float> consts(gpu::kShadeConstFloats, 0.0f);
  std::copy(b.L, b.L + 3 * n2, consts.begin());
  std::copy(b.hcoef, b.hcoef + n2, consts.begin() + 3 * n2);
  std::copy(b.gwin, b.gwin + n2, consts.begin() + 4 * n2);
  upload_if_changed(dev, g.shade_consts, g.consts_host, consts, "shade constants", kStorage | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);

  // Paper 004 section 7: the light-lobe table (the CPU's floats, uploaded when they change) and the
  // posed lights.
  const LightLobeTable* lt = in.lights_table;
  std::vector<float> light_data;
  if (lights) {
    if (lt->order != n)
      throw std::logic_error("shade on vulkan: light table of order " + std::to_string(lt->order) + " for order " + std::to_string(n));
    std::vector<float> tab(lt->psi);
    tab.insert(tab.end(), lt->k.begin(), lt->k.end());
    upload_if_changed(dev, g.light_table, g.light_host, tab, "shade light lobe table");
    for (const auto& l : *in.lights) {
      light_data.insert(light_data.end(), {l.position.x, l.position.y, l.position.z, l.radius});
      light_data.insert(light_data.end(), {l.radiance.x, l.radiance.y, l.radiance.z, 0.0f});
    }
  } else if (!g.light_table) {
    upload_if_changed(dev, g.light_table, g.light_host, {}, "shade light lobe table (unused)");
  }
  put(dev, g.shade_lights, light_data, "shade spherical lights");
  const std::uint32_t zero = 0;
  dev.ensure_buffer(g.shade_status, sizeof zero, kStorage, vk::MemoryKind::Host, "shade status");
  dev.upload(g.shade_status, &zero, sizeof zero);
  dev.ensure_buffer(g.shade_out, count * 4 * sizeof(float), kStorage, vk::MemoryKind::Host, "shading");

  vk::ComputePipeline& p = pipeline(dev, g.pipelines,
                                    "common.shade.n" + std::to_string(n) + ".vis" + std::to_string(vis_mode) + (lights ? ".lights" : "") +
                                        (pixels ? ".pixels" : ""),
                                    order_variant(spv::common_shade_comp_for(n), n, "shade"),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, vis_mode}, {2, lights ? 1u : 0u},
                                     {3, pixels ? gpu::kShadeRecPixels : gpu::kShadeRecPlanes}});
  struct Push {
    std::uint32_t count, first, end, flags, light_count, rows_theta, rows_f;
    float theta_floor;
  };
  const std::uint32_t flags =
      (in.zero_normal_empty ? gpu::kShadeFlagZeroNormalEmpty : 0u) | (ga && ga->coarse_row ? gpu::kShadeFlagCoarseRow : 0u);
  const std::uint32_t nl = lights ? static_cast<std::uint32_t>(in.lights->size()) : 0u;
  const std::uint32_t rt = lights ? static_cast<std::uint32_t>(lt->rows_theta) : 2u, rf = lights ? static_cast<std::uint32_t>(lt->rows_f) : 2u;
  const vk::Buffer& vis_buffer = dvis ? *dvis->buffer : dcoarse ? *dcoarse->buffer : g.shade_vis;
  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kShadeBindReceivers, g.shade_rec, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kShadeBindVis, vis_buffer, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kShadeBindVis4, vis_buffer, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::buffer_at(gpu::kShadeBindConsts, g.shade_consts), vk::Bind::buffer_at(gpu::kShadeBindBasis, basis),
      vk::Bind::buffer_at(gpu::kShadeBindOut, g.shade_out),
      vk::Bind::texels_at(gpu::kShadeBindTapPixel, g.shade_tap_pixel, VK_FORMAT_R32_SINT),
      vk::Bind::texels_at(gpu::kShadeBindTapIndex, taps.index ? *taps.index : g.shade_tap_index, VK_FORMAT_R32G32B32A32_SINT),
      vk::Bind::texels_at(gpu::kShadeBindTapWeight, taps.weight ? *taps.weight : g.shade_tap_weight, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kShadeBindCoarseRow, g.shade_coarse_row, VK_FORMAT_R32_SINT),
      vk::Bind::texels_at(gpu::kShadeBindLightTable, g.light_table, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kShadeBindLights, g.shade_lights, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::buffer_at(gpu::kShadeBindStatus, g.shade_status),
      vk::Bind::texels_at(gpu::kShadeBindPixelPosition, pixels ? *pixels->position_depth : g.shade_vis, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kShadeBindPixelNormal, pixels ? *pixels->normal_depth : g.shade_vis, VK_FORMAT_R32G32B32A32_SFLOAT)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("shade");
    dispatch_chunks<Push>(rec, p, binds, count, gpu::kShadeGroup, [&](std::uint32_t first, std::uint32_t end) {
      return Push{static_cast<std::uint32_t>(count), first, end, flags, nl, rt, rf, static_cast<float>(kLightThetaFloor)};
    });
    rec.end_timer();
    rec.barrier();
  }, "shade");
  // The shading read once, where it lies (through the mapping of the host buffer the shader wrote,
  // MemoryKind::Host), on every core; a copy first would cost the frame a zero-filled vector and a
  // second pass.
  const float* shaded = static_cast<const float*>(g.shade_out.mapped());
  dev.note_transfer(0, count * 4 * sizeof(float));
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1 << 14), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i != br.end(); ++i) out[i] = glm::vec3(shaded[4 * i], shaded[4 * i + 1], shaded[4 * i + 2]);
  });
  std::uint32_t clamped = 0;
  dev.download(g.shade_status, &clamped, sizeof clamped);
  // Summed over the pass's shading dispatches (image_splat shades surface pixels and misses apart).
  const double secs = timer_seconds(res);
  double& total = ctx.record().counters["kernel_gpu_seconds"];
  total = secs < 0.0 ? secs : std::max(total, 0.0) + secs;
  return clamped;
}

}  // namespace

long long vulkan_shade(render::FrameContext& ctx, const GpuShade& in, const ReceiverSoA& soa, glm::vec3* out) {
  return shade(ctx, in, soa, nullptr, 0, out);
}

long long vulkan_shade_pixels(render::FrameContext& ctx, const GpuShade& in, const vk::DeviceGBuffer& pixels, std::size_t count,
                              glm::vec3* out) {
  return shade(ctx, in, ReceiverSoA{}, &pixels, count, out);
}

}  // namespace softgi::techniques::common
