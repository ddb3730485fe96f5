// Spherical lights' GPU passes on the Vulkan backend (paper 001): the blocker accumulation and the
// exponential of both stages (the SLs' sample points, section 5.1, and the vertices, section 6) on
// the shared accumulate_log.comp / exponentiate.comp, the diffuse shading on common::vulkan_shade,
// the intensity update (section 5.2, eqs. 10-11: shaders/spherical_lights/intensity.comp) and the
// receiver accumulation (section 6, eqs. 13-24: shaders/spherical_lights/accumulate_indirect.comp).
// They read and write the same frame resources as the host passes (spherical_lights.cpp), so the
// backends can be compared pass by pass; the log vectors, visibilities and intensities stay on the
// device for the next GPU pass. Tables, product plans and basis constants are the CPU's own floats,
// uploaded once per device (the tables again when they change); per-frame inputs are uploaded only
// when their content changed.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "sl_passes.hpp"
#include "../common/accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/sh/sh.hpp"
#include "sl_shared.h"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/common/accumulate_log_comp.h"
#include "softgi/shaders/common/exponentiate_comp.h"
#include "softgi/shaders/spherical_lights/accumulate_indirect_comp.h"
#include "softgi/shaders/spherical_lights/intensity_comp.h"
}  // namespace spv

