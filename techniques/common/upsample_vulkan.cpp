// Bilateral and bilinear upsampling (paper 000 section 4.2, eq. 11) on the Vulkan backend: the
// eq. 11 weights (shaders/common/upsample_weights.comp) and their application to a coarse field
// (upsample_apply.comp), with upsample.cpp's checks and messages. The weights stay on the device
// for the applications that follow them.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/frame_pool.hpp"
#include "softgi_shared.h"
#include "upsample.hpp"
#include "upsample_shared.h"

namespace spv {
#include "softgi/shaders/common/upsample_apply_comp.h"
#include "softgi/shaders/common/upsample_weights_comp.h"
}  // namespace spv

namespace softgi::techniques::common {

namespace vk = backends::vulkan;
using namespace gpu_passes;

namespace {

// Per-device state: pipelines, and buffers reused from frame to frame (grown when needed).
struct UpsampleState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer fine_nz, coarse_nz, surface, up_index, up_weight, up_miss;  // weights
  const void* up_resident = nullptr;  // UpsampleWeights::index.data() of the weights in up_index / up_weight
  std::size_t up_pixels = 0;
  vk::Buffer ap_in, ap_out, ap_list;  // apply
};

UpsampleState& upsample_state(vk::Context& dev) {
  return *dev.cached<UpsampleState>("common.upsample", [] { return std::make_shared<UpsampleState>(); });
}

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  gpu_passes::check_fits(dev, bytes, what, pass, "use a smaller frame or --backend cpu");
}

[[noreturn]] void upsample_fail(const std::string& what) { throw std::invalid_argument("upsample on vulkan: " + what); }

// The host loops over display pixels run in blocks on every core.
constexpr std::size_t kBlock = 1 << 14;

// The indices i < n where keep(i), in increasing order (as one loop would list them), into out (n
// entries at least): each block's count, then each block's indices at its offset. Returns how many.
template <class Keep>
std::size_t compact_in_blocks(std::size_t n, const Keep& keep, std::uint32_t* out) {
  const std::size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<std::size_t> offset(blocks + 1, 0);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t k) {
    std::size_t count = 0;
    for (std::size_t i = k * kBlock, e = std::min(n, i + kBlock); i < e; ++i) count += keep(i) ? 1 : 0;
    offset[k + 1] = count;
  });
  for (std::size_t k = 0; k < blocks; ++k) offset[k + 1] += offset[k];
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t k) {
    std::size_t at = offset[k];
    for (std::size_t i = k * kBlock, e = std::min(n, i + kBlock); i < e; ++i)
      if (keep(i)) out[at++] = static_cast<std::uint32_t>(i);
  });
  return offset[blocks];
}

std::string dims(const PlaneView& v) {
  return std::to_string(v.width) + "x" + std::to_string(v.height) + " (scale " + std::to_string(v.scale) + ")";
}

