// SHEXP's GPU passes on the Vulkan backend (paper 004): accumulate_log, exponentiate (HYB, OL, PS*,
// PS) and the shading of the shade pass (also image_splat's shade_direct). They read and write the
// same host-side frame resources as the CPU passes (so the backends can be compared pass by pass), upload what they need, and read
// their result back. Tables, product plans and basis constants are the CPU's own floats, uploaded
// once per device and kept in the context's cache.
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
#include "shexp_vulkan_common.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/sh/product.hpp"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/accumulate_log_comp.h"
#include "softgi/shaders/exponentiate_comp.h"
#include "softgi/shaders/shade_comp.h"
}  // namespace spv

namespace softgi::techniques::shexp {

namespace vk = backends::vulkan;
using namespace vulkan_common;

static_assert(static_cast<int>(ReplacementRule::Off) == static_cast<int>(gpu::kRuleOff) &&
                  static_cast<int>(ReplacementRule::Continuous) == static_cast<int>(gpu::kRuleContinuous) &&
                  static_cast<int>(ReplacementRule::Clamped) == static_cast<int>(gpu::kRuleClamped) &&
                  static_cast<int>(ReplacementRule::Printed) == static_cast<int>(gpu::kRulePrinted),
              "ReplacementRule and softgi_shared.h disagree");
static_assert(kMaxAccOrder * kMaxAccOrder == static_cast<int>(gpu::kShexpMaxCoeffs), "softgi_shared.h: max coefficients");

namespace {

// SHEXP's per-device state: pipelines by specialisation, constants uploaded once, and per-frame
// buffers reused from frame to frame (grown when a frame needs more).
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer basis;
  std::map<int, PlanBuffers> plans;
  std::weak_ptr<const Tables> table_src;  // the Tables whose log table / OL table are uploaded
  vk::Buffer log_table, ol;
  std::uint32_t ol_count = 0;
  vk::Buffer receivers, rlist, ranges, blockers, weights, field_out;  // accumulate
  vk::Buffer exp_in, exp_out, status, series;                         // exponentiate
  vk::Buffer shade_rec, shade_vis, shade_consts, shade_out, shade_status, shade_lights;  // shade
  vk::Buffer shade_tap_pixel, shade_tap_index, shade_tap_weight;                 // shade: eq. 11 gather (image_splat)
  vk::Buffer light_table;               // LightLobeTable psi then k
  std::vector<float> light_host;        // the floats in light_table (upload_if_changed)
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("shexp.gpu", [] { return std::make_shared<GpuState>(); });
}

const PlanBuffers& plan_buffers(vk::Context& dev, GpuState& g, int order) {
  auto it = g.plans.find(order);
  if (it != g.plans.end()) return it->second;
  return g.plans.emplace(order, upload_product_plan(dev, ProductPlan::get(order), "shexp")).first->second;
}

const vk::Buffer& basis_buffer(vk::Context& dev, GpuState& g) {
  if (!g.basis) g.basis = dev.upload_vector(basis_recurrence_constants(), kStorage, "shexp basis constants");
  return g.basis;
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
  vulkan_common::check_fits(dev, bytes, what, "shexp " + pass, "use fewer proxy spheres or receivers, the sphere hierarchy, or --backend cpu");
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
  check_fits(dev, total * na * sizeof(float), "the band weights of " + std::to_string(total) + " blockers", "accumulate_log");
  check_fits(dev, count * n2a * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", "accumulate_log");
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", "accumulate_log");

  // Blocker lists concatenated; each receiver reads the list of its cluster.
  const PackedBlockers packed = pack_blocker_lists(cuts.lists, na, 1, 0.0f, "shexp", "accumulation order");
  const std::vector<float>&sph = packed.sph, &w = packed.w;
  const std::vector<std::uint32_t>& ranges = packed.ranges;
  std::vector<std::uint32_t> rlist(std::max<std::size_t>(1, count), 0);
  for (std::size_t c = 0; c < r.clusters.size(); ++c)
    for (std::size_t i = r.clusters[c].begin; i < r.clusters[c].end; ++i) rlist[i] = static_cast<std::uint32_t>(cuts.list_of_cluster[c]);

  upload_tables(dev, g, tp);
  const vk::Buffer& basis = basis_buffer(dev, g);
  upload_receivers(dev, g.receivers, r.soa, "shexp receivers");
  put(dev, g.rlist, rlist, "shexp receiver lists");
  put(dev, g.ranges, ranges, "shexp list ranges");
  put(dev, g.blockers, sph, "shexp blockers");
  put(dev, g.weights, w, "shexp band weights");
  const std::size_t out_bytes = std::max<std::size_t>(1, count * n2a) * sizeof(float);
  dev.ensure_buffer(g.field_out, out_bytes, kStorage, vk::MemoryKind::Host, "shexp log vectors");

  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "shexp.accumulate_log.n" + std::to_string(na) + ".rule" + std::to_string(static_cast<int>(s.rule)),
                                    words(spv::accumulate_log_comp),
                                    {{0, static_cast<std::uint32_t>(na)}, {1, static_cast<std::uint32_t>(s.rule)}});
  const vk::SubmitResult res = run_accumulate_log(
      dev, p, {g.receivers, g.rlist, g.ranges, g.blockers, g.weights, g.log_table, basis, g.field_out}, count, t.log, "shexp accumulate_log");

  auto f = std::make_shared<Field>();
  f->order = na;
  f->v.resize(count * n2a);
  dev.download(g.field_out, f->v.data(), f->v.size() * sizeof(float));
  auto& record = ctx.record();
  double pairs = 0.0;
  blocker_counters(record, r, cuts, pairs);
  const double secs = timer_seconds(res);
  record.counters["kernel_gpu_seconds"] = secs;
  record.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  record.counters["upload_bytes"] = static_cast<double>((sph.size() + w.size() + 6 * count) * sizeof(float) + (rlist.size() + ranges.size()) * 4);
  record.bytes = f->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kLogVisibility, f);
}

