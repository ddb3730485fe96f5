// image_splat's GPU passes on the Vulkan backend (paper 000, Sloan et al. 2007): accumulate_log and
// exponentiate through SHEXP's shaders (the per-tile blocker lists are common::BlockerLists, the log
// table a clamped common::ZhTable, exactly what shaders/common/accumulate_log.comp and
// exponentiate.comp consume). Same resources in, same structures out as the CPU passes.
#include "image_splat_vulkan.hpp"
#include "image_splat_vulkan_shading.hpp"
#include "image_splat_vulkan_binning.hpp"
#include "image_splat_vulkan_splat.hpp"

#include <algorithm>
#include <array>
#include <tuple>
#include <utility>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../common/accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/common/accumulate_log_comp.h"
#include "softgi/shaders/common/exponentiate_comp.h"
}  // namespace spv

namespace softgi::techniques::image_splat {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

namespace {

// image_splat's per-device state: pipelines by specialisation, tables uploaded when they change, and
// per-frame buffers reused from frame to frame (grown when a frame needs more).
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer basis;
  std::vector<float> log_host;                   // the floats in log_table (uploaded when they change)
  vk::Buffer log_table;
  std::weak_ptr<const sh::ShTables> ol_src;      // the ShTables whose OL table is in `ol`
  vk::Buffer ol;
  std::uint32_t ol_count = 0;
  AccumulationInputs inputs;  // accumulate_log: receivers, tile lists and spheres, uploaded when they change
  vk::Buffer log_out;
  vk::Buffer exp_in, exp_out, status, series;                       // exponentiate
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("image_splat.gpu", [] { return std::make_shared<GpuState>(); });
}

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  common::gpu_passes::check_fits(dev, bytes, what, "image_splat " + pass, "use fewer proxy spheres, a larger receiver_scale, or --backend cpu");
}

static_assert(sizeof(std::array<std::int32_t, 4>) == 16 && sizeof(std::array<float, 4>) == 16, "ivec4 / vec4 layout");

// The clamped log table: ShadowTables::log.data, the CPU accumulation's own floats. The ShadowTables
// object is copied every frame (it carries eta_indirect), so the upload is keyed by content.
const vk::Buffer& log_table(vk::Context& dev, GpuState& g, const ShadowTables& t) {
  upload_if_changed(dev, g.log_table, g.log_host, t.log.data, "image_splat log ZH table");
  return g.log_table;
}

// The OL table: the increasing prefix of the core's OL sweep that sh::ShTables::ol_lookup
// interpolates, converted to float once per ShTables object.
void ol_table(vk::Context& dev, GpuState& g, const std::shared_ptr<const sh::ShTables>& sht) {
  if (!g.ol_src.expired() && g.ol_src.lock() == sht) return;
  OlTable ol = upload_ol_table(dev, *sht, "image_splat");
  g.ol = std::move(ol.buffer);
  g.ol_count = ol.count;
  g.ol_src = sht;
}

// common::ProductPlan in the exponentiate shader's form.