// upsample.cpp's size and option checks (the per-pixel depth and normal checks run in the shader).
void check_upsample_input(const PlaneView& coarse, const PlaneView& fine, const UpsampleOptions& opt) {
  if (opt.mode != UpsampleMode::Bilateral && opt.mode != UpsampleMode::Bilinear)
    upsample_fail("unknown mode value " + std::to_string(static_cast<int>(opt.mode)));
  if (!std::isfinite(opt.epsilon_rel) || !(opt.epsilon_rel > 0.0))
    upsample_fail("epsilon_rel = " + std::to_string(opt.epsilon_rel) + " must be finite and positive");
  if (opt.normal_power < 0) upsample_fail("normal_power = " + std::to_string(opt.normal_power) + " must not be negative");
  if (!std::isfinite(opt.miss_threshold) || opt.miss_threshold < 0.0)
    upsample_fail("miss_threshold = " + std::to_string(opt.miss_threshold) + " must be finite and not negative");
  for (const auto& [v, name] : {std::pair<const PlaneView&, const char*>{coarse, "coarse"}, {fine, "fine"}}) {
    if (v.width <= 0 || v.height <= 0) upsample_fail(std::string(name) + " buffer size " + dims(v) + " must be positive");
    if (v.scale < 1) upsample_fail(std::string(name) + " buffer scale " + std::to_string(v.scale) + " must be at least 1");
    if (static_cast<std::int64_t>(v.width) * v.height > std::numeric_limits<std::int32_t>::max())
      upsample_fail(std::string(name) + " buffer " + dims(v) + " has more pixels than an int32 index can address");
    if (!v.depth || !v.normal) upsample_fail(std::string(name) + " buffer depth or normal pointer is null");
  }
  if (fine.scale > coarse.scale)
    upsample_fail("fine buffer scale " + std::to_string(fine.scale) + " exceeds coarse buffer scale " + std::to_string(coarse.scale));
  const auto extent_ok = [&](int fn, int cn) {
    const std::int64_t d = static_cast<std::int64_t>(fn) * fine.scale - static_cast<std::int64_t>(cn) * coarse.scale;
    return (d < 0 ? -d : d) < coarse.scale;
  };
  if (!extent_ok(fine.width, coarse.width) || !extent_ok(fine.height, coarse.height))
    upsample_fail("fine buffer " + dims(fine) + " and coarse buffer " + dims(coarse) +
                  " do not cover the same display area (extents differ by a coarse pixel or more)");
}

}  // namespace

