// SHEXP's GPU passes on the Vulkan backend (paper 004): accumulate_log and exponentiate (HYB, OL,
// PS*, PS) on the shared accumulation shaders; the shade pass's kernel is common::vulkan_shade. They
// read and write the same frame resources as the host passes (so the backends can be compared pass
// by pass). Tables, product plans and basis constants are the CPU's own floats, uploaded once per
// device and kept in the context's cache.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include "shexp_passes.hpp"
#include "../common/accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/sh/product.hpp"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/common/accumulate_log_comp.h"
#include "softgi/shaders/common/exponentiate_comp.h"
}  // namespace spv

namespace softgi::techniques::shexp {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

static_assert(static_cast<int>(ReplacementRule::Off) == static_cast<int>(gpu::kRuleOff) &&
                  static_cast<int>(ReplacementRule::Continuous) == static_cast<int>(gpu::kRuleContinuous) &&
                  static_cast<int>(ReplacementRule::Clamped) == static_cast<int>(gpu::kRuleClamped) &&
                  static_cast<int>(ReplacementRule::Printed) == static_cast<int>(gpu::kRulePrinted) &&
                  static_cast<int>(ReplacementRule::InsideOnly) == static_cast<int>(gpu::kRuleInsideOnly),
              "ReplacementRule and softgi_shared.h disagree");
static_assert(kMaxAccOrder * kMaxAccOrder == static_cast<int>(gpu::kAccumMaxCoeffs), "softgi_shared.h: max coefficients");

namespace {

// SHEXP's per-device state: pipelines by specialisation, constants uploaded once, and per-frame
// buffers reused from frame to frame (grown when a frame needs more).
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  std::weak_ptr<const Tables> table_src;  // the Tables whose log table / OL table are uploaded
  vk::Buffer log_table, ol;
  std::uint32_t ol_count = 0;
  AccumulationInputs inputs;  // accumulate: receivers, lists and blockers, uploaded when they change
  vk::Buffer field_out;
  vk::Buffer exp_in, exp_out, status, series;                         // exponentiate
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("shexp.gpu", [] { return std::make_shared<GpuState>(); });
}

// The log table (ZhTable::data, the accumulation's float copy of the core's double table) and the
// OL table (the increasing prefix of the core's OL sweep that sh::ShTables::ol_lookup interpolates,
// converted to float), uploaded when the frame's Tables object changes.
void upload_tables(vk::Context& dev, GpuState& g, const std::shared_ptr<const Tables>& t) {
  if (!g.table_src.expired() && g.table_src.lock() == t) return;
  g.log_table = dev.upload_vector(t->log.data, kStorage, "shexp log ZH table");
  OlTable ol = upload_ol_table(dev, *t->sh, "shexp");
  g.ol = std::move(ol.buffer);
  g.ol_count = ol.count;
  g.table_src = t;
}

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  gpu_passes::check_fits(dev, bytes, what, "shexp " + pass, "use fewer proxy spheres or receivers, the sphere hierarchy, or --backend cpu");
}

}  // namespace

bool vulkan_exp_supports(Mode m) { return m == Mode::HYB || m == Mode::OL || m == Mode::PSStar || m == Mode::PS; }

void vulkan_accumulate(const Settings& s, render::FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto tp = ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& t = *tp;
  const auto& cuts = *ctx.get<std::shared_ptr<const Cuts>>(kCuts);
  const int na = t.acc_order, n2a = na * na;
  const std::size_t count = r.soa.size();
  if (count > std::numeric_limits<std::uint32_t>::max() / 2)
    throw std::invalid_argument("shexp accumulate_log on vulkan: " + std::to_string(count) + " receivers exceed the 32-bit indexing");

  std::size_t total = 0;
  for (const auto& l : cuts.lists) total += l.size();
  check_fits(dev, total * 4 * sizeof(float), std::to_string(total) + " blocker spheres in the cuts", "accumulate_log");
  check_fits(dev, total * weight_stride(na) * sizeof(float), "the band weights of " + std::to_string(total) + " blockers", "accumulate_log");
  check_fits(dev, count * n2a * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", "accumulate_log");
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", "accumulate_log");

  // Blocker lists concatenated; each receiver reads the list of its cluster.
  const PackedBlockers packed = pack_blocker_lists(cuts.lists, na, 1, 0.0f, "shexp", "accumulation order");
  std::vector<std::uint32_t> rlist(std::max<std::size_t>(1, count), 0);
  for (std::size_t c = 0; c < r.clusters.size(); ++c)
    for (std::size_t i = r.clusters[c].begin; i < r.clusters[c].end; ++i) rlist[i] = static_cast<std::uint32_t>(cuts.list_of_cluster[c]);

  upload_tables(dev, g, tp);
  const vk::Buffer& basis = basis_constants(dev);
  const std::size_t uploaded = g.inputs.upload(dev, r.soa, rlist, packed, "shexp");
  // The log vectors stay on the device for exponentiate (device-local memory).
  const std::size_t out_bytes = std::max<std::size_t>(1, count * n2a) * sizeof(float);
  dev.ensure_buffer(g.field_out, out_bytes, kStorage, vk::MemoryKind::Device, "shexp log vectors");

  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "shexp.accumulate_log.n" + std::to_string(na) + ".rule" + std::to_string(static_cast<int>(s.rule)),
                                    words(spv::common_accumulate_log_comp),
                                    {{0, static_cast<std::uint32_t>(na)}, {1, static_cast<std::uint32_t>(s.rule)}});
  std::uint32_t chunks = 1;
  const vk::SubmitResult res = run_accumulate_log(
      dev, p, {g.inputs.receivers, g.inputs.rlist, g.inputs.ranges, g.inputs.blockers, g.inputs.weights, g.log_table, basis, g.field_out}, count, t.log,
      g.inputs.longest, "shexp accumulate_log", 0.0f, &chunks);

  auto& record = ctx.record();
  double pairs = 0.0;
  blocker_counters(record, r, cuts, pairs);
  const double secs = timer_seconds(res);
  record.counters["kernel_gpu_seconds"] = secs;
  record.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  record.counters["upload_bytes"] = static_cast<double>(uploaded);
  record.counters["blocker_chunks"] = chunks;
  record.bytes = count * n2a * sizeof(float);
  put_device_field<Field>(ctx, kLogVisibility, DeviceField{&g.field_out, count * n2a, na}, g.m, dev);
}

