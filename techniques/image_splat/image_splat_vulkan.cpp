// image_splat's GPU passes on the Vulkan backend (paper 000, Sloan et al. 2007): accumulate_log and
// exponentiate through SHEXP's shaders (the per-tile blocker lists are shexp::BlockerLists, the log
// table a clamped shexp::ZhTable, exactly what shaders/shexp/accumulate_log.comp and
// exponentiate.comp consume). Same resources in, same structures out as the CPU passes.
#include "image_splat_vulkan.hpp"

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

#include "../shexp/shexp_passes.hpp"
#include "../shexp/shexp_vulkan_common.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "image_splat_shared.h"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/accumulate_log_comp.h"
#include "softgi/shaders/exponentiate_comp.h"
#include "softgi/shaders/upsample_apply_comp.h"
#include "softgi/shaders/upsample_weights_comp.h"
}  // namespace spv

namespace softgi::techniques::image_splat {

namespace vk = backends::vulkan;
using namespace shexp::vulkan_common;

namespace {

// image_splat's per-device state: pipelines by specialisation, tables uploaded when they change, and
// per-frame buffers reused from frame to frame (grown when a frame needs more).
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer basis;
  std::map<int, PlanBuffers> plans;             // shexp::ProductPlan per order
  std::vector<float> log_host;                   // the floats in log_table (uploaded when they change)
  vk::Buffer log_table;
  std::weak_ptr<const sh::ShTables> ol_src;      // the ShTables whose OL table is in `ol`
  vk::Buffer ol;
  std::uint32_t ol_count = 0;
  vk::Buffer receivers, rlist, ranges, blockers, weights, log_out;  // accumulate_log
  vk::Buffer exp_in, exp_out, status, series;                       // exponentiate
  vk::Buffer fdepth, fnormal, cdepth, cnormal, up_index, up_weight, up_miss, up_status;  // upsample weights
  const void* up_resident = nullptr;  // UpsampleWeights::index.data() of the weights in up_index / up_weight
  std::size_t up_pixels = 0;
  vk::Buffer ap_in, ap_out;           // upsample apply
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("image_splat.gpu", [] { return std::make_shared<GpuState>(); });
}

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  shexp::vulkan_common::check_fits(dev, bytes, what, "image_splat " + pass, "use fewer proxy spheres, a larger receiver_scale, or --backend cpu");
}

static_assert(sizeof(std::array<std::int32_t, 4>) == 16 && sizeof(std::array<float, 4>) == 16, "ivec4 / vec4 layout");

[[noreturn]] void upsample_fail(const std::string& what) { throw std::invalid_argument("upsample on vulkan: " + what); }

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

// shexp::ProductPlan in the exponentiate shader's form.
const PlanBuffers& product_plan(vk::Context& dev, GpuState& g, int order) {
  auto it = g.plans.find(order);
  if (it != g.plans.end()) return it->second;
  return g.plans.emplace(order, upload_product_plan(dev, shexp::ProductPlan::get(order), "image_splat")).first->second;
}

}  // namespace