UpsampleWeights vulkan_upsample_weights(render::FrameContext& ctx, const PlaneView& coarse, const PlaneView& fine,
                                        const UpsampleOptions& opt, std::vector<float>* measure) {
  check_upsample_input(coarse, fine, opt);
  vk::Context& dev = vk::context_of(ctx);
  UpsampleState& g = upsample_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const std::size_t nf = static_cast<std::size_t>(fine.width) * fine.height, nc = static_cast<std::size_t>(coarse.width) * coarse.height;
  check_fits(dev, nf * 16, "the eq. 11 weights of " + std::to_string(nf) + " display pixels", "upsample");
  check_fits(dev, nf * 16, "the normals and depths of " + std::to_string(nf) + " display pixels", "upsample");
  // Each sample's normal and depth as one RGBA32F texel (upsample_weights.comp reads a sample with
  // one fetch). The same bytes cross to the device as the separate planes would (16 per sample),
  // except for display planes the Vulkan G-buffer pass left on the device in that layout
  // (vulkan::DeviceGBuffer): those are bound where they are.
  // The packing loop also checks the samples, upsample.cpp's rule and messages (the coarse buffer
  // first); a second pass lists the display pixels that see a surface: the shader's invocations.
  std::vector<std::uint32_t> surface = ctx.pool().take_for_overwrite<std::uint32_t>(nf);
  std::size_t ns = 0;
  const vk::DeviceGBuffer* planes = resident_display_planes(ctx, fine.depth, fine.normal, fine.width, fine.height);
  // In blocks on every core; the error names the first bad sample in pixel order. `resident`: the
  // device holds v's texels already, so they are checked, not packed.
  const auto up = [&](vk::Buffer& b, const PlaneView& v, std::size_t n, const char* name, const char* which, bool list, bool resident) {
    std::vector<glm::vec4> nz;
    if (!resident) nz = ctx.pool().take_for_overwrite<glm::vec4>(n);
    const std::size_t bad = first_bad_in_blocks(n, kBlock, [&](std::size_t i0, std::size_t e) {
      if (!resident)
        for (std::size_t i = i0; i < e; ++i) nz[i] = glm::vec4(v.normal[i], v.depth[i]);
      for (std::size_t i = i0; i < e; ++i)
        if (!upsample_sample_ok(v, i)) return i;
      return e;
    });
    if (list && bad == n) ns = compact_in_blocks(n, [&](std::size_t i) { return !std::isinf(v.depth[i]); }, surface.data());
    if (bad < n) {
      if (!resident) ctx.pool().give(std::move(nz));
      ctx.pool().give(std::move(surface));
      upsample_fail(upsample_sample_error(v, which, static_cast<int>(bad % static_cast<std::size_t>(v.width)),
                                          static_cast<int>(bad / static_cast<std::size_t>(v.width))));
    }
    if (resident) return;
    dev.ensure_buffer(b, n * sizeof(glm::vec4), kStorage, vk::MemoryKind::Device, name);
    dev.upload(b, nz.data(), n * sizeof(glm::vec4));
    ctx.pool().give(std::move(nz));
  };
  up(g.coarse_nz, coarse, nc, "upsample receiver normals and depth", "coarse", false, false);
  up(g.fine_nz, fine, nf, "upsample display normals and depth", "fine", true, planes != nullptr);
  dev.ensure_buffer(g.surface, std::max<std::size_t>(ns, 1) * sizeof(std::uint32_t), kStorage, vk::MemoryKind::Device,
                    "upsample surface pixels");
  if (ns) dev.upload(g.surface, surface.data(), ns * sizeof(std::uint32_t));
  ctx.pool().give(std::move(surface));
  dev.ensure_buffer(g.up_index, nf * 16, kStorage, vk::MemoryKind::Host, "upsample taps");
  dev.ensure_buffer(g.up_weight, nf * 16, kStorage, vk::MemoryKind::Host, "upsample weights");
  dev.ensure_buffer(g.up_miss, nf * 8, kStorage, vk::MemoryKind::Host, "upsample misses");
  g.up_resident = nullptr;

  const std::uint32_t mode = opt.mode == UpsampleMode::Bilateral ? gpu::kUpsampleBilateral : gpu::kUpsampleBilinear;
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "common.upsample_weights.m" + std::to_string(mode), words(spv::common_upsample_weights_comp),
                                    {{0, mode}});
  struct Push {
    std::uint32_t first, end;
    std::int32_t fw, fh, fscale, cw, ch, cscale;
    float epsilon_rel;
    std::int32_t normal_power;
    float miss_threshold;
  };
  const Push push{0,
                  0,
                  fine.width,
                  fine.height,
                  fine.scale,
                  coarse.width,
                  coarse.height,
                  coarse.scale,
                  static_cast<float>(opt.epsilon_rel),
                  opt.normal_power,
                  static_cast<float>(opt.miss_threshold)};
  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kUpBindFine, planes ? *planes->normal_depth : g.fine_nz, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kUpBindCoarse, g.coarse_nz, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kUpBindIndex, g.up_index, VK_FORMAT_R32G32B32A32_SINT),
      vk::Bind::texels_at(gpu::kUpBindWeight, g.up_weight, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kUpBindMiss, g.up_miss, VK_FORMAT_R32G32_UINT),
      vk::Bind::texels_at(gpu::kUpBindSurface, g.surface, VK_FORMAT_R32_UINT)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    // The background's outputs: no taps (index -1, weight 0), not a miss (measure 0).
    rec.fill(g.up_index, 0xFFFFFFFFu);
    rec.fill(g.up_weight, 0u);
    rec.fill(g.up_miss, 0u);
    rec.barrier();
    rec.begin_timer("upsample_weights");
    dispatch_chunks<Push>(rec, p, binds, ns, gpu::kUpWeightsGroup, [&](std::uint32_t first, std::uint32_t end) {
      Push q = push;
      q.first = first;
      q.end = end;
      return q;
    });
    rec.end_timer();
    rec.barrier();
  }, "upsample weights");
  // From the frame pool, as upsample.cpp's weights (the caller gives them back): every element is
  // overwritten, and fresh vectors would cost the frame their zero fill and page faults.
  render::FramePool& pool = ctx.pool();
  UpsampleWeights w;
  w.width = fine.width;
  w.height = fine.height;
  w.index = pool.take_for_overwrite<std::array<std::int32_t, 4>>(nf);
  w.weight = pool.take_for_overwrite<std::array<float, 4>>(nf);
  w.miss = pool.take_for_overwrite<std::uint8_t>(nf);
  dev.download(g.up_index, w.index.data(), nf * 16);
  dev.download(g.up_weight, w.weight.data(), nf * 16);
  // The miss flags and measures are read once, where they lie: through the mapping of the host
  // buffer the shader wrote (MemoryKind::Host; a copy first would cost the frame 8 bytes a pixel twice).
  const std::uint32_t* miss_words = static_cast<const std::uint32_t*>(g.up_miss.mapped());
  dev.note_transfer(0, nf * 8);
  if (measure) measure->resize(nf);
  w.misses = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, nf, kBlock), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& br, std::size_t misses) {
        for (std::size_t i = br.begin(); i != br.end(); ++i) {
          w.miss[i] = miss_words[2 * i] ? 1 : 0;
          misses += w.miss[i];
          if (measure) std::memcpy(&(*measure)[i], &miss_words[2 * i + 1], sizeof(float));
        }
        return misses;
      },
      std::plus<std::size_t>());
  g.up_resident = w.index.data();
  g.up_pixels = nf;
  ctx.record().counters["weights_gpu_seconds"] = timer_seconds(res);
  // 1: the display normals and depths were the G-buffer pass's on the device (not uploaded).
  ctx.record().counters["fine_planes_resident"] = planes ? 1.0 : 0.0;
  return w;
}