void check_accumulate_inputs(vk::Context& dev, const ShadowTables& t, const ReceiverBuffer& r, std::size_t lists, std::size_t total) {
  const int n = t.order, n2 = n * n;
  if (t.log.order != n || n > static_cast<int>(gpu::kAccumMaxOrder))
    throw std::logic_error("image_splat accumulate_log on vulkan: log table of order " + std::to_string(t.log.order) + " for order " +
                           std::to_string(n));
  const std::size_t count = r.soa.size();
  if (count > std::numeric_limits<std::uint32_t>::max() / 8)
    throw std::invalid_argument("image_splat accumulate_log on vulkan: " + std::to_string(count) + " receivers exceed the 32-bit indexing");
  if (lists != r.tiles.size())
    throw std::logic_error("image_splat accumulate_log on vulkan: " + std::to_string(lists) + " blocker lists for " +
                           std::to_string(r.tiles.size()) + " tiles");
  const std::string pass = "accumulate_log";
  check_fits(dev, total * 4 * sizeof(float), std::to_string(total) + " tile-proxy pairs (binned spheres)", pass);
  check_fits(dev, total * weight_stride(n) * sizeof(float), "the band weights of " + std::to_string(total) + " binned spheres", pass);
  check_fits(dev, count * n2 * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", pass);
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", pass);
}

// accumulate_log over `lists` (bound under g.m, which the caller holds), receivers and the
// receiver-to-tile map uploaded when they change.
void accumulate_log_bound(render::FrameContext& ctx, vk::Context& dev, GpuState& g, const Settings& s, const ShadowTables& t,
                          const ReceiverBuffer& r, const DeviceBinList& lists, std::size_t uploaded, const std::string& out) {
  const int n = t.order, n2 = n * n;
  const std::size_t count = r.soa.size();
  std::vector<std::uint32_t> rlist(count, 0);
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    for (std::size_t i = r.tiles[k].begin; i < r.tiles[k].end; ++i) rlist[i] = static_cast<std::uint32_t>(k);
  const std::size_t before = dev.transfer_bytes().upload;
  upload_receivers(dev, g.inputs.receivers, r.soa, "image_splat receivers", &g.inputs.receivers_hash);
  put_if_changed(dev, g.inputs.rlist, g.inputs.rlist_hash, rlist, "image_splat receiver lists");
  uploaded += dev.transfer_bytes().upload - before;
  const vk::Buffer& table = log_table(dev, g, t);
  // The log occlusion stays on the device for exponentiate (device-local memory).
  dev.ensure_buffer(g.log_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "image_splat log occlusion");

  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "image_splat.accumulate_log.n" + std::to_string(n) + ".rule" + std::to_string(static_cast<int>(s.rule)),
                                    words(spv::common_accumulate_log_comp),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(s.rule)}});
  vk::SubmitResult res;
  std::uint32_t chunks = 0;
  if (count)
    res = run_accumulate_log(dev, p, {g.inputs.receivers, g.inputs.rlist, *lists.ranges, *lists.spheres, *lists.payload, table, basis_constants(dev), g.log_out}, count, t.log,
                             lists.longest, "image_splat accumulate_log", pair_cut_factor(t, s.rule), &chunks);

  double pairs = 0.0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    pairs += static_cast<double>(r.tiles[k].end - r.tiles[k].begin) * static_cast<double>(lists.counts[k]);
  const double secs = timer_seconds(res);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["pairs"] = pairs;
  rec.counters["blocker_chunks"] = chunks;
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["kernel_gpu_seconds"] = secs;
  rec.counters["hard_cut"] = t.hard_cut;
  rec.counters["pair_cut"] = pair_cut_factor(t, s.rule) > 0.0f;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = count * n2 * sizeof(float);
  put_device_field<Field>(ctx, out, DeviceField{&g.log_out, count * n2, n}, g.m, dev);
}

}  // namespace

void vulkan_accumulate_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                           const ProxyBins& bins, const std::string& out) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  DeviceBinList lists = host_lists(bins.shadow);
  check_accumulate_inputs(dev, t, r, bins.shadow.size(), lists.total);
  // The tiles' blocker lists concatenated; each receiver reads the list of its tile.
  const PackedBlockers packed = pack_blocker_lists(bins.shadow, t.order, 0, 1.0f, "image_splat", "order");
  const std::size_t before = dev.transfer_bytes().upload;
  put_if_changed(dev, g.inputs.ranges, g.inputs.ranges_hash, packed.ranges, "image_splat list ranges");
  put_if_changed(dev, g.inputs.blockers, g.inputs.blockers_hash, packed.sph, "image_splat blocker spheres");
  put_if_changed(dev, g.inputs.weights, g.inputs.weights_hash, packed.w, "image_splat band weights");
  lists.ranges = &g.inputs.ranges;
  lists.spheres = &g.inputs.blockers;
  lists.payload = &g.inputs.weights;
  accumulate_log_bound(ctx, dev, g, s, t, r, lists, dev.transfer_bytes().upload - before, out);
}

void vulkan_accumulate_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                           const DeviceBins& bins, const std::string& out) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  check_accumulate_inputs(dev, t, r, bins.shadow.counts.size(), bins.shadow.total);
  accumulate_log_bound(ctx, dev, g, s, t, r, bins.shadow, 0, out);
}

bool vulkan_exp_supports(ExpMode m) { return m == ExpMode::HYB || m == ExpMode::OL || m == ExpMode::PSStar || m == ExpMode::PS; }

