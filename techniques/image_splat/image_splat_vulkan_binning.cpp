// image_splat's binning as a compute pass (paper 000 section 4.1; shaders/image_splat/bin_proxies.comp).
#include "image_splat_vulkan_binning.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common/accumulation_vulkan.hpp"
#include "image_splat_binning_shared.h"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/sh/sh.hpp"

namespace spv {
#include "softgi/shaders/image_splat/bin_proxies_comp.h"
}  // namespace spv

namespace softgi::techniques::image_splat {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

namespace {

// The device's binning state: the pipeline, the inputs (uploaded when they change) and the lists,
// grown as frames need more and reused from frame to frame.
struct BinState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer tiles;
  std::uint64_t tiles_hash = 0;
  struct Kind {
    vk::Buffer test, src_a, src_b, count, ranges, spheres, payload, index;
    std::uint64_t test_hash = 0, a_hash = 0, b_hash = 0;
  };
  Kind shadow, indirect;
};

std::shared_ptr<BinState> bin_state(vk::Context& dev) {
  return dev.cached<BinState>("image_splat.binning", [] { return std::make_shared<BinState>(); });
}

struct Push {
  std::uint32_t mode, tile_first, tile_end, first, end, payload;
};

// Proxies one dispatch may walk under the device's loop budget: per proxy the step itself and the
// payload loop, doubled (llvmpipe's counter was measured at 1.5x the loop count: accumulate_log_chunk).
std::uint32_t proxy_chunk(const vk::DeviceInfo& d) {
  const std::uint32_t budget = loop_budget(d);
  if (budget == std::numeric_limits<std::uint32_t>::max()) return budget;
  return std::max<std::uint32_t>(1u, budget / (2u * (1u + gpu::kBinMaxPayload)));
}

// Every (tile chunk, proxy chunk) dispatch of one mode; proxy chunks after the first carry count[]
// on (a barrier between them).
void record_kind(vk::Recorder& rec, const vk::ComputePipeline& p, const std::vector<vk::Bind>& binds, std::uint32_t mode,
                 std::size_t tiles, const DeviceProxies& in, std::uint32_t chunk) {
  const std::size_t max_tiles = static_cast<std::size_t>(rec.context().device_info().limits.maxComputeWorkGroupCount[0]) * gpu::kBinGroup;
  const std::size_t n = in.proxies;
  for (std::size_t first = 0; first < std::max<std::size_t>(n, 1); first += chunk) {
    const std::size_t end = std::min(n, first + chunk);
    if (first > 0) rec.barrier();
    for (std::size_t t0 = 0; t0 < tiles; t0 += max_tiles) {
      const std::size_t t1 = std::min(tiles, t0 + max_tiles);
      rec.dispatch(p, binds,
                   Push{mode, static_cast<std::uint32_t>(t0), static_cast<std::uint32_t>(t1), static_cast<std::uint32_t>(first),
                        static_cast<std::uint32_t>(end), in.payload},
                   static_cast<std::uint32_t>((t1 - t0 + gpu::kBinGroup - 1) / gpu::kBinGroup));
    }
  }
}

std::vector<vk::Bind> binds_of(const vk::Buffer& tiles, const BinState::Kind& k) {
  return {vk::Bind::texels_at(gpu::kBinBindTiles, tiles, VK_FORMAT_R32G32B32A32_SFLOAT),
          vk::Bind::texels_at(gpu::kBinBindTest, k.test, VK_FORMAT_R32G32B32A32_SFLOAT),
          vk::Bind::texels_at(gpu::kBinBindSrcA, k.src_a, VK_FORMAT_R32G32B32A32_SFLOAT),
          vk::Bind::texels_at(gpu::kBinBindSrcB, k.src_b, VK_FORMAT_R32G32B32A32_SFLOAT),
          vk::Bind::buffer_at(gpu::kBinBindCount, k.count),
          vk::Bind::texels_at(gpu::kBinBindRanges, k.ranges, VK_FORMAT_R32G32_UINT),
          vk::Bind::buffer_at(gpu::kBinBindDstA, k.spheres),
          vk::Bind::buffer_at(gpu::kBinBindDstB, k.payload),
          vk::Bind::buffer_at(gpu::kBinBindIndex, k.index)};
}

void ensure(vk::Context& dev, vk::Buffer& b, std::size_t bytes, vk::MemoryKind kind, const std::string& name) {
  dev.ensure_buffer(b, std::max<std::size_t>(16, bytes), kStorage, kind, name);
}

}  // namespace