void vulkan_upsample_apply(render::FrameContext& ctx, const UpsampleWeights& w, const float* in, int channels, float* out) {
  if (!in || !out) upsample_fail("input or output pointer is null");
  if (channels < 1 || channels > 64) upsample_fail("channels = " + std::to_string(channels) + " (expected 1..64)");
  const std::size_t nf = static_cast<std::size_t>(std::max(w.width, 0)) * static_cast<std::size_t>(std::max(w.height, 0));
  if (w.width <= 0 || w.height <= 0 || w.index.size() != nf || w.weight.size() != nf)
    upsample_fail("weights of " + std::to_string(w.width) + "x" + std::to_string(w.height) + " pixels have inconsistent array sizes");
  vk::Context& dev = vk::context_of(ctx);
  UpsampleState& g = upsample_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  // The coarse buffer's size: one past the largest tap; and the pixels with a tap, the shader's
  // invocations (the others keep their value, and cost no lane).
  const std::int32_t top = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, nf, kBlock), std::int32_t{-1},
      [&](const tbb::blocked_range<std::size_t>& br, std::int32_t t) {
        for (std::size_t i = br.begin(); i != br.end(); ++i) t = std::max({t, w.index[i][0], w.index[i][1], w.index[i][2], w.index[i][3]});
        return t;
      },
      [](std::int32_t a, std::int32_t b) { return std::max(a, b); });
  std::vector<std::uint32_t> list = ctx.pool().take_for_overwrite<std::uint32_t>(nf);
  const std::size_t nl = compact_in_blocks(nf, [&](std::size_t i) { return w.index[i][0] >= 0; }, list.data());
  const std::size_t nc = static_cast<std::size_t>(top + 1), ch = static_cast<std::size_t>(channels);
  check_fits(dev, nf * ch * sizeof(float), std::to_string(channels) + " channels of " + std::to_string(nf) + " display pixels", "upsample");
  if (g.up_resident != w.index.data() || g.up_pixels != nf) {  // not the weights on the device: upload them
    dev.ensure_buffer(g.up_index, nf * 16, kStorage, vk::MemoryKind::Host, "upsample taps");
    dev.ensure_buffer(g.up_weight, nf * 16, kStorage, vk::MemoryKind::Host, "upsample weights");
    dev.upload(g.up_index, w.index.data(), nf * 16);
    dev.upload(g.up_weight, w.weight.data(), nf * 16);
    g.up_resident = w.index.data();
    g.up_pixels = nf;
  }
  dev.ensure_buffer(g.ap_in, std::max<std::size_t>(1, nc * ch) * sizeof(float), kStorage, vk::MemoryKind::Device, "upsample input");
  if (nc) dev.upload(g.ap_in, in, nc * ch * sizeof(float));
  dev.ensure_buffer(g.ap_list, std::max<std::size_t>(1, nl) * sizeof(std::uint32_t), kStorage, vk::MemoryKind::Device,
                    "upsample pixels with taps");
  if (nl) dev.upload(g.ap_list, list.data(), nl * sizeof(std::uint32_t));
  // The listed pixels' values, in list order.
  dev.ensure_buffer(g.ap_out, std::max<std::size_t>(1, nl) * ch * sizeof(float), kStorage, vk::MemoryKind::Host, "upsample output");
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "common.upsample_apply.c" + std::to_string(channels), words(spv::common_upsample_apply_comp),
                                    {{0, static_cast<std::uint32_t>(channels)}});
  struct Push {
    std::uint32_t first, end;
  };
  const std::vector<vk::Bind> binds = {vk::Bind::texels_at(gpu::kApBindIndex, g.up_index, VK_FORMAT_R32G32B32A32_SINT),
                                       vk::Bind::texels_at(gpu::kApBindWeight, g.up_weight, VK_FORMAT_R32G32B32A32_SFLOAT),
                                       vk::Bind::texels_at(gpu::kApBindIn, g.ap_in, VK_FORMAT_R32_SFLOAT),
                                       vk::Bind::texels_at(gpu::kApBindOut, g.ap_out, VK_FORMAT_R32_SFLOAT),
                                       vk::Bind::texels_at(gpu::kApBindList, g.ap_list, VK_FORMAT_R32_UINT)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("upsample_apply");
    dispatch_chunks<Push>(rec, p, binds, nl, gpu::kUpsampleGroupX * gpu::kUpsampleGroupY,
                          [&](std::uint32_t first, std::uint32_t end) { return Push{first, end}; });
    rec.end_timer();
    rec.barrier();
  }, "upsample apply");
  std::vector<float> values = ctx.pool().take_for_overwrite<float>(nl * ch);
  if (nl) dev.download(g.ap_out, values.data(), nl * ch * sizeof(float));
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nl, kBlock), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t j = br.begin(); j != br.end(); ++j)
      for (std::size_t c = 0; c < ch; ++c) out[list[j] * ch + c] = values[j * ch + c];
  });
  ctx.pool().give(std::move(values));
  ctx.pool().give(std::move(list));
  ctx.record().counters["apply_gpu_seconds"] = timer_seconds(res);
}

}  // namespace softgi::techniques::common

namespace softgi::techniques::common::gpu_passes {

ResidentTaps resident_upsample_taps(vk::Context& dev, const std::array<std::int32_t, 4>* index, std::size_t pixels) {
  UpsampleState& g = upsample_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  if (!index || g.up_resident != static_cast<const void*>(index) || g.up_pixels != pixels) return {};
  return {&g.up_index, &g.up_weight};
}

}  // namespace softgi::techniques::common::gpu_passes

namespace softgi::techniques::common {

UpsampleKernels vulkan_upsample_kernels(render::FrameContext& ctx) {
  render::FrameContext* c = &ctx;
  return {[c](const PlaneView& coarse, const PlaneView& fine, const UpsampleOptions& opt) { return vulkan_upsample_weights(*c, coarse, fine, opt); },
          [c](const UpsampleWeights& w, const float* in, int channels, float* out) { vulkan_upsample_apply(*c, w, in, channels, out); }};
}

}  // namespace softgi::techniques::common