namespace softgi::techniques::spherical_lights {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

namespace {

constexpr double kHalfPi = 0.5 * sh::kPi;

// Per stage: the accumulation inputs (uploaded when they change), the log vectors and the visibility.
struct StageBuffers {
  AccumulationInputs inputs;
  vk::Buffer log, exp_in, vis;
};

// Spherical lights' per-device state: pipelines by specialisation, the tables of the frame's Tables
// object, and per-frame buffers reused from frame to frame (grown when a frame needs more).
struct GpuState {
  std::mutex m;
  PipelineCache pipelines;
  std::weak_ptr<const Tables> table_src;  // the Tables whose log, OL and w_theta tables are uploaded
  vk::Buffer log_table, weight_table, ol;
  std::uint32_t ol_count = 0;
  StageBuffers stage[2];
  vk::Buffer exp_status, series;
  // intensity_update
  vk::Buffer radiance, ranges, basis, albedo, intensity;
  std::uint64_t radiance_hash = 0, ranges_hash = 0, basis_hash = 0, albedo_hash = 0;
  // accumulate_indirect
  vk::Buffer spheres, rotation, object, object_centre, inter_begin, inter_list, consts, intensity_in, ind_out, ind_status, ind_state;
  vk::Buffer entry_sl, ratio, rlist, list_range;
  std::uint64_t entry_sl_hash = 0, ratio_hash = 0, rlist_hash = 0, list_range_hash = 0;
  std::uint64_t spheres_hash = 0, rotation_hash = 0, object_hash = 0, object_centre_hash = 0, inter_begin_hash = 0,
                inter_list_hash = 0, consts_hash = 0, intensity_in_hash = 0;
};

GpuState& gpu_state(vk::Context& dev) {
  return *dev.cached<GpuState>("spherical_lights.gpu", [] { return std::make_shared<GpuState>(); });
}

StageBuffers& stage_buffers(GpuState& g, Stage stage) { return g.stage[stage == Stage::Samples ? 0 : 1]; }
const char* stage_name(Stage stage) { return stage == Stage::Samples ? "sample points" : "receivers"; }

// The receivers of a stage, as the host passes read them (spherical_lights.cpp stage_receivers).
const ReceiverSoA& stage_receivers(render::FrameContext& ctx, Stage stage) {
  if (stage == Stage::Samples) return ctx.get<std::shared_ptr<const SlPose>>(kSlPose)->samples;
  return ctx.get<std::shared_ptr<const Receivers>>(kReceivers)->soa;
}

void upload_tables(vk::Context& dev, GpuState& g, const std::shared_ptr<const Tables>& t) {
  if (!g.table_src.expired() && g.table_src.lock() == t) return;
  g.log_table = dev.upload_vector(t->log.data, kStorage, "spherical_lights log ZH table");
  g.weight_table = dev.upload_vector(t->weight.w, kStorage, "spherical_lights w_theta table");
  OlTable ol = upload_ol_table(dev, *t->sh, "spherical_lights");
  g.ol = std::move(ol.buffer);
  g.ol_count = ol.count;
  g.table_src = t;
}

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass) {
  gpu_passes::check_fits(dev, bytes, what, "spherical_lights " + pass, "use fewer proxy spheres or receivers, or --backend cpu");
}

std::uint32_t exp_method(const Settings& s) {
  if (s.exp == sh::ExpMethod::HYB) return gpu::kExpHyb;
  if (s.exp == sh::ExpMethod::OL) return gpu::kExpOl;
  throw std::logic_error("spherical_lights vulkan: the exponentials support HYB and OL only");
}

void check_count(std::size_t count, const std::string& what, const std::string& pass) {
  if (count > std::numeric_limits<std::uint32_t>::max() / 8)
    throw std::invalid_argument("spherical_lights " + pass + " on vulkan: " + std::to_string(count) + " " + what +
                                " exceed the 32-bit indexing");
}

// Paper 001 eqs. 6-7 (paper 004 eq. 34 with the rules of section 6.2): every SL as a blocker of the
// stage's receivers, one flat list.
void vulkan_accumulate(const Settings& s, render::FrameContext& ctx, Stage stage) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto tp = ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const ReceiverSoA& rec = stage_receivers(ctx, stage);
  StageBuffers& sb = stage_buffers(g, stage);
  const int n = s.order, n2 = n * n;
  const std::size_t count = rec.size(), nb = pose.blockers.size();
  const std::string pass = std::string("accumulate_log (") + stage_name(stage) + ")";
  check_count(count, stage_name(stage), pass);
  check_fits(dev, nb * 4 * sizeof(float), std::to_string(nb) + " SL blocker spheres", pass);
  check_fits(dev, count * n2 * sizeof(float), "the log vectors of " + std::to_string(count) + " " + stage_name(stage), pass);
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " " + stage_name(stage), pass);

  // Every receiver reads the one list of every leaf, or (section 7.3) its cluster's cut: a vertex
  // its Lloyd cluster's, a sample point its object's.
  const char* cut_resource = stage == Stage::Samples ? kSampleShadowCuts : kShadowCuts;
  std::shared_ptr<const ClusterCuts> cuts;
  if (ctx.has(cut_resource)) cuts = ctx.get<std::shared_ptr<const ClusterCuts>>(cut_resource);
  std::vector<std::uint32_t> rlist(std::max<std::size_t>(1, count), 0u);
  double pairs = static_cast<double>(count) * static_cast<double>(nb);
  if (cuts) {
    pairs = 0.0;
    auto assign = [&](std::size_t begin, std::size_t end, int cluster) {
      const int l = cuts->list_of_cluster[static_cast<std::size_t>(cluster)];
      for (std::size_t i = begin; i < end; ++i) rlist[i] = static_cast<std::uint32_t>(l);
      pairs += static_cast<double>(end - begin) * static_cast<double>(cuts->lists[static_cast<std::size_t>(l)].size());
    };
    if (stage == Stage::Samples) {
      for (std::size_t i = 0; i < pose.size(); ++i) assign(pose.sample_begin[i], pose.sample_begin[i + 1], pose.object[i]);
    } else {
      const auto& receivers = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
      for (std::size_t c = 0; c < receivers.clusters.size(); ++c)
        assign(receivers.clusters[c].begin, receivers.clusters[c].end, static_cast<int>(c));
    }
  }
  const PackedBlockers packed = cuts ? pack_blocker_lists(cuts->lists, n, 1, 1.0f, "spherical_lights", "order")
                                     : pack_blocker_lists({pose.blockers}, n, 1, 1.0f, "spherical_lights", "order");
  upload_tables(dev, g, tp);
  const vk::Buffer& basis = basis_constants(dev);
  const std::size_t uploaded = sb.inputs.upload(dev, rec, rlist, packed, std::string("spherical_lights ") + stage_name(stage));
  dev.ensure_buffer(sb.log, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "spherical_lights log vectors");
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "sl.accumulate_log.n" + std::to_string(n) + ".rule" + std::to_string(static_cast<int>(s.rule)),
                                    words(spv::common_accumulate_log_comp),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(s.rule)}});
  std::uint32_t chunks = 1;
  const vk::SubmitResult res = run_accumulate_log(
      dev, p, {sb.inputs.receivers, sb.inputs.rlist, sb.inputs.ranges, sb.inputs.blockers, sb.inputs.weights, g.log_table, basis, sb.log},
      count, tp->log, sb.inputs.longest, "spherical_lights accumulate_log", 0.0f, &chunks);

  auto& r = ctx.record();
  const double secs = timer_seconds(res);
  r.counters["receivers"] = static_cast<double>(count);
  r.counters["blockers"] = static_cast<double>(nb);
  r.counters["blocker_chunks"] = chunks;
  r.counters["pairs"] = pairs;
  r.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  r.counters["kernel_gpu_seconds"] = secs;
  r.counters["upload_bytes"] = static_cast<double>(uploaded);
  r.bytes = count * n2 * sizeof(float);
  put_device_field<Field>(ctx, log_resource(stage), DeviceField{&sb.log, count * n2, n}, g.m, dev);
}