DeviceProxies device_indirect_proxies(const ProxyList& all, double alpha) {
  DeviceProxies in;
  const std::size_t n = all.size();
  in.proxies = n;
  in.payload = 1;
  in.test.resize(4 * n);
  in.a.resize(4 * n);
  in.b.assign(4 * n, 0.0f);
  // Albedo / pi folded as vulkan_accumulate_indirect folds it for host-binned lists.
  const float inv_pi = static_cast<float>(1.0 / sh::kPi);
  for (std::size_t p = 0; p < n; ++p) {
    const float c[4] = {all.cx[p], all.cy[p], all.cz[p], all.r[p]};
    std::copy(c, c + 4, in.a.begin() + 4 * p);
    std::copy(c, c + 3, in.test.begin() + 4 * p);
    in.test[4 * p + 3] = influence_radius(all.r[p], alpha);
    for (int k = 0; k < 3; ++k) in.b[4 * p + k] = all.albedo[p][k] * inv_pi;
  }
  return in;
}

DeviceProxies device_shadow_proxies(const common::BlockerList& all, double alpha) {
  DeviceProxies in;
  const std::size_t n = all.size(), order = static_cast<std::size_t>(all.order), ws = weight_stride(all.order);
  in.proxies = n;
  in.payload = static_cast<std::uint32_t>(ws / 4);
  in.test.resize(4 * n);
  in.a.resize(4 * n);
  // pack_blocker_lists' layout: the band weights, the row's padding holding 1 (its w_fill for image_splat).
  in.b.assign(n * ws, 1.0f);
  for (std::size_t p = 0; p < n; ++p) {
    const float c[4] = {all.cx[p], all.cy[p], all.cz[p], all.r[p]};
    std::copy(c, c + 4, in.a.begin() + 4 * p);
    std::copy(c, c + 3, in.test.begin() + 4 * p);
    in.test[4 * p + 3] = influence_radius(all.r[p], alpha);
    std::copy(all.w.begin() + p * order, all.w.begin() + (p + 1) * order, in.b.begin() + p * ws);
  }
  return in;
}

