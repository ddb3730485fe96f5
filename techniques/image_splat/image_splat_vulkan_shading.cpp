// image_splat's indirect accumulation on the Vulkan backend (paper 000 section 5, eqs. 13, 15 and
// 16-17): host dispatch of shaders/image_splat/accumulate_indirect.comp over the per-tile proxy lists.
#include "image_splat_vulkan_shading.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common/accumulation_vulkan.hpp"
#include "image_splat_indirect_shared.h"
#include "image_splat_vulkan_binning.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/image_splat/accumulate_indirect_comp.h"
}  // namespace spv

namespace softgi::techniques::image_splat {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

namespace {

// Per-device state of the indirect passes: pipelines by specialisation, the evaluator's tables
// (uploaded when their floats change: the evaluator is rebuilt when the light or the settings do)
// and per-frame buffers reused from frame to frame.
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  IndirectTableBuffers tables;
  vk::Buffer receivers, rlist, ranges, proxies, albedo, out, pairs;
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("image_splat.indirect.gpu", [] { return std::make_shared<GpuState>(); });
}

// Tables are compared float by float (upload_if_changed) rather than keyed on the evaluator's
// address: a rebuilt evaluator may reuse the address, and an unchanged light keeps its tables.

// The shader walks the exact operator's M and Q blocks in the evaluator's order and derives their
// offsets as running sums (constant after the order specialisation); refuse tables laid out
// otherwise rather than read the wrong floats.
void check_exact_layout(const IndirectEvaluator::TableView& tv) {
  const int n = tv.order;
  const auto bad = [](const std::string& what) {
    throw std::logic_error("image_splat accumulate_indirect on vulkan: the exact operator's " + what + " is not the shader's layout");
  };
  if (tv.moff.size() != static_cast<std::size_t>(2 * n - 1) || tv.qoff.size() != static_cast<std::size_t>(n) ||
      tv.hc.size() != static_cast<std::size_t>(n))
    bad("offset or hc count");
  int off = 0;
  for (int m = -(n - 1); m <= n - 1; ++m) {
    if (tv.moff[static_cast<std::size_t>(m + n - 1)] != off) bad("M block offset of m = " + std::to_string(m));
    off += (n - std::abs(m)) * (n - std::abs(m));
  }
  if (tv.mrow != off || tv.mtab.size() != static_cast<std::size_t>(tv.rows) * static_cast<std::size_t>(off)) bad("M row size");
  int qo = 0;
  for (int l = 0; l < n; ++l) {
    if (tv.qoff[static_cast<std::size_t>(l)] != qo) bad("Q block offset of band " + std::to_string(l));
    qo += (2 * l + 1) * (2 * l + 1);
  }
  if (tv.qrot.size() != static_cast<std::size_t>(qo)) bad("Q block size");
}

}  // namespace

bool vulkan_indirect_supported(IndirectOperator op) {
  return op == IndirectOperator::PointSampled || op == IndirectOperator::AveragedPolynomial || op == IndirectOperator::AveragedExact ||
         op == IndirectOperator::Exact;
}

namespace {

// Proxies one invocation of accumulate_indirect.comp may sum under the device's loop budget: the
// budget over a bound of one proxy's loop iterations, every loop of its body counted as if the driver
// unrolled none (llvmpipe counts them all, docs/backends.md), doubled as for accumulate_log.
std::uint32_t indirect_chunk(const vk::DeviceInfo& d, int order, bool exact) {
  const std::uint32_t budget = common::gpu_passes::loop_budget(d);
  if (budget == std::numeric_limits<std::uint32_t>::max()) return budget;
  const std::uint32_t n = static_cast<std::uint32_t>(order);
  // The proxy loop; F, the Legendre recurrence, fac, kap (n each); the basis (cos/sin recurrence,
  // outer and inner loops: 2n + n (n + 1) / 2); B (n bands, n^2 terms).
  std::uint32_t per = 1u + 4u * n + 2u * n + n * (n + 1u) / 2u + n + n * n;
  if (exact) {
    // exact_pair: the multiples (2 n), hp (n + n^2), per band the copy, two z rotations and two
    // dense w x w products (w = 2l + 1), the m-block offsets (2n - 1) and blocks (1 + w + w^2 each).
    per += 2u * n + n + n * n + 2u * n - 1u;
    for (std::uint32_t l = 0; l < n; ++l) {
      const std::uint32_t w = 2u * l + 1u;
      per += 1u + w + 2u * l + 2u * (w + w * w);
    }
    for (std::uint32_t am = 0; am < n; ++am) {
      const std::uint32_t w = n - am, blocks = am == 0 ? 1u : 2u;
      per += blocks * (1u + w + w * w);
    }
  }
  return std::max<std::uint32_t>(1u, budget / (2u * per));
}

}  // namespace