// The SH exponential of the summed logs (paper 004 section 4), HYB or OL.
void vulkan_exponentiate(const Settings& s, render::FrameContext& ctx, Stage stage) {
  const std::uint32_t method = exp_method(s);
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto tp = ctx.get<std::shared_ptr<const Tables>>(kTables);
  StageBuffers& sb = stage_buffers(g, stage);
  const DeviceField* dlog = device_field(ctx, log_resource(stage));
  std::shared_ptr<const Field> hlog;
  if (!dlog) hlog = ctx.get<std::shared_ptr<const Field>>(log_resource(stage));
  const int n = s.order, n2 = n * n;
  const int order = dlog ? dlog->order : hlog->order;
  if (order != n)
    throw std::logic_error("spherical_lights exponentiate on vulkan: log vectors of order " + std::to_string(order) + " for order " +
                           std::to_string(n));
  const std::size_t floats = dlog ? dlog->floats : hlog->v.size(), count = floats / n2;
  const std::string pass = std::string("exponentiate (") + stage_name(stage) + ")";
  check_count(count, stage_name(stage), pass);
  check_fits(dev, floats * sizeof(float), "the log vectors of " + std::to_string(count) + " " + stage_name(stage), pass);

  upload_tables(dev, g, tp);
  if (!dlog) {
    dev.ensure_buffer(sb.exp_in, std::max<std::size_t>(1, floats) * sizeof(float), kStorage, vk::MemoryKind::Device,
                      "spherical_lights exp input");
    if (floats) dev.upload(sb.exp_in, hlog->v.data(), floats * sizeof(float));
  }
  const vk::Buffer& in = dlog ? *dlog->buffer : sb.exp_in;
  dev.ensure_buffer(sb.vis, std::max<std::size_t>(1, floats) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "spherical_lights visibility");
  reset_exp_status(dev, g.exp_status, "spherical_lights exp status");
  if (!g.series) put(dev, g.series, exp_series(gpu::kExpPsStar, 2), "spherical_lights exp series (unused)");
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "sl.exponentiate.n" + std::to_string(n) + ".m" + std::to_string(method),
                                    order_variant(spv::common_exponentiate_comp_for(n), n, "spherical_lights exponentiate"),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(n)}, {2, method}});
  const vk::SubmitResult res = run_exponentiate(dev, p, {in, sb.vis, g.ol, g.series, g.exp_status}, count, g.ol_count, 2,
                                                "spherical_lights exponentiate");
  std::uint32_t status[gpu::kExpStatusWords];
  dev.download(g.exp_status, status, sizeof status);
  if (exp_status_failed(status)) {
    std::vector<float> log(floats);
    if (dlog) dev.download(*dlog->buffer, log.data(), log.size() * sizeof(float));
    else log = hlog->v;
    throw_exp_errors(status, log.data(), n2, std::string("spherical_lights exponentiate (") + stage_name(stage) + ")",
                     [&](std::size_t i) { return std::string(stage == Stage::Samples ? "sample point " : "receiver ") + std::to_string(i); });
  }
  auto& r = ctx.record();
  r.counters["receivers"] = static_cast<double>(count);
  r.counters["squarings"] = status[gpu::kExpStatusSquarings];
  r.counters["kernel_gpu_seconds"] = timer_seconds(res);
  r.bytes = floats * sizeof(float);
  put_device_field<Field>(ctx, visibility_resource(stage), DeviceField{&sb.vis, floats, n}, g.m, dev);
}