std::shared_ptr<Field> vulkan_accumulate_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t,
                                             const ReceiverBuffer& r, const ProxyBins& bins) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const int n = t.order, n2 = n * n;
  if (t.log.order != n || n > static_cast<int>(gpu::kShexpMaxOrder))
    throw std::logic_error("image_splat accumulate_log on vulkan: log table of order " + std::to_string(t.log.order) + " for order " +
                           std::to_string(n));
  const std::size_t count = r.soa.size();
  if (count > std::numeric_limits<std::uint32_t>::max() / 8)
    throw std::invalid_argument("image_splat accumulate_log on vulkan: " + std::to_string(count) + " receivers exceed the 32-bit indexing");
  if (bins.shadow.size() != r.tiles.size())
    throw std::logic_error("image_splat accumulate_log on vulkan: " + std::to_string(bins.shadow.size()) + " blocker lists for " +
                           std::to_string(r.tiles.size()) + " tiles");
  std::size_t total = 0;
  for (const auto& l : bins.shadow) total += l.size();
  const std::string pass = "accumulate_log";
  check_fits(dev, total * 4 * sizeof(float), std::to_string(total) + " tile-proxy pairs (binned spheres)", pass);
  check_fits(dev, total * n * sizeof(float), "the band weights of " + std::to_string(total) + " binned spheres", pass);
  check_fits(dev, count * n2 * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", pass);
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", pass);

  // The tiles' blocker lists concatenated; each receiver reads the list of its tile.
  const PackedBlockers packed = pack_blocker_lists(bins.shadow, n, 0, 1.0f, "image_splat", "order");
  const std::vector<float>&sph = packed.sph, &w = packed.w;
  const std::vector<std::uint32_t>& ranges = packed.ranges;
  std::vector<std::uint32_t> rlist(count, 0);
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    for (std::size_t i = r.tiles[k].begin; i < r.tiles[k].end; ++i) rlist[i] = static_cast<std::uint32_t>(k);

  const vk::Buffer& table = log_table(dev, g, t);
  if (!g.basis) g.basis = dev.upload_vector(shexp::basis_recurrence_constants(), kStorage, "image_splat basis constants");
  upload_receivers(dev, g.receivers, r.soa, "image_splat receivers");
  put(dev, g.rlist, rlist, "image_splat receiver tiles");
  put(dev, g.ranges, ranges, "image_splat tile list ranges");
  put(dev, g.blockers, sph, "image_splat binned spheres");
  put(dev, g.weights, w, "image_splat band weights");
  dev.ensure_buffer(g.log_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Host,
                    "image_splat log occlusion");

  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "image_splat.accumulate_log.n" + std::to_string(n) + ".rule" + std::to_string(static_cast<int>(s.rule)),
                                    words(spv::accumulate_log_comp),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(s.rule)}});
  vk::SubmitResult res;
  if (count)
    res = run_accumulate_log(dev, p, {g.receivers, g.rlist, g.ranges, g.blockers, g.weights, table, g.basis, g.log_out}, count, t.log,
                             "image_splat accumulate_log", pair_cut_factor(t, s.rule));

  auto f = std::make_shared<Field>();
  f->channels = n2;
  f->v.resize(count * n2);
  if (count) dev.download(g.log_out, f->v.data(), f->v.size() * sizeof(float));
  double pairs = 0.0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    pairs += static_cast<double>(r.tiles[k].end - r.tiles[k].begin) * static_cast<double>(bins.shadow[k].size());
  const double secs = timer_seconds(res);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["pairs"] = pairs;
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["kernel_gpu_seconds"] = secs;
  rec.counters["hard_cut"] = t.hard_cut;
  rec.counters["pair_cut"] = pair_cut_factor(t, s.rule) > 0.0f;
  rec.counters["upload_bytes"] = static_cast<double>((sph.size() + w.size() + 6 * count) * sizeof(float) + (rlist.size() + ranges.size()) * 4);
  rec.bytes = f->v.size() * sizeof(float);
  return f;
}

bool vulkan_exp_supports(ExpMode m) { return m == ExpMode::HYB || m == ExpMode::OL || m == ExpMode::PSStar || m == ExpMode::PS; }

std::shared_ptr<Field> vulkan_exponentiate(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const Field& log) {
  if (!vulkan_exp_supports(s.exp)) throw std::logic_error("image_splat exponentiate on vulkan: HYB, OL, PS* and PS only");
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const int n = t.order, n2 = n * n;
  if (log.channels != n2)
    throw std::logic_error("image_splat exponentiate on vulkan: " + std::to_string(log.channels) + " log channels for order " + std::to_string(n));
  const std::size_t count = log.v.size() / n2;
  check_fits(dev, count * n2 * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers", "exponentiate");

  ol_table(dev, g, t.sh);
  const PlanBuffers& plan = product_plan(dev, g, n);
  put(dev, g.exp_in, log.v, "image_splat exp input");
  dev.ensure_buffer(g.exp_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Host, "image_splat occlusion");
  reset_exp_status(dev, g.status, "image_splat exp status");

  const std::uint32_t method = s.exp == ExpMode::HYB ? gpu::kExpHyb : s.exp == ExpMode::OL ? gpu::kExpOl : s.exp == ExpMode::PSStar ? gpu::kExpPsStar : gpu::kExpPs;
  put(dev, g.series, exp_series(method, s.ps_degree), "image_splat exp series");
  // Accumulation order = shading order: the log vector is exponentiated at the shadow order n.
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "image_splat.exponentiate.n" + std::to_string(n) + ".m" + std::to_string(method),
                                    words(spv::exponentiate_comp),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(n)}, {2, method}});
  vk::SubmitResult res;
  if (count)
    res = run_exponentiate(dev, p, {g.exp_in, g.exp_out, g.ol, plan, g.series, g.status}, count, g.ol_count, s.ps_degree,
                           "image_splat exponentiate");

  std::uint32_t status[gpu::kExpStatusWords];
  dev.download(g.status, status, sizeof status);
  throw_exp_errors(status, log.v.data(), n2, "image_splat exponentiate on vulkan", [](std::size_t i) { return "receiver " + std::to_string(i); });

  auto out = std::make_shared<Field>();
  out->channels = n2;
  out->v.resize(count * n2);
  if (count) dev.download(g.exp_out, out->v.data(), out->v.size() * sizeof(float));
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["squarings"] = status[gpu::kExpStatusSquarings];
  rec.counters["kernel_gpu_seconds"] = timer_seconds(res);
  rec.bytes = out->v.size() * sizeof(float);
  return out;
}