void vulkan_exponentiate(const Settings& s, render::FrameContext& ctx) {
  if (!vulkan_exp_supports(s.mode)) throw std::logic_error("shexp vulkan: exponentiate supports HYB, OL, PS* and PS only");
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto tp = ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& f = *ctx.get<std::shared_ptr<const Field>>(kLogVisibility);
  const int na = f.order, n2a = na * na, n2 = s.order * s.order;
  const std::size_t count = r.soa.size();
  check_fits(dev, count * n2a * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", "exponentiate");

  upload_tables(dev, g, tp);
  const PlanBuffers& plan = plan_buffers(dev, g, na);
  dev.ensure_buffer(g.exp_in, std::max<std::size_t>(1, f.v.size()) * sizeof(float), kStorage, vk::MemoryKind::Device, "shexp exp input");
  dev.upload(g.exp_in, f.v.data(), f.v.size() * sizeof(float));
  dev.ensure_buffer(g.exp_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Host, "shexp visibility");
  reset_exp_status(dev, g.status, "shexp exp status");

  const std::uint32_t method = s.mode == Mode::HYB ? gpu::kExpHyb : s.mode == Mode::OL ? gpu::kExpOl : s.mode == Mode::PSStar ? gpu::kExpPsStar : gpu::kExpPs;
  put(dev, g.series, exp_series(method, s.ps_degree), "shexp exp series");
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "shexp.exponentiate.n" + std::to_string(na) + ".out" + std::to_string(s.order) + ".m" + std::to_string(method),
                                    words(spv::exponentiate_comp),
                                    {{0, static_cast<std::uint32_t>(na)}, {1, static_cast<std::uint32_t>(s.order)}, {2, method}});
  const vk::SubmitResult res =
      run_exponentiate(dev, p, {g.exp_in, g.exp_out, g.ol, plan, g.series, g.status}, count, g.ol_count, s.ps_degree, "shexp exponentiate");

  std::uint32_t status[gpu::kExpStatusWords];
  dev.download(g.status, status, sizeof status);
  throw_exp_errors(status, f.v.data(), n2a, "shexp exponentiate",
                   [&](std::size_t i) { return "receiver " + std::to_string(i) + " (object " + std::to_string(r.object[i]) + ")"; });

  auto out = std::make_shared<Field>();
  out->order = s.order;
  out->v.resize(count * n2);
  dev.download(g.exp_out, out->v.data(), out->v.size() * sizeof(float));
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
  record.bytes = out->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kVisibility, out);
}