// Section 5.2: L_S = sum_k L_pk Y_k (eq. 10), L^c_S = L_S * c_S (eq. 11), per SL and channel.
void vulkan_intensity(const Settings& s, render::FrameContext& ctx) {
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const auto& lp = *ctx.get<std::shared_ptr<const Shading>>(kSampleRadiance);
  const int n = s.order, n2 = n * n;
  const std::size_t m = pose.size(), samples = pose.samples.size();
  if (lp.value.size() != samples || pose.sample_begin.size() != m + 1 || pose.basis.size() != samples || pose.albedo.size() != m)
    throw std::logic_error("spherical_lights intensity_update on vulkan: the sample radiance does not match the " + std::to_string(samples) +
                           " sample points of " + std::to_string(m) + " SLs");
  check_count(3 * m, "SL channels", "intensity_update");
  check_fits(dev, samples * n2 * sizeof(float), "the projection sums of " + std::to_string(samples) + " sample points", "intensity_update");
  check_fits(dev, m * 3 * n2 * sizeof(float), "the albedo and intensity of " + std::to_string(m) + " SLs", "intensity_update");

  // The per-object precomputation (sample ranges, basis sums, albedo) changes only with the scene:
  // uploaded when its content hash changes; the sample radiance when it does.
  std::vector<std::uint32_t> ranges(pose.sample_begin.begin(), pose.sample_begin.end());
  std::vector<float> basis(samples * n2), albedo(m * 3 * n2);
  for (std::size_t k = 0; k < samples; ++k) std::copy(pose.basis[k], pose.basis[k] + n2, basis.begin() + k * n2);
  for (std::size_t i = 0; i < m; ++i) std::copy(pose.albedo[i], pose.albedo[i] + 3 * n2, albedo.begin() + i * 3 * n2);
  const std::size_t before = dev.transfer_bytes().upload;
  put_if_changed(dev, g.ranges, g.ranges_hash, ranges, "spherical_lights sample ranges");
  put_if_changed(dev, g.basis, g.basis_hash, basis, "spherical_lights projection sums");
  put_if_changed(dev, g.albedo, g.albedo_hash, albedo, "spherical_lights albedo SH");
  upload_bytes_if_changed(dev, g.radiance, g.radiance_hash, lp.value.data(), samples * sizeof(glm::vec3), "spherical_lights sample radiance");
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  dev.ensure_buffer(g.intensity, std::max<std::size_t>(1, m * 3 * n2) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "spherical_lights intensity");
  vk::ComputePipeline& p = pipeline(dev, g.pipelines, "sl.intensity.n" + std::to_string(n), order_variant(spv::spherical_lights_intensity_comp_for(n), n, "spherical_lights intensity"),
                                    {{0, static_cast<std::uint32_t>(n)}});
  struct Push {
    std::uint32_t first, end;
  };
  const std::vector<vk::Bind> binds = {
      vk::Bind::buffer_at(gpu::kSlIntBindRadiance, g.radiance),  vk::Bind::buffer_at(gpu::kSlIntBindRanges, g.ranges),
      vk::Bind::buffer_at(gpu::kSlIntBindBasis, g.basis),        vk::Bind::buffer_at(gpu::kSlIntBindAlbedo, g.albedo),
      vk::Bind::buffer_at(gpu::kSlIntBindOut, g.intensity)};
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("intensity_update");
    dispatch_chunks<Push>(rec, p, binds, 3 * m, gpu::kSlIntensityGroup, [](std::uint32_t first, std::uint32_t end) { return Push{first, end}; });
    rec.end_timer();
    rec.barrier();
  }, "spherical_lights intensity_update");
  auto& r = ctx.record();
  r.counters["sls"] = static_cast<double>(m);
  r.counters["sample_points"] = static_cast<double>(samples);
  r.counters["kernel_gpu_seconds"] = timer_seconds(res);
  r.counters["upload_bytes"] = static_cast<double>(uploaded);
  r.bytes = m * 3 * n2 * sizeof(float);
  // On the device for accumulate_indirect; the host copy is read back only if a host pass asks.
  put_device_field<Intensity>(ctx, kIntensity, DeviceField{&g.intensity, m * 3 * n2, n}, g.m, dev);
}