UpsampleWeights vulkan_upsample_weights(render::FrameContext& ctx, const PlaneView& coarse, const PlaneView& fine,
                                        const UpsampleOptions& opt, std::vector<float>* measure) {
  check_upsample_input(coarse, fine, opt);
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const std::size_t nf = static_cast<std::size_t>(fine.width) * fine.height, nc = static_cast<std::size_t>(coarse.width) * coarse.height;
  check_fits(dev, nf * 16, "the eq. 11 weights of " + std::to_string(nf) + " display pixels", "upsample");
  check_fits(dev, nf * 12, "the normals of " + std::to_string(nf) + " display pixels", "upsample");
  const auto up = [&](vk::Buffer& b, const void* src, std::size_t bytes, const char* name) {
    dev.ensure_buffer(b, bytes, kStorage, vk::MemoryKind::Device, name);
    dev.upload(b, src, bytes);
  };
  up(g.fdepth, fine.depth, nf * sizeof(float), "image_splat display depth");
  up(g.fnormal, fine.normal, nf * sizeof(glm::vec3), "image_splat display normals");
  up(g.cdepth, coarse.depth, nc * sizeof(float), "image_splat receiver depth");
  up(g.cnormal, coarse.normal, nc * sizeof(glm::vec3), "image_splat receiver normals");
  dev.ensure_buffer(g.up_index, nf * 16, kStorage, vk::MemoryKind::Host, "image_splat upsample taps");
  dev.ensure_buffer(g.up_weight, nf * 16, kStorage, vk::MemoryKind::Host, "image_splat upsample weights");
  dev.ensure_buffer(g.up_miss, nf * 8, kStorage, vk::MemoryKind::Host, "image_splat upsample misses");
  const std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  const std::uint32_t status0[gpu::kUpStatusWords] = {none, none};
  dev.ensure_buffer(g.up_status, sizeof status0, kStorage, vk::MemoryKind::Host, "image_splat upsample status");
  dev.upload(g.up_status, status0, sizeof status0);
  g.up_resident = nullptr;

  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "image_splat.upsample_weights", words(spv::upsample_weights_comp), {});
  struct Push {
    std::int32_t fw, fh, fscale, cw, ch, cscale;
    float epsilon_rel;
    std::int32_t normal_power;
    float miss_threshold;
    std::uint32_t mode;
  };
  const Push push{fine.width,
                  fine.height,
                  fine.scale,
                  coarse.width,
                  coarse.height,
                  coarse.scale,
                  static_cast<float>(opt.epsilon_rel),
                  opt.normal_power,
                  static_cast<float>(opt.miss_threshold),
                  opt.mode == UpsampleMode::Bilateral ? gpu::kUpsampleBilateral : gpu::kUpsampleBilinear};
  const std::vector<vk::Bind> binds = {
      vk::Bind::buffer_at(gpu::kUpBindFineDepth, g.fdepth),     vk::Bind::buffer_at(gpu::kUpBindFineNormal, g.fnormal),
      vk::Bind::buffer_at(gpu::kUpBindCoarseDepth, g.cdepth),   vk::Bind::buffer_at(gpu::kUpBindCoarseNormal, g.cnormal),
      vk::Bind::buffer_at(gpu::kUpBindIndex, g.up_index),       vk::Bind::buffer_at(gpu::kUpBindWeight, g.up_weight),
      vk::Bind::buffer_at(gpu::kUpBindMiss, g.up_miss),         vk::Bind::buffer_at(gpu::kUpBindStatus, g.up_status)};
  // The coarse buffer is checked by the invocations of its own extent: cover the larger of both.
  const int gw = std::max(fine.width, coarse.width), gh = std::max(fine.height, coarse.height);
  const auto& lim = dev.device_info().limits.maxComputeWorkGroupCount;
  const std::uint32_t gx = (static_cast<std::uint32_t>(gw) + gpu::kUpsampleGroupX - 1) / gpu::kUpsampleGroupX;
  const std::uint32_t gy = (static_cast<std::uint32_t>(gh) + gpu::kUpsampleGroupY - 1) / gpu::kUpsampleGroupY;
  if (gx > lim[0] || gy > lim[1])
    upsample_fail("display buffer " + dims(fine) + " needs more workgroups than device '" + dev.device_info().name + "' allows");
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("upsample_weights");
    rec.dispatch(p, binds, push, gx, gy);
    rec.end_timer();
    rec.barrier();
  }, "image_splat upsample weights");

  std::uint32_t status[gpu::kUpStatusWords];
  dev.download(g.up_status, status, sizeof status);
  // upsample.cpp's per-pixel errors, naming the pixel (the coarse buffer is checked first there).
  for (const auto& [word, v, name] : {std::tuple<std::uint32_t, const PlaneView&, const char*>{status[gpu::kUpStatusBadCoarse], coarse, "coarse"},
                                      {status[gpu::kUpStatusBadFine], fine, "fine"}}) {
    if (word == none) continue;
    const std::size_t i = word - 1;
    const int x = static_cast<int>(i % v.width), y = static_cast<int>(i / v.width);
    const float z = v.depth[i];
    const bool background = std::isinf(z) && z > 0.0f;
    if (!background && !(std::isfinite(z) && z > 0.0f))
      upsample_fail(std::string(name) + " depth at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is " + std::to_string(z) +
                    "; expected a positive eye-space depth or +inf for background");
    upsample_fail(std::string(name) + " normal at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is not finite");
  }
  UpsampleWeights w;
  w.width = fine.width;
  w.height = fine.height;
  w.index.resize(nf);
  w.weight.resize(nf);
  w.miss.resize(nf);
  dev.download(g.up_index, w.index.data(), nf * 16);
  dev.download(g.up_weight, w.weight.data(), nf * 16);
  std::vector<std::uint32_t> mm(2 * nf);
  dev.download(g.up_miss, mm.data(), nf * 8);
  if (measure) measure->resize(nf);
  for (std::size_t i = 0; i < nf; ++i) {
    w.miss[i] = mm[2 * i] ? 1 : 0;
    w.misses += w.miss[i];
    if (measure) std::memcpy(&(*measure)[i], &mm[2 * i + 1], sizeof(float));
  }
  g.up_resident = w.index.data();
  g.up_pixels = nf;
  ctx.record().counters["weights_gpu_seconds"] = timer_seconds(res);
  return w;
}