namespace {

// The operator and the tables' layout.
void check_indirect_setup(const IndirectEvaluator& ev) {
  const IndirectSetup& setup = ev.setup();
  if (!vulkan_indirect_supported(setup.op))
    throw std::logic_error("image_splat accumulate_indirect on vulkan: unknown indirect operator " +
                           std::to_string(static_cast<int>(setup.op)));
  const IndirectEvaluator::TableView tv = ev.tables();
  const int n = tv.order;
  if (n < 1 || n > static_cast<int>(gpu::kAccumMaxOrder) || tv.rows < 2)
    throw std::logic_error("image_splat accumulate_indirect on vulkan: tables of order " + std::to_string(n) + " with " +
                           std::to_string(tv.rows) + " rows");
  if (setup.op == IndirectOperator::Exact) check_exact_layout(tv);
}

// The operator, the tables' layout and the receiver count, checked before anything is uploaded.
void check_indirect_inputs(const ReceiverBuffer& r, std::size_t lists, const IndirectEvaluator& ev) {
  check_indirect_setup(ev);
  const std::size_t count = r.soa.size();
  if (count > std::numeric_limits<std::uint32_t>::max() / 8)
    throw std::invalid_argument("image_splat accumulate_indirect on vulkan: " + std::to_string(count) + " receivers exceed the 32-bit indexing");
  if (lists != r.tiles.size())
    throw std::logic_error("image_splat accumulate_indirect on vulkan: " + std::to_string(lists) + " proxy lists for " +
                           std::to_string(r.tiles.size()) + " tiles");
}

}  // namespace

