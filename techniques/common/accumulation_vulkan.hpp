// Host-side helpers of the Vulkan passes that run the shared accumulation shaders
// (shaders/common/*.comp) for every technique (shexp/shexp_vulkan.cpp, image_splat/
// image_splat_vulkan.cpp, shade_vulkan.cpp). Pipeline cache, uploads of the tables and
// product plans in the shaders' layout, size checks, chunked dispatch and the exponentiate status
// words. Includes the Vulkan headers: include only from the *_vulkan.cpp files. Not installed.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "accumulation.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/backends/vulkan/gbuffer_device.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/sh/tables.hpp"
#include "softgi_shared.h"

namespace softgi::techniques::common::gpu_passes {

namespace vk = backends::vulkan;

constexpr VkBufferUsageFlags kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;

// The SPIR-V of a shader compiled once per SH order (cmake/SoftgiShaders.cmake ORDER_VARIANTS: its
// `_for(order)`), checked: an order it was not compiled for is a logic error naming `what`.
std::span<const std::uint32_t> order_variant(std::span<const std::uint32_t> w, int order, const std::string& what);
// A compiled SPIR-V array (the generated softgi/shaders/*_comp.h headers) as a span.
template <std::size_t N>
std::span<const std::uint32_t> words(const std::uint32_t (&a)[N]) {
  return {a, N};
}

// Compute pipelines by specialisation key, created on first use.
using PipelineCache = std::map<std::string, std::unique_ptr<vk::ComputePipeline>>;
vk::ComputePipeline& pipeline(vk::Context& dev, PipelineCache& cache, const std::string& key, std::span<const std::uint32_t> spirv,
                              const std::vector<vk::SpecConstant>& spec);

std::string mib(std::size_t bytes);  // "1.5 MiB"
// Loop iterations a shader that counts its own may run per invocation on this device: the driver's
// limit less a margin for the loops it does not count, or no limit (0xffffffff).
std::uint32_t loop_budget(const vk::DeviceInfo& d);
double timer_seconds(const vk::SubmitResult& res);  // the first timer's seconds, -1 without timers

// Per-pass buffers larger than the device allows are reported before anything is allocated, naming
// the scene quantity that is too large: "<pass> on vulkan: <what> need ... (<advice>)".
void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass, const std::string& advice);

// Dispatches over [0, count) in chunks the device's workgroup-count limit allows.
template <class Push, class Fill>
void dispatch_chunks(vk::Recorder& rec, const vk::ComputePipeline& p, const std::vector<vk::Bind>& binds, std::size_t count,
                     std::uint32_t group, Fill fill) {
  const std::size_t max_items = static_cast<std::size_t>(rec.context().device_info().limits.maxComputeWorkGroupCount[0]) * group;
  for (std::size_t first = 0; first < count; first += max_items) {
    const std::size_t end = std::min(count, first + max_items);
    Push push = fill(static_cast<std::uint32_t>(first), static_cast<std::uint32_t>(end));
    rec.dispatch(p, binds, push, static_cast<std::uint32_t>((end - first + group - 1) / group));
  }
}

// A host vector into a reused device buffer (at least one element large, so empty inputs bind).
template <class V>
void put(vk::Context& dev, vk::Buffer& b, const V& v, const std::string& name) {
  // At least one 16-byte texel: an unused binding may still be viewed as vec4 texels.
  const std::size_t bytes = std::max<std::size_t>(16, std::max<std::size_t>(1, v.size()) * sizeof(v[0]));
  dev.ensure_buffer(b, bytes, kStorage, vk::MemoryKind::Device, name);
  if (!v.empty()) dev.upload(b, v.data(), v.size() * sizeof(v[0]));
}

// A table of host floats in a device buffer, re-uploaded only when its floats differ from `host`
// (the copy last uploaded), compared in place. An empty table uploads one 0 (an unused binding still
// needs a buffer). `usage`: the buffer's (with VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT for a uniform block).
void upload_if_changed(vk::Context& dev, vk::Buffer& buf, std::vector<float>& host, std::span<const float> now, const std::string& name,
                       VkBufferUsageFlags usage = kStorage);

// A 64-bit hash of a byte range (FNV-style multiply and shift over 8-byte words, in four streams):
// what a device buffer was last filled with, so that inputs that did not change between frames stay
// on the device.
std::uint64_t content_hash(const void* data, std::size_t bytes, std::uint64_t seed = 0xcbf29ce484222325ull);
// `bytes` bytes into `b` (grown as needed; at least 16 bytes so that an empty input binds), uploaded
// only when their hash differs from `hash` (the last upload's, updated) or `b` was reallocated.
void upload_bytes_if_changed(vk::Context& dev, vk::Buffer& b, std::uint64_t& hash, const void* data, std::size_t bytes,
                             const std::string& name);
template <class V>
void put_if_changed(vk::Context& dev, vk::Buffer& b, std::uint64_t& hash, const V& v, const std::string& name) {
  upload_bytes_if_changed(dev, b, hash, v.data(), v.size() * sizeof(v[0]), name);
}