void vulkan_upsample_apply(render::FrameContext& ctx, const UpsampleWeights& w, const float* in, int channels, float* out) {
  if (!in || !out) upsample_fail("input or output pointer is null");
  if (channels < 1 || channels > 64) upsample_fail("channels = " + std::to_string(channels) + " (expected 1..64)");
  const std::size_t nf = static_cast<std::size_t>(std::max(w.width, 0)) * static_cast<std::size_t>(std::max(w.height, 0));
  if (w.width <= 0 || w.height <= 0 || w.index.size() != nf || w.weight.size() != nf)
    upsample_fail("weights of " + std::to_string(w.width) + "x" + std::to_string(w.height) + " pixels have inconsistent array sizes");
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  // The coarse buffer's size: one past the largest tap.
  std::int32_t top = -1;
  for (const auto& idx : w.index) top = std::max({top, idx[0], idx[1], idx[2], idx[3]});
  const std::size_t nc = static_cast<std::size_t>(top + 1), ch = static_cast<std::size_t>(channels);
  check_fits(dev, nf * ch * sizeof(float), std::to_string(channels) + " channels of " + std::to_string(nf) + " display pixels", "upsample");
  if (g.up_resident != w.index.data() || g.up_pixels != nf) {  // not the weights on the device: upload them
    dev.ensure_buffer(g.up_index, nf * 16, kStorage, vk::MemoryKind::Host, "image_splat upsample taps");
    dev.ensure_buffer(g.up_weight, nf * 16, kStorage, vk::MemoryKind::Host, "image_splat upsample weights");
    dev.upload(g.up_index, w.index.data(), nf * 16);
    dev.upload(g.up_weight, w.weight.data(), nf * 16);
    g.up_resident = w.index.data();
    g.up_pixels = nf;
  }
  dev.ensure_buffer(g.ap_in, std::max<std::size_t>(1, nc * ch) * sizeof(float), kStorage, vk::MemoryKind::Device, "image_splat upsample input");
  if (nc) dev.upload(g.ap_in, in, nc * ch * sizeof(float));
  dev.ensure_buffer(g.ap_out, nf * ch * sizeof(float), kStorage, vk::MemoryKind::Host, "image_splat upsample output");
  dev.upload(g.ap_out, out, nf * ch * sizeof(float));  // pixels without a tap keep their value
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "image_splat.upsample_apply.c" + std::to_string(channels), words(spv::upsample_apply_comp),
                                    {{0, static_cast<std::uint32_t>(channels)}});
  struct Push {
    std::uint32_t first, end;
  };
  const std::vector<vk::Bind> binds = {vk::Bind::buffer_at(gpu::kApBindIndex, g.up_index), vk::Bind::buffer_at(gpu::kApBindWeight, g.up_weight),
                                       vk::Bind::buffer_at(gpu::kApBindIn, g.ap_in), vk::Bind::buffer_at(gpu::kApBindOut, g.ap_out)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("upsample_apply");
    dispatch_chunks<Push>(rec, p, binds, nf, gpu::kUpsampleGroupX * gpu::kUpsampleGroupY,
                          [&](std::uint32_t first, std::uint32_t end) { return Push{first, end}; });
    rec.end_timer();
    rec.barrier();
  }, "image_splat upsample apply");
  dev.download(g.ap_out, out, nf * ch * sizeof(float));
  ctx.record().counters["apply_gpu_seconds"] = timer_seconds(res);
}