std::uint32_t upload_indirect_tables(vk::Context& dev, IndirectTableBuffers& b, const IndirectEvaluator& ev) {
  check_indirect_setup(ev);
  const IndirectEvaluator::TableView tv = ev.tables();
  upload_if_changed(dev, b.vis, b.vis_host, tv.vis, "image_splat indirect visibility ZH table");
  upload_if_changed(dev, b.dfac, b.dfac_host, tv.dfac, "image_splat indirect D table");
  upload_if_changed(dev, b.mtab, b.mtab_host, tv.mtab, "image_splat indirect M blocks (eq. 16)");
  upload_if_changed(dev, b.qrot, b.qrot_host, tv.qrot, "image_splat indirect Q = Rx(-90 deg) band blocks");
  std::vector<float> consts(tv.ltilde.begin(), tv.ltilde.end());
  consts.insert(consts.end(), tv.vh.begin(), tv.vh.end());
  consts.insert(consts.end(), tv.hc.begin(), tv.hc.end());
  if (consts.size() > gpu::kIndConstFloats)
    throw std::logic_error("image_splat indirect on vulkan: " + std::to_string(consts.size()) + " constant floats (L~, vh, hc) exceed the " +
                           std::to_string(gpu::kIndConstFloats) + " of the shaders' uniform block");
  consts.resize(gpu::kIndConstFloats, 0.0f);  // the whole block (std140 vec4s), read as a uniform buffer
  upload_if_changed(dev, b.consts, b.consts_host, consts, "image_splat indirect L~ and band factors", kStorage | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
  const IndirectSetup& setup = ev.setup();
  return setup.op == IndirectOperator::Exact          ? gpu::kIndOpExact
         : setup.op == IndirectOperator::PointSampled ? gpu::kIndOpPoint
                                                      : gpu::kIndOpAveraged;
}

namespace {

// accumulate_indirect over `lists` (bound under g.m, which the caller holds).
std::shared_ptr<IndirectSums> accumulate_indirect_bound(render::FrameContext& ctx, vk::Context& dev, GpuState& g, const ReceiverBuffer& r,
                                                        const IndirectEvaluator& ev, const DeviceBinList& lists, std::size_t uploaded) {
  const IndirectSetup& setup = ev.setup();
  const IndirectEvaluator::TableView tv = ev.tables();
  const int n = tv.order;
  const bool exact = setup.op == IndirectOperator::Exact;
  const std::size_t count = r.soa.size();
  const std::string pass = "image_splat accumulate_indirect";
  const std::string advice = "use fewer proxy spheres, a larger receiver_scale, or --backend cpu";
  common::gpu_passes::check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", pass, advice);
  common::gpu_passes::check_fits(dev, count * 4 * sizeof(float), "the indirect sums of " + std::to_string(count) + " receivers", pass, advice);
  std::vector<std::uint32_t> rlist(count, 0);
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    for (std::size_t i = r.tiles[k].begin; i < r.tiles[k].end; ++i) rlist[i] = static_cast<std::uint32_t>(k);
  const std::size_t before = dev.transfer_bytes().upload;
  const std::uint32_t op = upload_indirect_tables(dev, g.tables, ev);
  upload_receivers(dev, g.receivers, r.soa, "image_splat indirect receivers");
  put(dev, g.rlist, rlist, "image_splat indirect receiver tiles");
  dev.ensure_buffer(g.out, std::max<std::size_t>(1, count) * 4 * sizeof(float), kStorage, vk::MemoryKind::Host, "image_splat indirect sums");
  const std::uint32_t zero = 0;
  dev.ensure_buffer(g.pairs, sizeof zero, kStorage, vk::MemoryKind::Host, "image_splat indirect pair count");
  dev.upload(g.pairs, &zero, sizeof zero);

  vk::ComputePipeline& p = pipeline(dev, g.pipelines,
                                    "image_splat.accumulate_indirect.n" + std::to_string(n) + ".rule" + std::to_string(static_cast<int>(setup.rule)) +
                                        ".op" + std::to_string(op),
                                    words(spv::image_splat_accumulate_indirect_comp),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(setup.rule)}, {2, op}});
  struct Push {
    std::uint32_t count, first, end, rows;
    float scale, eta;
    std::uint32_t chunk_first, chunk_count, chunk_add;
    float reach;
  };
  const float eta = setup.eta > 0.0 ? static_cast<float>(setup.eta) : 0.0f;
  const std::uint32_t longest = lists.longest;
  const std::uint32_t chunk = indirect_chunk(dev.device_info(), n, exact);
  const std::uint32_t n_chunks = longest <= chunk ? 1u : (longest + chunk - 1u) / chunk;
  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kIndBindReceivers, g.receivers, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kIndBindReceiverList, g.rlist, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kIndBindListRange, *lists.ranges, VK_FORMAT_R32G32_UINT),
      vk::Bind::texels_at(gpu::kIndBindProxies, *lists.spheres, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kIndBindAlbedo, *lists.payload, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kIndBindVis, g.tables.vis, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kIndBindDfac, g.tables.dfac, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kIndBindConsts, g.tables.consts),
      vk::Bind::buffer_at(gpu::kIndBindBasis, basis_constants(dev)),
      vk::Bind::buffer_at(gpu::kIndBindOut, g.out),
      vk::Bind::buffer_at(gpu::kIndBindPairs, g.pairs),
      vk::Bind::texels_at(gpu::kIndBindMtab, g.tables.mtab, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kIndBindQrot, g.tables.qrot, VK_FORMAT_R32_SFLOAT)};
  vk::SubmitResult res;
  if (count)
    res = dev.submit([&](vk::Recorder& rec) {
      rec.begin_timer("accumulate_indirect");
      for (std::uint32_t c = 0; c < n_chunks; ++c) {
        const std::uint32_t in_chunk = n_chunks == 1 ? std::numeric_limits<std::uint32_t>::max() : chunk;
        dispatch_chunks<Push>(rec, p, binds, count, gpu::kIndGroup, [&](std::uint32_t first, std::uint32_t end) {
          return Push{static_cast<std::uint32_t>(count), first, end, static_cast<std::uint32_t>(tv.rows), tv.scale, eta, c * chunk, in_chunk,
                      c > 0 ? 1u : 0u,
                      static_cast<float>(setup.reach)};
        });
        if (c + 1 < n_chunks) rec.barrier();  // the next chunk reads these sums back
      }
      rec.end_timer();
      rec.barrier();
    }, "image_splat accumulate_indirect");

  auto sums = std::make_shared<IndirectSums>();
  sums->rgb.assign(count * 3, 0.0f);
  sums->omega.assign(count, 0.0f);
  std::uint32_t inside = 0;
  if (count) {
    std::vector<float> o(count * 4);
    dev.download(g.out, o.data(), o.size() * sizeof(float));
    dev.download(g.pairs, &inside, sizeof inside);
    for (std::size_t i = 0; i < count; ++i) {
      for (int c = 0; c < 3; ++c) sums->rgb[3 * i + c] = o[4 * i + c];
      sums->omega[i] = o[4 * i + 3];
    }
  }
  double pairs = 0.0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    pairs += static_cast<double>(r.tiles[k].end - r.tiles[k].begin) * static_cast<double>(lists.counts[k]);
  sums->pairs = pairs;
  const double secs = timer_seconds(res);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["pairs"] = pairs;
  rec.counters["pairs_inside_influence"] = static_cast<double>(inside);
  rec.counters["proxy_chunks"] = n_chunks;
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["kernel_gpu_seconds"] = secs;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded + dev.transfer_bytes().upload - before);
  rec.bytes = (sums->rgb.size() + sums->omega.size()) * sizeof(float);
  return sums;
}

}  // namespace