void vulkan_exponentiate(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const std::string& in,
                         const std::string& out) {
  if (!vulkan_exp_supports(s.exp)) throw std::logic_error("image_splat exponentiate on vulkan: HYB, OL, PS* and PS only");
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const int n = t.order, n2 = n * n;
  // The log occlusion where accumulate_log left it on the device, else uploaded from the host.
  const DeviceField* dlog = device_field(ctx, in);
  std::shared_ptr<const Field> hlog;
  if (!dlog) hlog = ctx.get<std::shared_ptr<const Field>>(in);
  const int channels = dlog ? dlog->order * dlog->order : hlog->channels;
  if (channels != n2)
    throw std::logic_error("image_splat exponentiate on vulkan: " + std::to_string(channels) + " log channels for order " + std::to_string(n));
  const std::size_t count = (dlog ? dlog->floats : hlog->v.size()) / n2;
  check_fits(dev, count * n2 * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", "exponentiate");

  ol_table(dev, g, t.sh);
  if (!dlog) put(dev, g.exp_in, hlog->v, "image_splat exp input");
  const vk::Buffer& exp_in = dlog ? *dlog->buffer : g.exp_in;
  dev.ensure_buffer(g.exp_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Device, "image_splat occlusion");
  reset_exp_status(dev, g.status, "image_splat exp status");

  const std::uint32_t method = s.exp == ExpMode::HYB ? gpu::kExpHyb : s.exp == ExpMode::OL ? gpu::kExpOl : s.exp == ExpMode::PSStar ? gpu::kExpPsStar : gpu::kExpPs;
  put(dev, g.series, exp_series(method, s.ps_degree), "image_splat exp series");
  // Accumulation order = shading order: the log vector is exponentiated at the shadow order n.
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "image_splat.exponentiate.n" + std::to_string(n) + ".m" + std::to_string(method),
                                    order_variant(spv::common_exponentiate_comp_for(n), n, "image_splat exponentiate"),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(n)}, {2, method}});
  vk::SubmitResult res;
  if (count)
    res = run_exponentiate(dev, p, {exp_in, g.exp_out, g.ol, g.series, g.status}, count, g.ol_count, s.ps_degree,
                           "image_splat exponentiate");

  std::uint32_t status[gpu::kExpStatusWords];
  dev.download(g.status, status, sizeof status);
  if (exp_status_failed(status)) {
    // The error names the offending coefficient: read the log vectors back for it.
    std::vector<float> log(count * n2);
    if (dlog) dev.download(*dlog->buffer, log.data(), log.size() * sizeof(float));
    else log = hlog->v;
    throw_exp_errors(status, log.data(), n2, "image_splat exponentiate on vulkan", [](std::size_t i) { return "receiver " + std::to_string(i); });
  }
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["squarings"] = status[gpu::kExpStatusSquarings];
  rec.counters["kernel_gpu_seconds"] = timer_seconds(res);
  rec.bytes = count * n2 * sizeof(float);
  put_device_field<Field>(ctx, out, DeviceField{&g.exp_out, count * n2, n}, g.m, dev);
}