DirectKernels vulkan_direct_kernels(render::FrameContext& ctx) {
  render::FrameContext* c = &ctx;
  DirectKernels k;
  k.surface = [c](const DirectShader& d, const render::GBuffer& fine, const Upsampled& up, glm::vec3* out) -> long long {
    const std::size_t ns = up.surface.size();
    if (ns == 0) return 0;
    shexp::ReceiverSoA soa;
    soa.resize(ns);
    for (std::size_t i = 0; i < ns; ++i) {
      const std::size_t p = static_cast<std::size_t>(up.surface[i]);
      soa.set(i, fine.position[p], fine.normal[p]);
    }
    const shexp::BatchShade bs = d.batch(nullptr);
    const std::size_t n2 = static_cast<std::size_t>(d.order) * d.order;
    shexp::GpuShade in{&bs, d.lights_table.get(), &d.lights, true, nullptr};
    shexp::GpuShade::Gather ga;
    if (!up.coarse_visibility.empty()) {  // section 4.2: O_p interpolated on the device
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
    return shexp::vulkan_shade(*c, in, soa, out);
  };
  k.receivers = [c](const DirectShader& d, const shexp::ReceiverSoA& rec, const float* g, glm::vec3* out) -> long long {
    const shexp::BatchShade bs = d.batch(g);
    return shexp::vulkan_shade(*c, shexp::GpuShade{&bs, d.lights_table.get(), &d.lights, true, nullptr}, rec, out);
  };
  return k;
}

UpsampleKernels cpu_upsample_kernels() { return {upsample_weights, upsample_apply}; }

UpsampleKernels vulkan_upsample_kernels(render::FrameContext& ctx) {
  render::FrameContext* c = &ctx;
  return {[c](const PlaneView& coarse, const PlaneView& fine, const UpsampleOptions& opt) { return vulkan_upsample_weights(*c, coarse, fine, opt); },
          [c](const UpsampleWeights& w, const float* in, int channels, float* out) { vulkan_upsample_apply(*c, w, in, channels, out); }};
}

}  // namespace softgi::techniques::image_splat