long long vulkan_shade(render::FrameContext& ctx, const GpuShade& in, const ReceiverSoA& soa, glm::vec3* out) {
  if (!in.b) throw std::logic_error("shexp shade on vulkan: no shading constants");
  const BatchShade& b = *in.b;
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const int n = b.order, n2 = n * n;
  const std::size_t count = soa.size();
  if (count == 0) return 0;
  if (count > std::numeric_limits<std::uint32_t>::max() / 8)
    throw std::invalid_argument("shexp shade on vulkan: " + std::to_string(count) + " receivers exceed the 32-bit indexing");
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", "shade");
  const bool lights = in.lights_table && in.lights && !in.lights->empty();
  const GpuShade::Gather* ga = in.gather;
  const std::uint32_t vis_mode = ga ? gpu::kShadeVisGather : (b.g ? gpu::kShadeVisReceiver : gpu::kShadeVisNone);
  const PlanBuffers& plan = plan_buffers(dev, g, n);
  const vk::Buffer& basis = basis_buffer(dev, g);
  upload_receivers(dev, g.shade_rec, soa, "shexp shade receivers");
  // Visibility: per receiver, or the coarse field of a gather.
  const float* vsrc = ga ? ga->coarse : b.g;
  const std::size_t vrows = ga ? ga->coarse_count : count;
  const std::size_t vis_bytes = vsrc ? vrows * n2 * sizeof(float) : 0;
  check_fits(dev, vis_bytes, "the visibility of " + std::to_string(vrows) + (ga ? " coarse samples" : " receivers"), "shade");
  dev.ensure_buffer(g.shade_vis, std::max<std::size_t>(sizeof(float), vis_bytes), kStorage, vk::MemoryKind::Device, "shexp shade visibility");
  if (vis_bytes) dev.upload(g.shade_vis, vsrc, vis_bytes);
  if (ga) {
    if (!ga->pixel || !ga->index || !ga->weight || (ga->coarse_count && !ga->coarse))
      throw std::logic_error("shexp shade on vulkan: incomplete gather");
    check_fits(dev, ga->pixels * 16, "the eq. 11 taps of " + std::to_string(ga->pixels) + " display pixels", "shade");
    for (std::size_t i = 0; i < count; ++i)
      if (ga->pixel[i] < 0 || static_cast<std::size_t>(ga->pixel[i]) >= ga->pixels)
        throw std::logic_error("shexp shade on vulkan: receiver " + std::to_string(i) + " gathers from pixel " + std::to_string(ga->pixel[i]) +
                               " outside " + std::to_string(ga->pixels));
    dev.ensure_buffer(g.shade_tap_pixel, count * sizeof(std::int32_t), kStorage, vk::MemoryKind::Device, "shexp shade tap pixels");
    dev.upload(g.shade_tap_pixel, ga->pixel, count * sizeof(std::int32_t));
    dev.ensure_buffer(g.shade_tap_index, ga->pixels * 16, kStorage, vk::MemoryKind::Device, "shexp shade tap index");
    dev.upload(g.shade_tap_index, ga->index, ga->pixels * 16);
    dev.ensure_buffer(g.shade_tap_weight, ga->pixels * 16, kStorage, vk::MemoryKind::Device, "shexp shade tap weights");
    dev.upload(g.shade_tap_weight, ga->weight, ga->pixels * 16);
  } else {
    for (vk::Buffer* buf : {&g.shade_tap_pixel, &g.shade_tap_index, &g.shade_tap_weight})
      dev.ensure_buffer(*buf, 16, kStorage, vk::MemoryKind::Device, "shexp shade taps (unused)");
  }
  std::vector<float> consts(5 * n2);
  std::copy(b.L, b.L + 3 * n2, consts.begin());
  std::copy(b.hcoef, b.hcoef + n2, consts.begin() + 3 * n2);
  std::copy(b.gwin, b.gwin + n2, consts.begin() + 4 * n2);
  put(dev, g.shade_consts, consts, "shexp shade constants");

  // Paper 004 section 7: the light-lobe table (the CPU's floats, uploaded when they change) and the
  // posed lights.
  const LightLobeTable* lt = in.lights_table;
  std::vector<float> light_data;
  if (lights) {
    if (lt->order != n)
      throw std::logic_error("shexp shade on vulkan: light table of order " + std::to_string(lt->order) + " for order " + std::to_string(n));
    std::vector<float> tab(lt->psi);
    tab.insert(tab.end(), lt->k.begin(), lt->k.end());
    upload_if_changed(dev, g.light_table, g.light_host, tab, "shexp light lobe table");
    for (const auto& l : *in.lights) {
      light_data.insert(light_data.end(), {l.position.x, l.position.y, l.position.z, l.radius});
      light_data.insert(light_data.end(), {l.radiance.x, l.radiance.y, l.radiance.z, 0.0f});
    }
  } else if (!g.light_table) {
    upload_if_changed(dev, g.light_table, g.light_host, {}, "shexp light lobe table (unused)");
  }
  put(dev, g.shade_lights, light_data, "shexp spherical lights");
  const std::uint32_t zero = 0;
  dev.ensure_buffer(g.shade_status, sizeof zero, kStorage, vk::MemoryKind::Host, "shexp shade status");
  dev.upload(g.shade_status, &zero, sizeof zero);
  dev.ensure_buffer(g.shade_out, count * 4 * sizeof(float), kStorage, vk::MemoryKind::Host, "shexp shading");

  vk::ComputePipeline& p = pipeline(dev, g.pipelines,
                                    "shexp.shade.n" + std::to_string(n) + ".vis" + std::to_string(vis_mode) + (lights ? ".lights" : ""),
                                    words(spv::shade_comp), {{0, static_cast<std::uint32_t>(n)}, {1, vis_mode}, {2, lights ? 1u : 0u}});
  struct Push {
    std::uint32_t count, first, end, flags, light_count, rows_theta, rows_f;
    float theta_floor;
  };
  const std::uint32_t flags = in.zero_normal_empty ? gpu::kShadeFlagZeroNormalEmpty : 0u;
  const std::uint32_t nl = lights ? static_cast<std::uint32_t>(in.lights->size()) : 0u;
  const std::uint32_t rt = lights ? static_cast<std::uint32_t>(lt->rows_theta) : 2u, rf = lights ? static_cast<std::uint32_t>(lt->rows_f) : 2u;
  const std::vector<vk::Bind> binds = {
      vk::Bind::buffer_at(gpu::kShadeBindReceivers, g.shade_rec),       vk::Bind::buffer_at(gpu::kShadeBindVis, g.shade_vis),
      vk::Bind::buffer_at(gpu::kShadeBindConsts, g.shade_consts),       vk::Bind::buffer_at(gpu::kShadeBindPrIndex, plan.pr_range),
      vk::Bind::buffer_at(gpu::kShadeBindPrTerms, plan.pr_terms),       vk::Bind::buffer_at(gpu::kShadeBindBasis, basis),
      vk::Bind::buffer_at(gpu::kShadeBindOut, g.shade_out),             vk::Bind::buffer_at(gpu::kShadeBindTapPixel, g.shade_tap_pixel),
      vk::Bind::buffer_at(gpu::kShadeBindTapIndex, g.shade_tap_index),  vk::Bind::buffer_at(gpu::kShadeBindTapWeight, g.shade_tap_weight),
      vk::Bind::buffer_at(gpu::kShadeBindLightTable, g.light_table),    vk::Bind::buffer_at(gpu::kShadeBindLights, g.shade_lights),
      vk::Bind::buffer_at(gpu::kShadeBindStatus, g.shade_status)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("shade");
    dispatch_chunks<Push>(rec, p, binds, count, gpu::kShexpShadeGroup, [&](std::uint32_t first, std::uint32_t end) {
      return Push{static_cast<std::uint32_t>(count), first, end, flags, nl, rt, rf, static_cast<float>(kLightThetaFloor)};
    });
    rec.end_timer();
    rec.barrier();
  }, "shexp shade");
  std::vector<float> rgba(count * 4);
  dev.download(g.shade_out, rgba.data(), rgba.size() * sizeof(float));
  for (std::size_t i = 0; i < count; ++i) out[i] = glm::vec3(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2]);
  std::uint32_t clamped = 0;
  dev.download(g.shade_status, &clamped, sizeof clamped);
  // Summed over the pass's shading dispatches (image_splat shades surface pixels and misses apart).
  const double secs = timer_seconds(res);
  double& total = ctx.record().counters["kernel_gpu_seconds"];
  total = secs < 0.0 ? secs : std::max(total, 0.0) + secs;
  return clamped;
}

}  // namespace softgi::techniques::shexp