DirectKernels vulkan_direct_kernels(render::FrameContext& ctx) {
  render::FrameContext* c = &ctx;
  DirectKernels k;
  k.surface = [c](const DirectShader& d, const render::GBuffer& fine, const Upsampled& up, glm::vec3* out) -> long long {
    const std::size_t ns = up.surface.size();
    if (ns == 0) return 0;
    const common::BatchShade bs = d.batch(nullptr);
    const std::size_t n2 = static_cast<std::size_t>(d.order) * d.order;
    common::GpuShade in{&bs, d.lights_table.get(), &d.lights, true, nullptr};
    common::GpuShade::Gather ga;
    if (up.device_visibility) {
      // Section 4.2 with O_p where exponentiate left it, in receiver order: each tap's coarse pixel
      // reads the row of its receiver (a tap only ever names a coarse pixel that hit a surface).
      if (up.w.index.size() != fine.object.size() || up.w.weight.size() != up.w.index.size())
        throw std::logic_error("image_splat shade_direct on vulkan: upsampling weights do not match the display buffer");
      ga.pixel = up.surface.data();
      ga.index = up.w.index.data();
      ga.weight = up.w.weight.data();
      ga.pixels = up.w.index.size();
      ga.coarse_resource = up.device_visibility;
      ga.coarse_row = up.coarse_receiver.data();
      ga.coarse_rows = up.coarse_receiver.size();
      in.gather = &ga;
    } else if (!up.coarse_visibility.empty()) {  // section 4.2: O_p interpolated on the device
      if (up.coarse_visibility.size() % n2 != 0 || up.w.index.size() != fine.object.size() || up.w.weight.size() != up.w.index.size())
        throw std::logic_error("image_splat shade_direct on vulkan: upsampled visibility and weights do not match the display buffer");
      ga.pixel = up.surface.data();
      ga.index = up.w.index.data();
      ga.weight = up.w.weight.data();
      ga.pixels = up.w.index.size();
      ga.coarse = up.coarse_visibility.data();
      ga.coarse_count = up.coarse_visibility.size() / n2;
      in.gather = &ga;
    }
    // The surface pixels' positions and normals where the G-buffer pass left them on the device;
    // packed from the host planes and uploaded otherwise.
    const vk::DeviceGBuffer* planes =
        in.gather ? resident_display_planes(*c, fine.depth.data(), fine.normal.data(), fine.width, fine.height) : nullptr;
    if (planes && planes->host_position != fine.position.data()) planes = nullptr;
    c->record().counters["receivers_resident"] = planes ? 1.0 : 0.0;
    if (planes) return common::vulkan_shade_pixels(*c, in, *planes, ns, out);
    common::ReceiverSoA soa;
    soa.resize(ns);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ns, 1 << 14), [&](const tbb::blocked_range<std::size_t>& br) {
      for (std::size_t i = br.begin(); i != br.end(); ++i) {
        const std::size_t p = static_cast<std::size_t>(up.surface[i]);
        soa.set(i, fine.position[p], fine.normal[p]);
      }
    });
    return common::vulkan_shade(*c, in, soa, out);
  };
  k.receivers = [c](const DirectShader& d, const common::ReceiverSoA& rec, const float* g, glm::vec3* out) -> long long {
    const common::BatchShade bs = d.batch(g);
    return common::vulkan_shade(*c, common::GpuShade{&bs, d.lights_table.get(), &d.lights, true, nullptr}, rec, out);
  };
  k.reads_device_visibility = true;
  return k;
}

// O_p's DC coefficients (normalize_indirect's xi_p, eq. 12) from exponentiate's device copy.
std::vector<float> vulkan_field_dc(render::FrameContext& ctx, const std::string& name) {
  const DeviceField* f = device_field(ctx, name);
  if (!f) throw std::logic_error("image_splat normalize_indirect on vulkan: '" + name + "' has no device copy");
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);  // the field's buffer is this state's
  const std::size_t before = dev.transfer_bytes().download;
  std::vector<float> dc = download_field_column(dev, *f, static_cast<std::size_t>(f->order) * f->order, 0, "image_splat normalize_indirect");
  ctx.record().counters["dc_download_bytes"] = static_cast<double>(dev.transfer_bytes().download - before);
  return dc;
}

void register_vulkan_kernels() {
  DeviceKernels k;
  k.field_dc = vulkan_field_dc;
  k.bin_proxies = vulkan_bin_proxies;
  // The lists where bin_proxies left them: on the device (device binning) or on the host.
  k.accumulate_log = [](render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                        const std::string& bins, const std::string& out) {
    if (const auto* d = ctx.device_copy<std::shared_ptr<const DeviceBins>>(bins)) {
      if ((*d)->order != t.order)
        throw std::logic_error("image_splat accumulate_log on vulkan: device lists of order " + std::to_string((*d)->order) +
                               " for order " + std::to_string(t.order));
      return vulkan_accumulate_log(ctx, s, t, r, **d, out);
    }
    vulkan_accumulate_log(ctx, s, t, r, *ctx.get<std::shared_ptr<const ProxyBins>>(bins), out);
  };
  k.splat_log = vulkan_splat_log;
  k.splat_indirect = vulkan_splat_indirect;
  k.exp_supports = vulkan_exp_supports;
  k.exponentiate = vulkan_exponentiate;
  k.indirect_supported = vulkan_indirect_supported;
  k.accumulate_indirect = [](render::FrameContext& ctx, const ReceiverBuffer& r, const std::string& bins, const IndirectEvaluator& ev) {
    if (const auto* d = ctx.device_copy<std::shared_ptr<const DeviceBins>>(bins)) return vulkan_accumulate_indirect(ctx, r, **d, ev);
    return vulkan_accumulate_indirect(ctx, r, *ctx.get<std::shared_ptr<const ProxyBins>>(bins), ev);
  };
  k.upsample = common::vulkan_upsample_kernels;
  k.direct = vulkan_direct_kernels;
  register_device_kernels(vk::kBackendName, std::move(k));
}

}  // namespace softgi::techniques::image_splat
