// image_splat's binning on the Vulkan backend (shaders/image_splat/bin_proxies.comp): the per-tile
// proxy lists of bin_proxies (paper 000 section 4.1) built by a compute pass and left on the device
// in the layouts accumulate_log.comp and accumulate_indirect.comp read, so that the host neither
// bins nor packs nor uploads them. Includes the Vulkan headers: include only from *_vulkan*.cpp.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "image_splat_internal.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/frame.hpp"

namespace softgi::techniques::image_splat {

// A flat proxy list as the device passes read it, per proxy: its sphere of influence (centre,
// influence_radius) in `test`, its sphere (centre, radius) in `a`, and `payload` vec4s in `b` (the
// band weights in rows of weight_stride(order) floats, the padding 1, for shadows; albedo / pi for
// indirect light).
struct DeviceProxies {
  std::vector<float> test, a, b;
  std::uint32_t payload = 1;  // vec4s of b per proxy
  std::size_t proxies = 0;
};
DeviceProxies device_shadow_proxies(const common::BlockerList& all, double alpha);
DeviceProxies device_indirect_proxies(const ProxyList& all, double alpha);

// One kind of per-tile list on the device: ranges (uvec2 per tile: first entry, count), spheres
// (vec4 per entry: centre, radius), payload (`payload` vec4s per entry: the band weights in rows of
// weight_stride(order) floats for shadows, albedo / pi for indirect light) and index (the entry's
// proxy in the flat list). vulkan_bin_proxies' buffers belong to the device's binning state and hold
// this frame's lists until the next frame bins again; accumulate_log and accumulate_indirect also
// describe the lists they packed from host bins this way (index null).
struct DeviceBinList {
  const backends::vulkan::Buffer* ranges = nullptr;
  const backends::vulkan::Buffer* spheres = nullptr;
  const backends::vulkan::Buffer* payload = nullptr;
  const backends::vulkan::Buffer* index = nullptr;
  std::vector<std::uint32_t> counts;  // entries per tile (read back: the host lays the lists out)
  std::uint32_t longest = 0;
  std::size_t total = 0;
};
// The entries per tile, their total and the longest list of host-binned lists (BlockerLists or
// ProxyLists), as a DeviceBinList whose buffers the caller fills in once it has packed them.
template <class List>
DeviceBinList host_lists(const std::vector<List>& lists) {
  DeviceBinList d;
  for (const List& l : lists) {
    d.counts.push_back(static_cast<std::uint32_t>(l.size()));
    d.total += l.size();
    d.longest = std::max(d.longest, static_cast<std::uint32_t>(l.size()));
  }
  return d;
}

// The device copy of image_splat's bins resource: shadow lists always, indirect lists when
// indirect light is on (then `has_indirect`).
struct DeviceBins {
  DeviceBinList shadow, indirect;
  int order = 0;  // band weights per shadow entry (rows of weight_stride(order) floats)
  bool has_indirect = false;
  // The flat list the indirect lists were binned from (the evaluator's input checks read it).
  std::shared_ptr<const ProxyList> indirect_proxies;
};

// bin_proxies on the GPU: count per tile, lay the lists out on the host from the counts (one uint
// per tile read back), write them in proxy order (an in-order compaction per tile). Puts the device
// copy of `out` and, deferred, its host copy (a ProxyBins rebuilt from the flat lists and the entry
// indices read back), identical to bin_proxies' lists. Returns the per-tile counts and the GPU time
// of both dispatches.
BinCounts vulkan_bin_proxies(render::FrameContext& ctx, const ReceiverBuffer& r, std::shared_ptr<const common::BlockerList> all_shadow,
                                 double alpha_shadow, std::shared_ptr<const ProxyList> all_indirect, double alpha_indirect,
                                 const std::string& out);

// accumulate_log and accumulate_indirect over device-binned lists, bound where vulkan_bin_proxies
// left them (the same results as over the host copy of the same lists: the same floats in the same
// order).
void vulkan_accumulate_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                           const DeviceBins& bins, const std::string& out);
std::shared_ptr<IndirectSums> vulkan_accumulate_indirect(render::FrameContext& ctx, const ReceiverBuffer& r, const DeviceBins& bins,
                                                         const IndirectEvaluator& ev);

}  // namespace softgi::techniques::image_splat