std::shared_ptr<IndirectSums> vulkan_accumulate_indirect(render::FrameContext& ctx, const ReceiverBuffer& r, const ProxyBins& bins,
                                                         const IndirectEvaluator& ev) {
  check_indirect_inputs(r, bins.indirect.size(), ev);
  // The CPU evaluator's own input checks (proxy centres, radii, albedo; same messages): an empty
  // receiver range checks the list and evaluates nothing.
  for (const ProxyList& l : bins.indirect) ev.accumulate(r.soa, 0, 0, l, nullptr, nullptr);
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  DeviceBinList lists = host_lists(bins.indirect);
  common::gpu_passes::check_fits(dev, lists.total * 4 * sizeof(float), std::to_string(lists.total) + " tile-proxy pairs (binned spheres)",
                                 "image_splat accumulate_indirect", "use fewer proxy spheres, a larger receiver_scale, or --backend cpu");
  // The tiles' proxy lists concatenated; each receiver reads the list of its tile. Albedo / pi is
  // folded on the host in the CPU's order (a * inv_pi, then times the pair's value).
  const float inv_pi = static_cast<float>(1.0 / sh::kPi);
  std::vector<float> sph(lists.total * 4), alb(lists.total * 4, 0.0f);
  std::vector<std::uint32_t> ranges(2 * r.tiles.size(), 0);
  std::size_t at = 0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k) {
    const ProxyList& b = bins.indirect[k];
    ranges[2 * k] = static_cast<std::uint32_t>(at);
    ranges[2 * k + 1] = static_cast<std::uint32_t>(b.size());
    for (std::size_t j = 0; j < b.size(); ++j, ++at) {
      sph[4 * at] = b.cx[j];
      sph[4 * at + 1] = b.cy[j];
      sph[4 * at + 2] = b.cz[j];
      sph[4 * at + 3] = b.r[j];
      alb[4 * at] = b.albedo[j].x * inv_pi;
      alb[4 * at + 1] = b.albedo[j].y * inv_pi;
      alb[4 * at + 2] = b.albedo[j].z * inv_pi;
    }
  }
  const std::size_t before = dev.transfer_bytes().upload;
  put(dev, g.ranges, ranges, "image_splat indirect tile list ranges");
  put(dev, g.proxies, sph, "image_splat indirect binned proxies");
  put(dev, g.albedo, alb, "image_splat indirect proxy albedo");
  lists.ranges = &g.ranges;
  lists.spheres = &g.proxies;
  lists.payload = &g.albedo;
  return accumulate_indirect_bound(ctx, dev, g, r, ev, lists, dev.transfer_bytes().upload - before);
}

std::shared_ptr<IndirectSums> vulkan_accumulate_indirect(render::FrameContext& ctx, const ReceiverBuffer& r, const DeviceBins& bins,
                                                         const IndirectEvaluator& ev) {
  if (!bins.has_indirect || !bins.indirect_proxies)
    throw std::logic_error("image_splat accumulate_indirect on vulkan: the device bins hold no indirect lists");
  check_indirect_inputs(r, bins.indirect.counts.size(), ev);
  // The evaluator's input checks on every proxy the lists were binned from (a superset of the
  // binned ones: the same messages).
  ev.accumulate(r.soa, 0, 0, *bins.indirect_proxies, nullptr, nullptr);
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  return accumulate_indirect_bound(ctx, dev, g, r, ev, bins.indirect, 0);
}

}  // namespace softgi::techniques::image_splat