BinCounts vulkan_bin_proxies(render::FrameContext& ctx, const ReceiverBuffer& r, std::shared_ptr<const common::BlockerList> all_shadow,
                                 double alpha_shadow, std::shared_ptr<const ProxyList> all_indirect, double alpha_indirect,
                                 const std::string& out) {
  vk::Context& dev = vk::context_of(ctx);
  std::shared_ptr<BinState> state = bin_state(dev);
  BinState& st = *state;
  std::lock_guard<std::mutex> lock(st.m);
  const std::string pass = "image_splat bin_proxies";
  const std::string advice = "use fewer proxy spheres, a larger receiver_scale, a larger tile_size, or --backend cpu";
  const std::size_t nt = r.tiles.size();
  if (nt > std::numeric_limits<std::uint32_t>::max() / 2 || all_shadow->size() > std::numeric_limits<std::uint32_t>::max() / 8 ||
      (all_indirect && all_indirect->size() > std::numeric_limits<std::uint32_t>::max() / 8))
    throw std::invalid_argument(pass + " on vulkan: " + std::to_string(nt) + " tiles and " + std::to_string(all_shadow->size()) +
                                " proxies exceed the 32-bit indexing");
  const bool ind = all_indirect != nullptr;
  std::vector<DeviceProxies> in;
  in.push_back(device_shadow_proxies(*all_shadow, alpha_shadow));
  if (ind) in.push_back(device_indirect_proxies(*all_indirect, alpha_indirect));
  BinState::Kind* kinds[2] = {&st.shadow, &st.indirect};
  const char* names[2] = {"shadow", "indirect"};

  const std::size_t up0 = dev.transfer_bytes().upload, down0 = dev.transfer_bytes().download;
  std::vector<float> boxes(8 * nt, 0.0f);
  for (std::size_t k = 0; k < nt; ++k) {
    const ReceiverTile& t = r.tiles[k];
    const float b[8] = {t.lo.x, t.lo.y, t.lo.z, 0.0f, t.hi.x, t.hi.y, t.hi.z, 0.0f};
    std::copy(b, b + 8, boxes.begin() + 8 * k);
  }
  check_fits(dev, boxes.size() * sizeof(float), "the boxes of " + std::to_string(nt) + " receiver tiles", pass, advice);
  put_if_changed(dev, st.tiles, st.tiles_hash, boxes, "image_splat binning tile boxes");
  for (std::size_t q = 0; q < in.size(); ++q) {
    BinState::Kind& k = *kinds[q];
    const std::string nm = std::string("image_splat binning ") + names[q];
    check_fits(dev, in[q].b.size() * sizeof(float), "the payload of " + std::to_string(in[q].proxies) + " proxies", pass, advice);
    put_if_changed(dev, k.test, k.test_hash, in[q].test, nm + " spheres of influence");
    put_if_changed(dev, k.src_a, k.a_hash, in[q].a, nm + " proxies");
    put_if_changed(dev, k.src_b, k.b_hash, in[q].b, nm + " proxy payload");
    ensure(dev, k.count, nt * 4, vk::MemoryKind::Host, nm + " counts");
    // Bound in both modes: at least allocated before the count.
    ensure(dev, k.ranges, nt * 8, vk::MemoryKind::Device, nm + " list ranges");
    ensure(dev, k.spheres, 0, vk::MemoryKind::Device, nm + " lists");
    ensure(dev, k.payload, 0, vk::MemoryKind::Device, nm + " list payload");
    ensure(dev, k.index, 0, vk::MemoryKind::Device, nm + " list indices");
  }
  vk::ComputePipeline& pipe = pipeline(dev, st.pipelines, "image_splat.bin_proxies", words(spv::image_splat_bin_proxies_comp), {});
  const std::uint32_t chunk = proxy_chunk(dev.device_info());

  BinCounts res;
  res.gpu_seconds = 0.0;
  // One submission of every dispatch of `mode`, each list kind's count[] zeroed first.
  auto run_mode = [&](std::uint32_t mode, const char* label) {
    const vk::SubmitResult done = dev.submit([&](vk::Recorder& rec) {
      for (std::size_t q = 0; q < in.size(); ++q) rec.fill(kinds[q]->count, 0u);
      rec.barrier();
      rec.begin_timer(label);
      for (std::size_t q = 0; q < in.size(); ++q) record_kind(rec, pipe, binds_of(st.tiles, *kinds[q]), mode, nt, in[q], chunk);
      rec.end_timer();
      rec.barrier();
    }, pass + " " + label);
    res.gpu_seconds += std::max(0.0, timer_seconds(done));
  };
  if (nt > 0) run_mode(gpu::kBinCount, "bin_count");

  // The lists laid out from the counts: each tile's list starts where the previous one ends.
  auto bins = std::make_shared<DeviceBins>();
  bins->has_indirect = ind;
  bins->order = all_shadow->order;
  bins->indirect_proxies = all_indirect;
  DeviceBinList* lists[2] = {&bins->shadow, &bins->indirect};
  for (std::size_t q = 0; q < in.size(); ++q) {
    BinState::Kind& k = *kinds[q];
    DeviceBinList& l = *lists[q];
    l.counts.assign(nt, 0);
    if (nt) dev.download(k.count, l.counts.data(), nt * 4);
    std::vector<std::uint32_t> ranges(2 * nt);
    std::size_t at = 0;
    for (std::size_t t = 0; t < nt; ++t) {
      if (l.counts[t] > in[q].proxies)
        throw std::logic_error(pass + " on vulkan: " + std::to_string(l.counts[t]) + " " + names[q] + " proxies counted for tile " +
                               std::to_string(t) + " of " + std::to_string(in[q].proxies));
      ranges[2 * t] = static_cast<std::uint32_t>(at);
      ranges[2 * t + 1] = l.counts[t];
      at += l.counts[t];
      l.longest = std::max(l.longest, l.counts[t]);
    }
    l.total = at;
    const std::string what = std::to_string(at) + " tile-proxy pairs (" + names[q] + ")";
    check_fits(dev, at * 16, what, pass, advice);
    check_fits(dev, at * 16 * in[q].payload, "the payload of " + what, pass, advice);
    if (at > std::numeric_limits<std::uint32_t>::max() / 8)
      throw std::invalid_argument(pass + " on vulkan: " + what + " exceed the 32-bit indexing (" + advice + ")");
    const std::string nm = std::string("image_splat binning ") + names[q];
    ensure(dev, k.spheres, at * 16, vk::MemoryKind::Device, nm + " lists");
    ensure(dev, k.payload, at * 16 * in[q].payload, vk::MemoryKind::Device, nm + " list payload");
    ensure(dev, k.index, at * 4, vk::MemoryKind::Device, nm + " list indices");
    if (nt) dev.upload(k.ranges, ranges.data(), ranges.size() * 4);
    l.ranges = &k.ranges;
    l.spheres = &k.spheres;
    l.payload = &k.payload;
    l.index = &k.index;
    res.bytes += at * (16 * (1 + in[q].payload) + 4) + ranges.size() * 4;
  }
  if (nt > 0) {
    run_mode(gpu::kBinScatter, "bin_scatter");
    // Each tile's scatter wrote as many entries as its count found: a driver that ended a loop early
    // (or any other disagreement of the two modes) would leave lists with stale entries.
    for (std::size_t q = 0; q < in.size(); ++q) {
      std::vector<std::uint32_t> written(nt);
      dev.download(kinds[q]->count, written.data(), nt * 4);
      for (std::size_t t = 0; t < nt; ++t)
        if (written[t] != lists[q]->counts[t])
          throw std::logic_error(pass + " on vulkan: tile " + std::to_string(t) + " counted " + std::to_string(lists[q]->counts[t]) + " " +
                                 names[q] + " proxies but wrote " + std::to_string(written[t]));
    }
  }
  res.shadow_counts = bins->shadow.counts;
  if (ind) res.indirect_counts = bins->indirect.counts;
  res.pairs_tested = static_cast<double>(nt) * static_cast<double>(all_shadow->size() + (ind ? all_indirect->size() : 0));
  res.upload_bytes = dev.transfer_bytes().upload - up0;
  res.download_bytes = dev.transfer_bytes().download - down0;

  // The host copy, read back only for a host pass: the flat lists' proxies at the entry indices.
  const double pairs_tested = res.pairs_tested;
  const int order = all_shadow->order;
  ctx.put_deferred<std::shared_ptr<const ProxyBins>>(out, [state, bins, all_shadow, all_indirect, pairs_tested, order, &dev]() {
    std::lock_guard<std::mutex> l(state->m);
    auto b = std::make_shared<ProxyBins>();
    const std::size_t tiles = bins->shadow.counts.size();
    b->pairs_tested = pairs_tested;
    b->shadow.assign(tiles, common::BlockerList{order, {}, {}, {}, {}, {}});
    std::vector<std::uint32_t> idx(bins->shadow.total);
    if (!idx.empty()) dev.download(*bins->shadow.index, idx.data(), idx.size() * 4);
    std::size_t at = 0;
    const common::BlockerList& s = *all_shadow;
    for (std::size_t t = 0; t < tiles; ++t)
      for (std::uint32_t j = 0; j < bins->shadow.counts[t]; ++j, ++at) {
        const std::uint32_t p = idx[at];
        b->shadow[t].push(glm::vec3(s.cx[p], s.cy[p], s.cz[p]), s.r[p], &s.w[static_cast<std::size_t>(p) * order]);
      }
    b->shadow_tile_pairs = static_cast<double>(bins->shadow.total);
    if (bins->has_indirect) {
      b->indirect.assign(tiles, ProxyList{});
      idx.assign(bins->indirect.total, 0);
      if (!idx.empty()) dev.download(*bins->indirect.index, idx.data(), idx.size() * 4);
      at = 0;
      const ProxyList& a = *all_indirect;
      for (std::size_t t = 0; t < tiles; ++t)
        for (std::uint32_t j = 0; j < bins->indirect.counts[t]; ++j, ++at) {
          const std::uint32_t p = idx[at];
          b->indirect[t].push(glm::vec3(a.cx[p], a.cy[p], a.cz[p]), a.r[p], a.albedo[p]);
        }
      b->indirect_tile_pairs = static_cast<double>(bins->indirect.total);
    }
    return std::shared_ptr<const ProxyBins>(b);
  });
  ctx.put_device<std::shared_ptr<const DeviceBins>>(out, bins);
  return res;
}

}  // namespace softgi::techniques::image_splat