void vulkan_exponentiate(const Settings& s, render::FrameContext& ctx) {
  if (!vulkan_exp_supports(s.mode)) throw std::logic_error("shexp vulkan: exponentiate supports HYB, OL, PS* and PS only");
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto tp = ctx.get<std::shared_ptr<const Tables>>(kTables);
  // The log vectors where accumulate_log left them on the device, else uploaded from the host.
  const DeviceField* dlog = device_field(ctx, kLogVisibility);
  std::shared_ptr<const Field> hlog;
  if (!dlog) hlog = ctx.get<std::shared_ptr<const Field>>(kLogVisibility);
  const int na = dlog ? dlog->order : hlog->order, n2a = na * na, n2 = s.order * s.order;
  const std::size_t count = r.soa.size();
  check_fits(dev, count * n2a * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", "exponentiate");
  if ((dlog ? dlog->floats : hlog->v.size()) != count * n2a)
    throw std::logic_error("shexp exponentiate on vulkan: the log vectors do not match the " + std::to_string(count) + " receivers");

  upload_tables(dev, g, tp);
  if (!dlog) {
    dev.ensure_buffer(g.exp_in, std::max<std::size_t>(1, hlog->v.size()) * sizeof(float), kStorage, vk::MemoryKind::Device, "shexp exp input");
    dev.upload(g.exp_in, hlog->v.data(), hlog->v.size() * sizeof(float));
  }
  const vk::Buffer& exp_in = dlog ? *dlog->buffer : g.exp_in;
  dev.ensure_buffer(g.exp_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Device, "shexp visibility");
  reset_exp_status(dev, g.status, "shexp exp status");

  const std::uint32_t method = s.mode == Mode::HYB ? gpu::kExpHyb : s.mode == Mode::OL ? gpu::kExpOl : s.mode == Mode::PSStar ? gpu::kExpPsStar : gpu::kExpPs;
  put(dev, g.series, exp_series(method, s.ps_degree), "shexp exp series");
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "shexp.exponentiate.n" + std::to_string(na) + ".out" + std::to_string(s.order) + ".m" + std::to_string(method),
                                    order_variant(spv::common_exponentiate_comp_for(na), na, "shexp exponentiate"),
                                    {{0, static_cast<std::uint32_t>(na)}, {1, static_cast<std::uint32_t>(s.order)}, {2, method}});
  const vk::SubmitResult res =
      run_exponentiate(dev, p, {exp_in, g.exp_out, g.ol, g.series, g.status}, count, g.ol_count, s.ps_degree, "shexp exponentiate");

  std::uint32_t status[gpu::kExpStatusWords];
  dev.download(g.status, status, sizeof status);
  if (exp_status_failed(status)) {
    // The error names the offending coefficient: read the log vectors back for it.
    std::vector<float> log(count * n2a);
    if (dlog) dev.download(*dlog->buffer, log.data(), log.size() * sizeof(float));
    else log = hlog->v;
    throw_exp_errors(status, log.data(), n2a, "shexp exponentiate",
                     [&](std::size_t i) { return "receiver " + std::to_string(i) + " (object " + std::to_string(r.object[i]) + ")"; });
  }

  auto& record = ctx.record();
  const double nrec = static_cast<double>(count);
  record.counters["receivers"] = nrec;
  double series_squares = 0.0, series_products = 0.0;
  exp_series_counts(method, s.ps_degree, series_squares, series_products);
  record.counters["squarings"] = status[gpu::kExpStatusSquarings];
  record.counters["squares"] = status[gpu::kExpStatusSquarings] + nrec * series_squares;
  record.counters["products"] = nrec * series_products;
  record.counters["squarings_per_receiver"] = nrec > 0 ? status[gpu::kExpStatusSquarings] / nrec : 0.0;
  record.counters["kernel_gpu_seconds"] = timer_seconds(res);
  record.bytes = count * n2 * sizeof(float);
  // The visibility stays on the device for the shade pass.
  put_device_field<Field>(ctx, kVisibility, DeviceField{&g.exp_out, count * n2, s.order}, g.m, dev);
}

void register_vulkan_kernels() {
  DeviceKernels k;
  k.accumulate = vulkan_accumulate;
  k.exp_supports = vulkan_exp_supports;
  k.exponentiate = vulkan_exponentiate;
  k.shade = common::vulkan_shade;
  register_device_kernels(vk::kBackendName, std::move(k));
}

}  // namespace softgi::techniques::shexp