// Section 6: per receiver, sum over the SLs of Lbar_i Vbar_i (eqs. 13-24) in the blocking order of
// section 7.2.
void vulkan_indirect(const Settings& s, render::FrameContext& ctx) {
  const std::uint32_t method = exp_method(s);
  vk::Context& dev = vk::context_of(ctx);
  GpuState& g = gpu_state(dev);
  std::lock_guard<std::mutex> lock(g.m);
  const auto tp = ctx.get<std::shared_ptr<const Tables>>(kTables);
  const Tables& t = *tp;
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& cuts = *ctx.get<std::shared_ptr<const SlCuts>>(kSlCuts);
  const int n = s.order, n2 = n * n;
  const std::size_t m = pose.size(), count = r.soa.size(), objects = pose.object_centre.size();
  std::size_t entries = 0, longest = 0;
  for (const auto& l : cuts.lists) {
    entries += l.sl.size();
    longest = std::max(longest, l.sl.size());
  }
  if (longest > gpu::kSlMaxLights)
    throw std::invalid_argument("spherical_lights accumulate_indirect on vulkan: a receiver cluster sums " + std::to_string(longest) +
                                " spherical lights, above the shader's bound of " + std::to_string(gpu::kSlMaxLights) +
                                " (use the hierarchy, fewer proxy spheres, or --backend cpu)");
  if (t.log.order != n || t.weight.order != n || t.weight.rows < 2 || t.log.rows < 2)
    throw std::logic_error("spherical_lights accumulate_indirect on vulkan: tables of another order");
  check_count(count, "receivers", "accumulate_indirect");
  check_fits(dev, count * 6 * sizeof(float), "the positions and normals of " + std::to_string(count) + " receivers", "accumulate_indirect");
  check_fits(dev, count * 4 * sizeof(float), "the indirect shading of " + std::to_string(count) + " receivers", "accumulate_indirect");
  check_fits(dev, m * 3 * n2 * sizeof(float), "the intensities of " + std::to_string(m) + " SLs", "accumulate_indirect");
  check_fits(dev, entries * 12 * sizeof(float), "the rotations of " + std::to_string(entries) + " SLs in the cluster lists", "accumulate_indirect");

  // The intensities where intensity_update left them on the device, else uploaded from the host.
  const DeviceField* dlc = device_field(ctx, kIntensity);
  std::shared_ptr<const Intensity> hlc;
  if (!dlc) hlc = ctx.get<std::shared_ptr<const Intensity>>(kIntensity);
  const std::size_t lc_floats = dlc ? dlc->floats : hlc->v.size();
  if (lc_floats != m * 3 * n2 || (dlc ? dlc->order : hlc->order) != n)
    throw std::logic_error("spherical_lights accumulate_indirect on vulkan: the intensities do not match the " + std::to_string(m) + " SLs");

  // The cluster lists' entries (section 7.3), concatenated: spheres, rotations, objects, SLs, ratios
  // and the intersecting entries as CSR arrays; per receiver its cluster's list.
  const std::size_t rows = std::max<std::size_t>(1, entries);
  std::vector<float> spheres(rows * 4, 0.0f), rotation(rows * 12, 0.0f), ratio(rows * 4, 1.0f),
      centres(std::max<std::size_t>(1, objects) * 4, 0.0f);
  std::vector<std::uint32_t> object(rows, 0u), entry_sl(rows, 0u), inter_begin(entries + 1, 0u), inter_list;
  std::vector<std::uint32_t> list_range(2 * std::max<std::size_t>(1, cuts.lists.size()), 0u);
  std::size_t e = 0;
  for (std::size_t li = 0; li < cuts.lists.size(); ++li) {
    const SlList& l = cuts.lists[li];
    const std::size_t begin = e;
    list_range[2 * li] = static_cast<std::uint32_t>(begin);
    list_range[2 * li + 1] = static_cast<std::uint32_t>(l.sl.size());
    for (std::size_t a = 0; a < l.sl.size(); ++a, ++e) {
      const int i = l.sl[a];
      spheres[4 * e] = pose.centre[i].x;
      spheres[4 * e + 1] = pose.centre[i].y;
      spheres[4 * e + 2] = pose.centre[i].z;
      spheres[4 * e + 3] = pose.radius[i];
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) rotation[12 * e + 4 * c + k] = pose.rotation[i][c][k];
      object[e] = static_cast<std::uint32_t>(pose.object[i]);
      entry_sl[e] = static_cast<std::uint32_t>(i);
      if (!l.ratio.empty())
        for (int c = 0; c < 3; ++c) ratio[4 * e + c] = l.ratio[a][c];
      for (int j : l.intersecting[a]) inter_list.push_back(static_cast<std::uint32_t>(begin + j));
      inter_begin[e + 1] = static_cast<std::uint32_t>(inter_list.size());
    }
  }
  std::vector<std::uint32_t> rlist(std::max<std::size_t>(1, count), 0u);
  for (std::size_t c = 0; c < r.clusters.size(); ++c)
    for (std::size_t i = r.clusters[c].begin; i < r.clusters[c].end; ++i) rlist[i] = static_cast<std::uint32_t>(cuts.list_of_cluster[c]);
  if (inter_list.empty()) inter_list.push_back(0u);
  for (std::size_t o = 0; o < objects; ++o)
    for (int k = 0; k < 3; ++k) centres[4 * o + k] = pose.object_centre[o][k];
  // H(N) band factors (clamped cosine / pi with the rotation factor) and the ZH rotation factors.
  std::vector<float> consts(2 * static_cast<std::size_t>(n));
  const std::vector<double> cc = sh::clamped_cosine_zh(n);
  for (int l = 0; l < n; ++l) {
    consts[l] = static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / sh::kPi);
    consts[n + l] = static_cast<float>(sh::zh_rotation_factor(l));
  }

  upload_tables(dev, g, tp);
  const vk::Buffer& basis = basis_constants(dev);
  const std::size_t before = dev.transfer_bytes().upload;
  // The vertex receivers are accumulate_log's: the same buffer and hash, so that a frame uploads them once.
  StageBuffers& rb = stage_buffers(g, Stage::Receivers);
  upload_receivers(dev, rb.inputs.receivers, r.soa, "spherical_lights receivers", &rb.inputs.receivers_hash);
  put_if_changed(dev, g.spheres, g.spheres_hash, spheres, "spherical_lights SL spheres");
  put_if_changed(dev, g.rotation, g.rotation_hash, rotation, "spherical_lights SL rotations");
  put_if_changed(dev, g.object, g.object_hash, object, "spherical_lights SL objects");
  put_if_changed(dev, g.object_centre, g.object_centre_hash, centres, "spherical_lights object centres");
  put_if_changed(dev, g.inter_begin, g.inter_begin_hash, inter_begin, "spherical_lights intersecting offsets");
  put_if_changed(dev, g.inter_list, g.inter_list_hash, inter_list, "spherical_lights intersecting lists");
  put_if_changed(dev, g.consts, g.consts_hash, consts, "spherical_lights indirect constants");
  put_if_changed(dev, g.entry_sl, g.entry_sl_hash, entry_sl, "spherical_lights list entries");
  put_if_changed(dev, g.ratio, g.ratio_hash, ratio, "spherical_lights reflection ratios");
  put_if_changed(dev, g.rlist, g.rlist_hash, rlist, "spherical_lights receiver lists");
  put_if_changed(dev, g.list_range, g.list_range_hash, list_range, "spherical_lights list ranges");
  if (!dlc) put_if_changed(dev, g.intensity_in, g.intensity_in_hash, hlc->v, "spherical_lights intensity input");
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  const vk::Buffer& lc = dlc ? *dlc->buffer : g.intensity_in;

  const std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  std::uint32_t status[gpu::kSlStatusWords] = {0, 0, 0, none, none, none, 0, none};
  dev.ensure_buffer(g.ind_status, sizeof status, kStorage, vk::MemoryKind::Host, "spherical_lights indirect status");
  dev.upload(g.ind_status, status, sizeof status);
  dev.ensure_buffer(g.ind_out, std::max<std::size_t>(1, count) * 4 * sizeof(float), kStorage, vk::MemoryKind::Host,
                    "spherical_lights indirect shading");
  check_fits(dev, std::max<std::size_t>(1, count) * (n2 + 4) * sizeof(float), "the pass state of " + std::to_string(count) + " receivers",
             "accumulate_indirect");
  dev.ensure_buffer(g.ind_state, std::max<std::size_t>(1, count) * (n2 + 4) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "spherical_lights indirect pass state");
  const std::uint32_t blocking = s.blocking == Blocking::PerObject ? gpu::kSlPerObject : gpu::kSlPerSphere;
  vk::ComputePipeline& p = pipeline(dev, g.pipelines,
                                    "sl.indirect.n" + std::to_string(n) + ".rule" + std::to_string(static_cast<int>(s.rule)) + ".m" +
                                        std::to_string(method) + ".b" + std::to_string(blocking),
                                    order_variant(spv::spherical_lights_accumulate_indirect_comp_for(n), n, "spherical_lights accumulate_indirect"),
                                    {{0, static_cast<std::uint32_t>(n)}, {1, static_cast<std::uint32_t>(s.rule)}, {2, method}, {3, blocking}});
  struct Push {
    std::uint32_t count, first, end, lights, log_rows, weight_rows, ol_count;
    float log_scale, weight_scale;
    std::uint32_t budget, resume;
  };
  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kSlIndBindReceivers, rb.inputs.receivers, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindSpheres, g.spheres, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindRotation, g.rotation, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindObject, g.object, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kSlIndBindObjCentre, g.object_centre, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindInterBegin, g.inter_begin, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kSlIndBindInterList, g.inter_list, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kSlIndBindIntensity, lc, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindLogTable, g.log_table, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindWeight, g.weight_table, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindConsts, g.consts, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kSlIndBindBasis, basis),
      vk::Bind::texels_at(gpu::kSlIndBindOl, g.ol, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kSlIndBindOut, g.ind_out),
      vk::Bind::buffer_at(gpu::kSlIndBindStatus, g.ind_status),
      vk::Bind::texels_at(gpu::kSlIndBindEntrySl, g.entry_sl, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kSlIndBindRatio, g.ratio, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSlIndBindRList, g.rlist, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kSlIndBindLists, g.list_range, VK_FORMAT_R32G32_UINT),
      vk::Bind::buffer_at(gpu::kSlIndBindState, g.ind_state)};
  const float weight_scale = static_cast<float>((t.weight.rows - 1) / kHalfPi);
  // Passes until every receiver has summed all its SLs: one where the driver has no loop limit,
  // else as many as the limit requires (the shader's header comment).
  const std::uint32_t budget = loop_budget(dev.device_info());
  double secs = 0.0;
  int passes = 0;
  for (;;) {
    const vk::SubmitResult res = dev.submit([&](vk::Recorder& rec) {
      rec.begin_timer("accumulate_indirect");
      dispatch_chunks<Push>(rec, p, binds, count, gpu::kSlIndirectGroup, [&](std::uint32_t first, std::uint32_t end) {
        return Push{static_cast<std::uint32_t>(count), first, end, static_cast<std::uint32_t>(entries), static_cast<std::uint32_t>(t.log.rows),
                    static_cast<std::uint32_t>(t.weight.rows), g.ol_count, t.log.scale, weight_scale, budget, passes > 0 ? 1u : 0u};
      });
      rec.end_timer();
      rec.barrier();
    }, "spherical_lights accumulate_indirect");
    secs += std::max(0.0, timer_seconds(res));
    ++passes;
    dev.download(g.ind_status, status, sizeof status);
    if (status[gpu::kSlStatusBudget] != none)
      throw std::invalid_argument("spherical_lights accumulate_indirect on vulkan: receiver " + std::to_string(status[gpu::kSlStatusBudget] - 1) +
                                  ": one SL's exponentials need more loop iterations than this driver runs per invocation (" +
                                  std::to_string(budget) + " on " + dev.device_info().driver_name + "); lower 'order'");
    if (status[gpu::kSlStatusUnfinished] == 0 || status[gpu::kSlStatusBadInput] != none || status[gpu::kSlStatusDcOverflow] != none) break;
    // Every pass sums at least one SL of each unfinished receiver, so a receiver's list bounds the passes.
    if (passes > static_cast<int>(gpu::kSlMaxLights) + 1)
      throw std::logic_error("spherical_lights accumulate_indirect on vulkan: receivers still unfinished after " + std::to_string(passes) + " passes");
    status[gpu::kSlStatusUnfinished] = 0;
    dev.upload(g.ind_status, status, sizeof status);
  }
  if (status[gpu::kSlStatusBadInput] != none)
    throw std::invalid_argument("spherical_lights accumulate_indirect on vulkan: receiver " + std::to_string(status[gpu::kSlStatusBadInput] - 1) +
                                " has a non-finite log coefficient");
  if (status[gpu::kSlStatusDcOverflow] != none)
    throw std::overflow_error("spherical_lights accumulate_indirect on vulkan: receiver " + std::to_string(status[gpu::kSlStatusDcOverflow] - 1) +
                              ": a DC coefficient gives a mean log value whose exponential overflows");
  if (status[gpu::kSlStatusOverflow] != none)
    throw std::overflow_error("spherical_lights accumulate_indirect on vulkan: receiver " + std::to_string(status[gpu::kSlStatusOverflow] - 1) +
                              ": a visibility coefficient overflowed");
  // The host to_image pass reads the shading: downloaded here (4 floats per receiver).
  std::vector<float> rgba(count * 4);
  if (count) dev.download(g.ind_out, rgba.data(), rgba.size() * sizeof(float));
  auto out = std::make_shared<Shading>();
  out->value.resize(count);
  for (std::size_t i = 0; i < count; ++i) out->value[i] = glm::vec3(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2]);

  auto& rec = ctx.record();
  const double pairs = status[gpu::kSlStatusPairs];
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["sls"] = static_cast<double>(m);
  rec.counters["pairs"] = pairs;
  rec.counters["eliminated_pairs"] = status[gpu::kSlStatusEliminated];
  rec.counters["visibility_clamped"] = status[gpu::kSlStatusClamped];
  rec.counters["exponentials"] = 2.0 * pairs;
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["per_object_blocking"] = s.blocking == Blocking::PerObject;
  rec.counters["kernel_gpu_seconds"] = secs;
  rec.counters["passes"] = passes;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = out->value.size() * sizeof(glm::vec3);
  ctx.put<std::shared_ptr<const Shading>>(kIndirectShading, out);
}

}  // namespace

void register_vulkan_kernels() {
  DeviceKernels k;
  k.accumulate = vulkan_accumulate;
  k.exponentiate = vulkan_exponentiate;
  k.shade = common::vulkan_shade;
  k.intensity = vulkan_intensity;
  k.indirect = vulkan_indirect;
  register_device_kernels(vk::kBackendName, std::move(k));
}

}  // namespace softgi::techniques::spherical_lights