// Receivers as six planes px, py, pz, nx, ny, nz (accumulate_log.comp's and shade.comp's layout).
// With `hash`: uploaded only when they changed since the upload that set it.
void upload_receivers(vk::Context& dev, vk::Buffer& buf, const ReceiverSoA& soa, const std::string& name,
                      std::uint64_t* hash = nullptr);

// A frame resource a GPU pass left in device memory: `floats` floats (`order`^2 per receiver) at
// the start of `buffer`. The pass stores it as the resource's device copy (FrameContext::put_device)
// and the host copy deferred (put_deferred), so that the next GPU pass binds the buffer and only a
// host pass that reads the resource downloads it; a host put() of the resource drops the device
// copy. Valid for the frame that wrote it (a graph has one writer per resource).
struct DeviceField {
  const vk::Buffer* buffer = nullptr;
  std::size_t floats = 0;
  int order = 0;
};
// The device copy of `resource` in this frame, or null.
inline const DeviceField* device_field(render::FrameContext& ctx, const std::string& resource) {
  return ctx.device_copy<DeviceField>(resource);
}
// Stores `field` as the device copy of `resource` and, deferred, its host copy: read back (under
// `m`, the mutex of the state owning the buffer) when a host pass asks for it.
template <class HostField>
void put_device_field(render::FrameContext& ctx, const std::string& resource, const DeviceField& field, std::mutex& m,
                      vk::Context& dev) {
  ctx.put_deferred<std::shared_ptr<const HostField>>(resource, [field, &m, &dev]() {
    std::lock_guard<std::mutex> lock(m);
    auto f = std::make_shared<HostField>();
    if constexpr (requires { f->channels; }) f->channels = field.order * field.order;
    else f->order = field.order;
    f->v.resize(field.floats);
    dev.download(*field.buffer, f->v.data(), f->v.size() * sizeof(float));
    return std::shared_ptr<const HostField>(f);
  });
  ctx.put_device<DeviceField>(resource, field);
}

// The eq. 11 taps and weights vulkan_upsample_weights left on the device (upsample_vulkan.cpp), when
// `index` (pixels entries) is the host copy of the weights it computed last: a later dispatch binds
// them instead of uploading the host copy. Null when they are not the resident ones.
struct ResidentTaps {
  const vk::Buffer* index = nullptr;
  const vk::Buffer* weight = nullptr;
};
ResidentTaps resident_upsample_taps(vk::Context& dev, const std::array<std::int32_t, 4>* index, std::size_t pixels);

// The host's checks of a GPU pass's inputs, on every core, naming the first bad element as one loop
// would: `first_in(begin, end)` visits the block [begin, end) (and may fill it: the packing of the
// input) and returns its first bad index, or end. Blocks of `block` indices run in parallel; the
// result is the smallest bad index, n when there is none.
std::size_t first_bad_in_blocks(std::size_t n, std::size_t block, const std::function<std::size_t(std::size_t, std::size_t)>& first_in);

// The display G-buffer's planes on the device (vulkan::DeviceGBuffer, left by the Vulkan "gbuffer"
// pass) when `depth` and `normal` are the host planes of width x height pixels that pass put in
// this frame; null otherwise (planes from elsewhere are packed and uploaded).
const vk::DeviceGBuffer* resident_display_planes(render::FrameContext& ctx, const float* depth, const glm::vec3* normal, int width,
                                                 int height);

// Column `column` of every row of a device field (`stride` floats per row, `rows` rows): read back
// without the rest of the field (shaders/common/field_column.comp).
std::vector<float> download_field_column(vk::Context& dev, const DeviceField& field, std::size_t stride, std::size_t column,
                                         const std::string& what);

// The OL table: the increasing prefix of the core's OL sweep that sh::ShTables::ol_lookup
// interpolates, converted to float as planes x, a, b. `technique` names the buffer and the error.
struct OlTable {
  vk::Buffer buffer;
  std::uint32_t count = 0;
};
OlTable upload_ol_table(vk::Context& dev, const sh::ShTables& sht, const std::string& technique);

// The basis-recurrence constants (basis_recurrence_constants), uploaded once per device and shared by
// every pass that runs the shared shaders (they never change). (The product plans are code: the
// shaders' squares and products are generated from ProductPlan at build time, sh_exp.glsl.)
const vk::Buffer& basis_constants(vk::Context& dev);


// Floats of band weights per blocker in PackedBlockers::w: the order rounded up to a multiple of 4
// (accumulate_log.comp reads them as vec4s; the padding holds w_fill and is never read as a weight).
constexpr std::size_t weight_stride(int order) { return 4 * ((static_cast<std::size_t>(order) + 3) / 4); }

// Blocker lists concatenated as accumulate_log.comp reads them: spheres (cx, cy, cz, r), band
// weights (`order` per sphere in rows of weight_stride(order) floats; `w_fill` for a list without
// weights) and a (first, count) range per list. At least `min_rows` spheres and lists are allocated
// (zero-filled). A non-empty list of another order is a logic error: "<technique> vulkan: a blocker
// list of order X for <order_name> n".
struct PackedBlockers {
  std::vector<float> sph, w;
  std::vector<std::uint32_t> ranges;
};
PackedBlockers pack_blocker_lists(const std::vector<BlockerList>& lists, int order, std::size_t min_rows, float w_fill,
                                  const std::string& technique, const std::string& order_name);

// The accumulation inputs of accumulate_log.comp in device buffers, each uploaded only when its
// content changed since the last frame (receivers, receiver-to-list map, list ranges, spheres, band
// weights). upload() returns the bytes it uploaded.
struct AccumulationInputs {
  vk::Buffer receivers, rlist, ranges, blockers, weights;
  std::uint64_t receivers_hash = 0, rlist_hash = 0, ranges_hash = 0, blockers_hash = 0, weights_hash = 0;
  std::uint32_t longest = 0;  // the longest blocker list uploaded
  std::size_t upload(vk::Context& dev, const ReceiverSoA& soa, const std::vector<std::uint32_t>& rlist, const PackedBlockers& packed,
                     const std::string& technique);
};

// The accumulate_log.comp dispatch over `count` receivers (bindings as softgi_shared.h names them),
// timed as "accumulate_log". cut > 0: a blocker counts only where |c - p| < cut r (image_splat).
// Under a driver's loop-iteration limit the blocker lists (the longest holds `longest`) are summed
// in chunks of accumulate_log_chunk blockers, one dispatch each, every chunk adding to the sums
// before it (the same float additions in the same order as one pass); `chunks` gets their count.
struct AccumulateBuffers {
  const vk::Buffer &receivers, &rlist, &ranges, &blockers, &weights, &table, &basis, &out;
};
vk::SubmitResult run_accumulate_log(vk::Context& dev, const vk::ComputePipeline& p, const AccumulateBuffers& b, std::size_t count,
                                    const ZhTable& log, std::uint32_t longest, const std::string& submit_name, float cut = 0.0f,
                                    std::uint32_t* chunks = nullptr);
// Blockers one invocation of accumulate_log.comp at `order` may sum under the device's loop budget:
// the budget over a bound of the loop iterations per blocker (every loop of the blocker's body
// counted as if the driver unrolled none of them, doubled: llvmpipe's counter was measured at 1.5x
// the loop count at order 3), at least 1.
std::uint32_t accumulate_log_chunk(const vk::DeviceInfo& d, int order);

// exponentiate.comp's methods: HYB, OL, PS* and PS (softgi_shared.h kExp*; the exact exponential
// stays on the host). The series coefficients of PS* (float(1/k!)) and PS (1.0f/k), k = 0..degree,
// as the CPU's exp_block computes them; degree in 1..kExpMaxDegree.
std::vector<float> exp_series(std::uint32_t method, int degree);
// Squares and products one receiver's series costs (the CPU's ExpStats, squarings excluded).
void exp_series_counts(std::uint32_t method, int degree, double& squares, double& products);
// The exponentiate.comp dispatch over `count` receivers, timed as "exponentiate". exponentiate.comp's
// status words: reset before the dispatch, and the CPU pass's errors (exp_batch) raised from them
// afterwards, naming the receiver. `log` holds the n2 input coefficients per receiver;
// `receiver_name(i)` names receiver i in the non-finite-input message.
struct ExponentiateBuffers {
  const vk::Buffer &in, &out, &ol, &series, &status;
};
vk::SubmitResult run_exponentiate(vk::Context& dev, const vk::ComputePipeline& p, const ExponentiateBuffers& b, std::size_t count,
                                  std::uint32_t ol_count, int degree, const std::string& submit_name);
void reset_exp_status(vk::Context& dev, vk::Buffer& status, const std::string& name);
// Whether exponentiate.comp's status words report an error (then throw_exp_errors names it).
bool exp_status_failed(const std::uint32_t (&status)[gpu::kExpStatusWords]);
void throw_exp_errors(const std::uint32_t (&status)[gpu::kExpStatusWords], const float* log, int n2, const std::string& pass,
                      const std::function<std::string(std::size_t)>& receiver_name);

}  // namespace softgi::techniques::common::gpu_passes

namespace softgi::techniques::common {
// The shading of receivers on the GPU (GpuShade; shaders/common/shade.comp): the Vulkan backend's
// ShadeKernel.
long long vulkan_shade(render::FrameContext& ctx, const GpuShade& in, const ReceiverSoA& rec, glm::vec3* out);
// The same for a gather whose receivers are display pixels (in.gather->pixel[i] for receiver i < count)
// of the display G-buffer whose planes `pixels` holds on the device: positions and normals are read
// there, and no receiver plane crosses to the device.
long long vulkan_shade_pixels(render::FrameContext& ctx, const GpuShade& in, const backends::vulkan::DeviceGBuffer& pixels,
                              std::size_t count, glm::vec3* out);
}  // namespace softgi::techniques::common
