// Image-space proxy accumulation (paper 000, Sloan et al. 2007) as a render::Technique: parameters,
// pass graph and the CPU implementation of every pass. docs/techniques/image_splat.md describes the
// graph and what differs from the paper.
#include "softgi/techniques/image_splat.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "../common/device_kernels.hpp"
#include "../common/pass_support.hpp"
#include "../common/shared_params.hpp"
#include "image_splat_internal.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/vertex_image.hpp"

namespace softgi::techniques::image_splat {

std::vector<render::ExperimentDef> experiments();  // image_splat_experiments.cpp

using render::FrameContext;
using render::ParamDesc;
using common::KernelIsa;

// --- parameters ----------------------------------------------------------------------------------

std::vector<ParamDesc> param_descs() {
  std::vector<ParamDesc> d;
  // Quality ladder (softgi report): the receiver buffer's scale is the paper's main cost knob
  // (section 4: cost per coarse pixel and proxy), the SH order the shadows' sharpness.
  d.push_back(common::params::order(4, "shadows (log occlusion, O_p, L)").with_ladder({"3", "4", "4", "5"}));
  d.push_back(ParamDesc::boolean("indirect", true, "accumulate indirect light re-radiated by the proxies (section 5)"));
  d.push_back(ParamDesc::integer("indirect_order", 3, common::kMinOrder, common::kMaxOrder, "SH order of indirect accumulation (paper: 3)"));
  d.push_back(ParamDesc::choice("indirect_operator", "averaged_poly", {"averaged_poly", "averaged", "point", "exact"},
                                "indirect operator: averaged eq. 15 with the polynomial D (paper, order 3) or with D by "
                                "quadrature, point-sampled eq. 13, exact eqs. 16-17"));
  d.push_back(ParamDesc::boolean("normalize_indirect", true, "normalise the indirect sum by xi_p (eq. 12); off: the plain sum"));
  d.push_back(ParamDesc::integer("receiver_scale", 2, 1, 8, "receiver buffer at 1/s of display resolution, s in {1, 2, 4, 8} (section 4)")
                  .with_ladder({"8", "4", "2", "1"}));
  d.push_back(ParamDesc::choice("coverage", "derived", {"derived", "environment", "paper", "off"},
                                "sphere of influence (section 4.1): eta derived for the worst-case delta light, for the "
                                "scene's environment, the paper's 15 / 10, or none"));
  d.push_back(ParamDesc::choice("eta_light", "unit_shading", {"unit_shading", "unit_peak"},
                                "light normalisation of the eta derivation: unshadowed shading 1 (the paper's text) or "
                                "peak radiance 1 (reproduces the paper's 15 / 10)"));
  d.push_back(ParamDesc::real("eta_threshold", 1.0 / 256.0, 1e-5, 0.5, "shading difference allowed outside the sphere of influence"));
  d.push_back(ParamDesc::real("eta_shadow", 0.0, 0.0, 1000.0, "shadow expansion factor override (0 = from coverage, else > 1)"));
  d.push_back(ParamDesc::real("eta_indirect", 0.0, 0.0, 1000.0, "indirect expansion factor override (0 = from coverage, else > 1)"));
  d.push_back(ParamDesc::boolean("smooth_clamp", true, "re-weight the tables smoothly to 0 around 1/eta (off: hard cut at eta r)"));
  d.push_back(common::params::exp({"hyb", "ol", "ps*", "exact"},
                                  "SH exponential of the accumulated log occlusion (paper 004 section 4; ps* = PS*-2)"));
  d.push_back(common::params::self_shadow_rules());
  d.push_back(common::params::replacement_rule());
  d.push_back(common::params::window_h());
  d.push_back(common::params::table_resolution());
  d.push_back(common::params::log_threshold());
  d.push_back(ParamDesc::choice("upsample", "bilateral", {"bilateral", "bilinear"}, "upsampling to display resolution (section 4.2, eq. 11)"));
  d.push_back(ParamDesc::choice("shade_interpolation", "auto", {"auto", "transfer", "visibility"},
                                "what the eq. 11 taps interpolate for the direct shading: each coarse sample's transfer row "
                                "(O_p times the light and clamped cosine, one dot product per pixel; with O_p alongside for "
                                "the spherical lights) or O_p itself, shaded with an SH product per pixel as section 4.2 "
                                "writes it (the same value; the CPU backend, Vulkan interpolates O_p); auto: transfer rows "
                                "where each coarse sample serves 16 display pixels or more (receiver_scale >= 4), which "
                                "repays its rows, else O_p"));
  d.push_back(ParamDesc::choice("fallback", "robust", {"robust", "shaded", "none"},
                                "display pixels no coarse sample matches: shade from the full proxy list, interpolate "
                                "shaded coarse results, or keep eq. 11's value"));
  d.push_back(ParamDesc::real("bilateral_epsilon", 0.01, 1e-6, 10.0, "epsilon of the depth weight, relative to the target's depth"));
  d.push_back(ParamDesc::integer("normal_power", 32, 0, 256, "exponent of the normal weight (paper: 32)"));
  d.push_back(ParamDesc::real("miss_threshold", 0.05, 0.0, 1.0, "unnormalised eq. 11 weight below which a display pixel is a miss"));
  d.push_back(ParamDesc::integer("tile_size", 16, 4, 64, "receiver tile edge in coarse pixels for binning the proxies"));
  d.push_back(ParamDesc::choice("binning", "host", {"host", "device"},
                                "where the proxies are binned to receiver tiles (section 4.1): on the host, or by a compute "
                                "pass on a device backend that leaves the lists on the device (the CPU backend bins on the host)"));
  d.push_back(ParamDesc::choice("splatting", "binned", {"binned", "raster"},
                                "how proxies reach their receivers (section 4.1): each tile's receivers sum the proxies binned "
                                "to the tile, or each proxy's sphere of influence is rasterised into the receiver buffer and "
                                "summed by additive blending, for shadows and indirect light (Figure 3; a rasterising device "
                                "backend, the CPU backend sums the binned lists either way)"));
  d.push_back(common::params::analytic_lights());
  d.push_back(common::params::kernel());
  return d;
}

Settings read_settings(const render::ParamSet& p) {
  Settings s;
  s.order = p.get_int("order");
  s.indirect = p.get_bool("indirect");
  s.indirect_order = p.get_int("indirect_order");
  s.op = parse_indirect_operator(p.get_enum("indirect_operator"));
  if (s.indirect && s.op == IndirectOperator::AveragedPolynomial && s.indirect_order != 3)
    throw std::invalid_argument("parameter 'indirect_operator': averaged_poly (the paper's polynomial D) exists at order 3 only, "
                                "but parameter 'indirect_order' is " + std::to_string(s.indirect_order) +
                                " (use indirect_order=3 or indirect_operator=averaged)");
  s.normalize_indirect = p.get_bool("normalize_indirect");
  s.receiver_scale = p.get_int("receiver_scale");
  if (s.receiver_scale != 1 && s.receiver_scale != 2 && s.receiver_scale != 4 && s.receiver_scale != 8)
    throw std::invalid_argument("parameter 'receiver_scale': " + std::to_string(s.receiver_scale) + " (expected 1, 2, 4 or 8)");
  const std::string& cov = p.get_enum("coverage");
  s.coverage = cov == "derived" ? Coverage::Derived : cov == "environment" ? Coverage::Environment : cov == "paper" ? Coverage::Paper : Coverage::Off;
  s.eta_light = p.get_enum("eta_light") == "unit_peak" ? LightNormalisation::UnitPeakRadiance : LightNormalisation::UnitShading;
  s.eta_threshold = p.get_float("eta_threshold");
  s.eta_shadow = p.get_float("eta_shadow");
  s.eta_indirect = p.get_float("eta_indirect");
  for (const char* name : {"eta_shadow", "eta_indirect"}) {
    const double v = p.get_float(name);
    if (v != 0.0 && !(v > 1.0))
      throw std::invalid_argument(std::string("parameter '") + name + "': " + p.get_text(name) +
                                  " (expected 0 = from coverage, or > 1: the sphere of influence is eta times the proxy radius)");
  }
  s.smooth_clamp = p.get_bool("smooth_clamp");
  const std::string& e = p.get_enum("exp");
  s.exp = e == "hyb" ? ExpMode::HYB : e == "ol" ? ExpMode::OL : e == "ps*" ? ExpMode::PSStar : ExpMode::Exact;
  s.rule = common::params::read_replacement_rule(p);
  s.window_h = common::params::read_window_h(p, s.order);
  s.table_resolution = p.get_int("table_resolution");
  s.log_threshold = p.get_float("log_threshold");
  s.upsample.mode = parse_upsample_mode(p.get_enum("upsample"));
  s.fallback = parse_upsample_fallback(p.get_enum("fallback"));
  const std::string& si = p.get_enum("shade_interpolation");
  s.shade_interpolation = si == "transfer"     ? ShadeInterpolation::Transfer
                          : si == "visibility" ? ShadeInterpolation::Visibility
                          : s.receiver_scale >= kTransferMinScale ? ShadeInterpolation::Transfer
                                                                  : ShadeInterpolation::Visibility;
  s.upsample.epsilon_rel = p.get_float("bilateral_epsilon");
  s.upsample.normal_power = p.get_int("normal_power");
  s.upsample.miss_threshold = p.get_float("miss_threshold");
  s.tile_size = p.get_int("tile_size");
  s.device_binning = p.get_enum("binning") == "device";
  s.raster_splats = p.get_enum("splatting") == "raster";
  s.lights = p.get_bool("analytic_lights");
  s.isa = common::params::read_kernel(p);
  return s;
}

namespace {

// Inputs of the graph besides the shared ones (empty: the passes needing them are left out).
constexpr const char* kBlockerSpheres = "blocker_spheres";
constexpr const char* kSphericalLights = "spherical_lights";
constexpr const char* kIndirectEnabled = "image_splat.indirect_enabled";
// Resources written by the technique's passes.
constexpr const char* kTables = "image_splat.tables";
constexpr const char* kIndirectTables = "image_splat.indirect_tables";
constexpr const char* kLightTables = "image_splat.light_tables";
constexpr const char* kReceivers = "image_splat.receivers";
constexpr const char* kBins = "image_splat.bins";
constexpr const char* kLogOcclusion = "image_splat.log_occlusion";
constexpr const char* kOcclusion = "image_splat.occlusion";
constexpr const char* kIndirectSums = "image_splat.indirect_sums";
constexpr const char* kIndirectNorm = "image_splat.indirect_normalized";
constexpr const char* kUpsampled = "image_splat.upsampled";
constexpr const char* kRobust = "image_splat.robust_misses";

constexpr std::size_t kBlock = 256;  // receivers per task in per-receiver passes (a multiple of every lane count)



// --- state kept across frames --------------------------------------------------------------------

struct State {
  std::mutex m;
  std::map<std::tuple<std::string, int, double>, std::vector<glm::vec3>> env_sh;  // (env, order, window_h)
  std::map<std::tuple<int, double, std::string, int>, EtaDerivation> etas;        // (order, threshold, env or "", 0 shadow / 1 indirect)
  common::SharedCache<std::tuple<int, int, double, double, bool>, ShadowTables> tables;
  std::map<std::string, std::shared_ptr<const IndirectEvaluator>> evaluators;
  common::LightTableCache light_tables;
};

// The windowed environment SH at `order` (cached per environment).
std::vector<glm::vec3> env_light(State& st, const scene::Scene& scene, int order, double window_h) {
  const auto key = std::make_tuple(common::environment_signature(scene.environment), order, window_h);
  std::lock_guard<std::mutex> lock(st.m);
  auto it = st.env_sh.find(key);
  if (it != st.env_sh.end()) return it->second;
  std::vector<glm::vec3> L = common::windowed_environment_sh("image_splat", scene, order, window_h);
  st.env_sh[key] = L;
  return L;
}

EtaDerivation derive_eta(State& st, const scene::Scene& scene, const Settings& s, bool shadow) {
  const int order = shadow ? s.order : s.indirect_order;
  const bool env = s.coverage == Coverage::Environment;
  std::vector<glm::vec3> L;
  if (env) L = env_light(st, scene, order, 0.0);
  const auto key = std::make_tuple(order, s.eta_threshold, env ? common::environment_signature(scene.environment) : std::string(),
                                   (shadow ? 0 : 1) + 2 * static_cast<int>(s.eta_light));
  {
    std::lock_guard<std::mutex> lock(st.m);
    auto it = st.etas.find(key);
    if (it != st.etas.end()) return it->second;
  }
  EtaDerivation d = shadow ? derive_eta_shadow(order, s.eta_threshold, env ? &L : nullptr, s.eta_light)
                           : derive_eta_indirect(order, s.eta_threshold, env ? &L : nullptr, s.eta_light);
  std::lock_guard<std::mutex> lock(st.m);
  st.etas[key] = d;
  return d;
}

void check_proxies(const FrameContext& ctx) { common::check_proxy_spheres("image_splat", ctx, true); }

// --- passes --------------------------------------------------------------------------------------

void pass_tables(State& st, const Settings& s, FrameContext& ctx) {
  // Section 4.1: eta for shadows and indirect light, from the coverage setting or the overrides.
  double eta_s = 0.0, eta_i = 0.0;
  auto& rec = ctx.record();
  if (s.coverage == Coverage::Paper) {
    eta_s = kPaperEtaShadow;
    eta_i = kPaperEtaIndirect;
  } else if (s.coverage != Coverage::Off) {
    const EtaDerivation ds = derive_eta(st, ctx.scene, s, true);
    eta_s = ds.eta;
    rec.counters["theta_shadow_deg"] = ds.theta_deg;
    rec.counters["max_difference_shadow"] = ds.max_difference;
    if (s.indirect) {
      const EtaDerivation di = derive_eta(st, ctx.scene, s, false);
      eta_i = di.eta;
      rec.counters["theta_indirect_deg"] = di.theta_deg;
      rec.counters["max_difference_indirect"] = di.max_difference;
    }
  }
  if (s.eta_shadow > 0.0) eta_s = s.eta_shadow;
  if (s.eta_indirect > 0.0) eta_i = s.eta_indirect;

  bool cached = false;
  const std::shared_ptr<const ShadowTables> t = st.tables.get(
      std::make_tuple(s.order, s.table_resolution, s.log_threshold, eta_s, s.smooth_clamp),
      [&s, eta_s] {
        auto tab = std::make_shared<ShadowTables>();
        tab->order = s.order;
        tab->sh = common::accumulation_tables(s.order, s.table_resolution, s.log_threshold);
        const common::ZhTable log = common::make_zh_table(tab->sh->cap_log(), s.order, true);
        tab->eta_shadow = eta_s;
        if (eta_s > 0.0 && s.smooth_clamp) {
          // Section 4.1, smooth clamping: rows near 1/eta weighted to 0, smaller angles forced to 0.
          tab->log = clamp_zh_table(log, eta_s, kClampRampRows);
          tab->support_alpha_shadow = clamped_support_alpha(s.table_resolution, eta_s, kClampRampRows);
        } else {
          tab->log = log;
          tab->hard_cut = eta_s > 0.0;
          tab->support_alpha_shadow = eta_s > 0.0 ? 1.0 / eta_s : 0.0;
        }
        return std::shared_ptr<const ShadowTables>(tab);
      },
      cached);
  // eta_indirect is not part of the shadow table: a copy carries it with the indirect support.
  auto out = std::make_shared<ShadowTables>(*t);
  out->eta_indirect = eta_i;
  out->support_alpha_indirect = eta_i > 0.0 ? (s.smooth_clamp ? clamped_support_alpha(s.table_resolution, eta_i, kClampRampRows) : 1.0 / eta_i) : 0.0;
  rec.counters["order"] = s.order;
  rec.counters["rows"] = s.table_resolution;
  rec.counters["cached"] = cached;
  rec.counters["eta_shadow"] = eta_s;
  rec.counters["eta_indirect"] = eta_i;
  rec.counters["eta_paper_shadow"] = kPaperEtaShadow;
  rec.counters["eta_paper_indirect"] = kPaperEtaIndirect;
  rec.counters["influence_shadow"] = out->support_alpha_shadow > 0.0 ? 1.0 / out->support_alpha_shadow : 0.0;
  rec.counters["influence_indirect"] = out->support_alpha_indirect > 0.0 ? 1.0 / out->support_alpha_indirect : 0.0;
  rec.bytes = out->bytes();
  ctx.put<std::shared_ptr<const ShadowTables>>(kTables, out);
}

void pass_indirect_tables(State& st, const Settings& s, FrameContext& ctx) {
  const auto& t = *ctx.get<std::shared_ptr<const ShadowTables>>(kTables);
  IndirectSetup setup;
  setup.order = s.indirect_order;
  setup.op = s.op;
  setup.eta = t.eta_indirect;
  setup.smooth_clamp = s.smooth_clamp;
  setup.table_resolution = s.table_resolution;
  setup.rule = s.rule;
  // The printed rule's adjusted sphere can outgrow the proxy: the pairs its sphere of influence
  // selects are cut per pair, as pair_cut_factor does for the shadows.
  if (s.rule == common::ReplacementRule::Printed) setup.reach = reach_factor(t.support_alpha_indirect);
  std::ostringstream key;
  key << common::environment_signature(ctx.scene.environment) << '|' << s.indirect_order << '|' << static_cast<int>(s.op) << '|' << t.eta_indirect << '|'
      << s.smooth_clamp << '|' << s.table_resolution << '|' << static_cast<int>(s.rule) << '|' << s.window_h << '|' << s.order;
  std::shared_ptr<const IndirectEvaluator> ev;
  bool cached = true;
  {
    std::lock_guard<std::mutex> lock(st.m);
    auto it = st.evaluators.find(key.str());
    if (it != st.evaluators.end()) ev = it->second;
  }
  if (!ev) {
    cached = false;
    // The proxies re-radiate the light the receivers are shaded with (windowed at the shadow order,
    // truncated to the indirect order): L~ = L convolved with the clamped cosine (section 3).
    const std::vector<glm::vec3> L = env_light(st, ctx.scene, std::max(s.order, s.indirect_order), s.window_h);
    ev = std::make_shared<const IndirectEvaluator>(setup, irradiance_sh(L, s.indirect_order));
    std::lock_guard<std::mutex> lock(st.m);
    st.evaluators[key.str()] = ev;
  }
  auto& rec = ctx.record();
  rec.counters["order"] = s.indirect_order;
  rec.counters["cached"] = cached;
  rec.counters["eta_indirect"] = t.eta_indirect;
  rec.bytes = ev->bytes();
  ctx.put<std::shared_ptr<const IndirectEvaluator>>(kIndirectTables, ev);
}

void pass_light_tables(State& st, const Settings& s, FrameContext& ctx) { st.light_tables.run_pass(s.order, s.window_h, ctx, kLightTables); }

void pass_receivers(const Settings& s, FrameContext& ctx) {
  const auto& coarse = ctx.get<render::GBuffer>(render::kReceiverGBuffer);
  auto r = std::make_shared<ReceiverBuffer>(make_receivers(coarse, s.tile_size));
  std::size_t mx = 0;
  for (const auto& t : r->tiles) mx = std::max(mx, t.end - t.begin);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(r->soa.size());
  rec.counters["coarse_pixels"] = static_cast<double>(r->receiver.size());
  rec.counters["tiles"] = static_cast<double>(r->tiles.size());
  rec.counters["receivers_per_tile_max"] = static_cast<double>(mx);
  rec.bytes = r->bytes();
  ctx.put<std::shared_ptr<const ReceiverBuffer>>(kReceivers, r);
}

// The flat proxy lists and the radii' support factors that binning starts from.
struct BinInputs {
  std::shared_ptr<common::BlockerList> shadow = std::make_shared<common::BlockerList>();
  std::shared_ptr<ProxyList> indirect;  // null when indirect light is off
  double alpha_shadow = 0.0, alpha_indirect = 0.0;
};

BinInputs bin_inputs(const Settings& s, FrameContext& ctx) {
  check_proxies(ctx);
  const auto& t = *ctx.get<std::shared_ptr<const ShadowTables>>(kTables);
  BinInputs in;
  if (ctx.has(kIndirectTables)) in.indirect = std::make_shared<ProxyList>();
  flat_proxies(ctx.scene, ctx.posed, s.order, in.shadow.get(), in.indirect.get());
  in.alpha_shadow = t.support_alpha_shadow;
  in.alpha_indirect = t.support_alpha_indirect;
  return in;
}

void record_bins(FrameContext& ctx, const ReceiverBuffer& r, const BinInputs& in, const BinCounts& b) {
  const bool ind = in.indirect != nullptr;
  std::size_t mxs = 0, mxi = 0;
  double rs = 0.0, ri = 0.0, ts = 0.0, ti = 0.0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k) {
    const double nrec = static_cast<double>(r.tiles[k].end - r.tiles[k].begin);
    mxs = std::max<std::size_t>(mxs, b.shadow_counts[k]);
    rs += nrec * static_cast<double>(b.shadow_counts[k]);
    ts += static_cast<double>(b.shadow_counts[k]);
    if (ind) {
      mxi = std::max<std::size_t>(mxi, b.indirect_counts[k]);
      ri += nrec * static_cast<double>(b.indirect_counts[k]);
      ti += static_cast<double>(b.indirect_counts[k]);
    }
  }
  const double nt = std::max<double>(1.0, static_cast<double>(r.tiles.size()));
  auto& rec = ctx.record();
  rec.counters["proxies"] = static_cast<double>(in.shadow->size());
  rec.counters["tiles"] = static_cast<double>(r.tiles.size());
  rec.counters["pairs_tested"] = b.pairs_tested;
  rec.counters["shadow_tile_pairs"] = ts;
  rec.counters["shadow_proxies_per_tile_mean"] = ts / nt;
  rec.counters["shadow_proxies_per_tile_max"] = static_cast<double>(mxs);
  rec.counters["shadow_receiver_pairs"] = rs;
  rec.counters["indirect_tile_pairs"] = ti;
  rec.counters["indirect_proxies_per_tile_mean"] = ti / nt;
  rec.counters["indirect_proxies_per_tile_max"] = static_cast<double>(mxi);
  rec.counters["indirect_receiver_pairs"] = ri;
  // Receiver-proxy pairs without binning, for the saving binning (splatting) buys.
  rec.counters["all_receiver_pairs"] = static_cast<double>(r.soa.size()) * static_cast<double>(in.shadow->size());
  if (b.gpu_seconds >= 0.0) {
    rec.counters["kernel_gpu_seconds"] = b.gpu_seconds;
    rec.counters["upload_bytes"] = static_cast<double>(b.upload_bytes);
    rec.counters["download_bytes"] = static_cast<double>(b.download_bytes);
  }
  rec.bytes = b.bytes;
}

}  // namespace

BinCounts bin_counts(const ProxyBins& bins) {
  BinCounts b;
  for (const auto& l : bins.shadow) b.shadow_counts.push_back(static_cast<std::uint32_t>(l.size()));
  for (const auto& l : bins.indirect) b.indirect_counts.push_back(static_cast<std::uint32_t>(l.size()));
  b.pairs_tested = bins.pairs_tested;
  b.bytes = bins.bytes();
  return b;
}

namespace {

void pass_bin(const Settings& s, FrameContext& ctx) {
  const BinInputs in = bin_inputs(s, ctx);
  const auto& r = *ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
  auto bins = std::make_shared<ProxyBins>(bin_proxies(r, *in.shadow, in.alpha_shadow, in.indirect.get(), in.alpha_indirect));
  record_bins(ctx, r, in, bin_counts(*bins));
  ctx.put<std::shared_ptr<const ProxyBins>>(kBins, bins);
}

// A per-receiver field of `count` x `channels` zeros whose storage comes from the frame pool and
// goes back to it at the end of the frame unless a caller holds the resource: every frame needs
// the same fields again, and fresh pages cost a fault each (bench/README.md, "Frame memory").
std::shared_ptr<Field> pooled_field(FrameContext& ctx, int channels, std::size_t count) {
  auto f = std::make_shared<Field>();
  f->channels = channels;
  f->v = ctx.pool().take(count * static_cast<std::size_t>(channels), 0.0f);
  ctx.on_release([f](render::FramePool& pool) {
    if (f.use_count() == 1) pool.give(std::move(f->v));
  });
  return f;
}

void pass_accumulate_log(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
  const auto& t = *ctx.get<std::shared_ptr<const ShadowTables>>(kTables);
  const auto& bins = *ctx.get<std::shared_ptr<const ProxyBins>>(kBins);
  auto f = pooled_field(ctx, s.order * s.order, r.soa.size());
  const auto t0 = std::chrono::steady_clock::now();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.tiles.size(), 1), [&](const tbb::blocked_range<std::size_t>& tr) {
    for (std::size_t k = tr.begin(); k != tr.end(); ++k)
      accumulate_log_range(t, s.rule, s.isa, r.soa, r.tiles[k].begin, r.tiles[k].end, bins.shadow[k], f->v.data());
  });
  const double secs = common::seconds_since(t0);
  double pairs = 0.0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    pairs += static_cast<double>(r.tiles[k].end - r.tiles[k].begin) * static_cast<double>(bins.shadow[k].size());
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(r.soa.size());
  rec.counters["pairs"] = pairs;
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["kernel_lanes"] = common::kernel_lanes(s.isa);
  rec.counters["hard_cut"] = t.hard_cut;
  rec.bytes = f->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kLogOcclusion, f);
}

void pass_exponentiate(const Settings& s, FrameContext& ctx) {
  const auto& t = *ctx.get<std::shared_ptr<const ShadowTables>>(kTables);
  const auto& f = *ctx.get<std::shared_ptr<const Field>>(kLogOcclusion);
  const std::size_t n2 = static_cast<std::size_t>(f.channels), count = n2 ? f.v.size() / n2 : 0;
  auto g = pooled_field(ctx, f.channels, count);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, kBlock), [&](const tbb::blocked_range<std::size_t>& br) {
    try {
      exponentiate(t, s.exp, s.ps_degree, s.isa, f.v.data() + br.begin() * n2, g->v.data() + br.begin() * n2, br.size(), br.begin());
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string("image_splat exponentiate (receivers ") + std::to_string(br.begin()) + ".." +
                               std::to_string(br.end() - 1) + "): " + e.what());
    }
  });
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.bytes = g->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kOcclusion, g);
}

void pass_accumulate_indirect(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
  const auto& bins = *ctx.get<std::shared_ptr<const ProxyBins>>(kBins);
  const auto& ev = *ctx.get<std::shared_ptr<const IndirectEvaluator>>(kIndirectTables);
  auto sums = std::make_shared<IndirectSums>();
  sums->rgb = ctx.pool().take(r.soa.size() * 3, 0.0f);
  sums->omega = ctx.pool().take(r.soa.size(), 0.0f);
  ctx.on_release([sums](render::FramePool& pool) {
    if (sums.use_count() > 1) return;
    pool.give(std::move(sums->rgb));
    pool.give(std::move(sums->omega));
  });
  std::atomic<long long> inside{0};
  const auto t0 = std::chrono::steady_clock::now();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.tiles.size(), 1), [&](const tbb::blocked_range<std::size_t>& tr) {
    long long n = 0;
    for (std::size_t k = tr.begin(); k != tr.end(); ++k)
      n += ev.accumulate(r.soa, r.tiles[k].begin, r.tiles[k].end, bins.indirect[k], sums->rgb.data(), sums->omega.data(), s.isa);
    inside += n;
  });
  const double secs = common::seconds_since(t0);
  double pairs = 0.0;
  for (std::size_t k = 0; k < r.tiles.size(); ++k)
    pairs += static_cast<double>(r.tiles[k].end - r.tiles[k].begin) * static_cast<double>(bins.indirect[k].size());
  sums->pairs = pairs;
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(r.soa.size());
  rec.counters["pairs"] = pairs;
  rec.counters["pairs_inside_influence"] = static_cast<double>(inside.load());
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["kernel_lanes"] = ev.batched() ? common::kernel_lanes(s.isa) : 1;  // the exact operator: pair by pair
  rec.bytes = (sums->rgb.size() + sums->omega.size()) * sizeof(float);
  ctx.put<std::shared_ptr<const IndirectSums>>(kIndirectSums, sums);
}

// Eq. 12 over n receivers: out = xi rgb, with O_p from `occ` (n^2 per receiver) when present.
struct XiStats {
  double sum = 0.0, raw_min = std::numeric_limits<double>::infinity(), raw_max = -std::numeric_limits<double>::infinity();
  long long outside = 0;  // raw xi outside [0, 1] by more than kXiReportTolerance
};
// Raw xi beyond [0, 1] by less than this is float noise of O_p,0 (a single proxy gives union = sum
// exactly); beyond it, the SH exponential's error or the different shadow and indirect clamps.
constexpr double kXiReportTolerance = 1e-2;

void normalise(const Settings& s, const float* rgb, const float* omega, const float* occ, int n2, std::size_t count, float* out,
               XiStats* stats) {
  for (std::size_t i = 0; i < count; ++i) {
    float xi = 1.0f;
    if (s.normalize_indirect && occ) {
      xi = indirect_normalisation(occ[i * n2], omega[i]);
      if (stats && omega[i] > 1e-7f) {
        const double s4pi = sh::kSqrt4Pi, raw = (s4pi - occ[i * n2]) / (omega[i] / s4pi);
        stats->raw_min = std::min(stats->raw_min, raw);
        stats->raw_max = std::max(stats->raw_max, raw);
        stats->outside += raw < -kXiReportTolerance || raw > 1.0 + kXiReportTolerance;
      }
    }
    if (stats) stats->sum += xi;
    for (int c = 0; c < 3; ++c) out[3 * i + c] = xi * rgb[3 * i + c];
  }
}

// `field_dc` (a device backend's): O_p's DC coefficients read back from the device where a GPU pass
// left O_p there, so that the rest of it stays there for shade_direct.
void pass_normalize_indirect(const Settings& s, FrameContext& ctx,
                             const std::function<std::vector<float>(FrameContext&, const std::string&)>& field_dc = {}) {
  const auto& sums = *ctx.get<std::shared_ptr<const IndirectSums>>(kIndirectSums);
  auto out = pooled_field(ctx, 3, sums.omega.size());
  XiStats xs;
  std::shared_ptr<const Field> occ;
  std::vector<float> dc;
  const bool has_occ = ctx.has(kOcclusion);
  if (has_occ && field_dc && ctx.is_deferred(kOcclusion)) {
    dc = field_dc(ctx, kOcclusion);
    if (dc.size() != sums.omega.size())
      throw std::logic_error("image_splat normalize_indirect: " + std::to_string(dc.size()) + " DC coefficients of O_p for " +
                             std::to_string(sums.omega.size()) + " receivers");
    normalise(s, sums.rgb.data(), sums.omega.data(), dc.data(), 1, sums.omega.size(), out->v.data(), &xs);
  } else {
    if (has_occ) occ = ctx.get<std::shared_ptr<const Field>>(kOcclusion);
    normalise(s, sums.rgb.data(), sums.omega.data(), occ ? occ->v.data() : nullptr, occ ? occ->channels : 0, sums.omega.size(),
              out->v.data(), &xs);
  }
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(sums.omega.size());
  rec.counters["normalized"] = s.normalize_indirect && has_occ;
  rec.counters["xi_mean"] = sums.omega.empty() ? 1.0 : xs.sum / static_cast<double>(sums.omega.size());
  rec.counters["xi_raw_min"] = std::isfinite(xs.raw_min) ? xs.raw_min : 1.0;
  rec.counters["xi_raw_max"] = std::isfinite(xs.raw_max) ? xs.raw_max : 1.0;
  rec.counters["xi_clamped"] = static_cast<double>(xs.outside);
  rec.bytes = out->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kIndirectNorm, out);
}

PlaneView plane(const render::GBuffer& gb) { return common::plane_view(gb); }

// A receiver-order field scattered to coarse-pixel order (background pixels 0), for upsampling.
// Its storage comes from the frame pool: every frame needs it again, and fresh pages cost a fault
// each (bench/README.md, "Frame memory").
std::vector<float> to_pixels(const ReceiverBuffer& r, const float* v, int channels, render::FramePool& pool) {
  const std::size_t ch = static_cast<std::size_t>(channels);
  std::vector<float> out = pool.take_for_overwrite<float>(r.receiver.size() * ch);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.receiver.size(), 4096), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t q = br.begin(); q != br.end(); ++q) {
      const std::int32_t i = r.receiver[q];
      float* o = out.data() + q * ch;
      if (i < 0)
        std::fill(o, o + ch, 0.0f);
      else
        std::copy(v + static_cast<std::size_t>(i) * ch, v + (static_cast<std::size_t>(i) + 1) * ch, o);
    }
  });
  return out;
}

// The indices of the display pixels that hit a surface, in scan order, into `out` (its capacity
// kept): counted per block in parallel, then written at each block's offset.
void surface_pixels(const render::GBuffer& fine, std::vector<std::int32_t>& out) {
  constexpr std::size_t kRun = 16384;
  const std::size_t np = fine.object.size(), blocks = (np + kRun - 1) / kRun;
  std::vector<std::size_t> offset(blocks + 1, 0);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    std::size_t c = 0;
    for (std::size_t i = b * kRun, e = std::min(np, (b + 1) * kRun); i < e; ++i) c += fine.hit(i);
    offset[b + 1] = c;
  });
  for (std::size_t b = 0; b < blocks; ++b) offset[b + 1] += offset[b];
  out.resize(offset[blocks]);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    std::size_t k = offset[b];
    for (std::size_t i = b * kRun, e = std::min(np, (b + 1) * kRun); i < e; ++i)
      if (fine.hit(i)) out[k++] = static_cast<std::int32_t>(i);
  });
}

// The kernels (k): upsample.cpp's on the CPU, compute shaders on Vulkan (image_splat_vulkan.cpp).
void pass_upsample(const Settings& s, FrameContext& ctx, const UpsampleKernels& k) {
  const auto& fine = ctx.get<render::GBuffer>(render::kGBuffer);
  const auto& coarse = ctx.get<render::GBuffer>(render::kReceiverGBuffer);
  const auto& r = *ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
  auto up = std::make_shared<Upsampled>();
  up->order = s.order;
  // Section 4.2: one set of eq. 11 weights serves O_p (n^2 channels) and the indirect shading (3).
  up->w = k.weights(plane(coarse), plane(fine), s.upsample);
  const std::size_t np = fine.object.size();
  up->surface = ctx.pool().take_for_overwrite<std::int32_t>(np);
  surface_pixels(fine, up->surface);
  if (ctx.has(kOcclusion) && ctx.is_deferred(kOcclusion)) {
    // O_p stays where a GPU pass left it: shade_direct's device kernel gathers from it through the
    // coarse pixels' receivers (see Upsampled).
    up->device_visibility = kOcclusion;
    up->coarse_receiver = r.receiver;
  } else if (ctx.has(kOcclusion)) {
    // Interpolated per block in shade_direct (see Upsampled).
    const auto& occ = *ctx.get<std::shared_ptr<const Field>>(kOcclusion);
    up->coarse_visibility = to_pixels(r, occ.v.data(), occ.channels, ctx.pool());
  }
  if (ctx.has(kIndirectNorm)) {
    const auto& ind = *ctx.get<std::shared_ptr<const Field>>(kIndirectNorm);
    std::vector<float> in = to_pixels(r, ind.v.data(), 3, ctx.pool());
    up->indirect = ctx.pool().take_for_overwrite<float>(np * 3);  // 0 where apply writes nothing (no tap)
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np * 3, 1 << 16), [&](const tbb::blocked_range<std::size_t>& br) {
      std::fill(up->indirect.begin() + static_cast<std::ptrdiff_t>(br.begin()), up->indirect.begin() + static_cast<std::ptrdiff_t>(br.end()), 0.0f);
    });
    k.apply(up->w, in.data(), 3, up->indirect.data());
    ctx.pool().give(std::move(in));
  }
  // The per-pixel planes go back to the pool at the end of the frame, unless the caller asked for
  // this resource and holds it.
  ctx.on_release([up](render::FramePool& pool) {
    if (up.use_count() > 1) return;
    common::give(pool, std::move(up->w));
    pool.give(std::move(up->surface));
    pool.give(std::move(up->indirect));
    pool.give(std::move(up->coarse_visibility));
  });
  auto& rec = ctx.record();
  const std::size_t hits = up->surface.size();
  rec.counters["pixels"] = static_cast<double>(np);
  rec.counters["surface_pixels"] = static_cast<double>(hits);
  rec.counters["misses"] = static_cast<double>(up->w.misses);
  rec.counters["miss_fraction"] = hits ? static_cast<double>(up->w.misses) / static_cast<double>(hits) : 0.0;
  rec.bytes = up->bytes();
  ctx.put<std::shared_ptr<const Upsampled>>(kUpsampled, up);
}

// Section 4.2's robust fallback: the misses accumulated from the entire proxy list, with the same
// clamped tables and kernels as the receiver buffer.
void pass_robust(const Settings& s, FrameContext& ctx) {
  check_proxies(ctx);
  const auto& fine = ctx.get<render::GBuffer>(render::kGBuffer);
  const auto& up = *ctx.get<std::shared_ptr<const Upsampled>>(kUpsampled);
  const auto& t = *ctx.get<std::shared_ptr<const ShadowTables>>(kTables);
  std::shared_ptr<const IndirectEvaluator> ev;
  if (ctx.has(kIndirectTables)) ev = ctx.get<std::shared_ptr<const IndirectEvaluator>>(kIndirectTables);
  auto rm = std::make_shared<RobustMisses>();
  for (std::size_t i = 0; i < up.w.miss.size(); ++i)
    if (up.w.miss[i] && fine.hit(i)) rm->pixel.push_back(static_cast<std::int32_t>(i));
  const std::size_t nm = rm->pixel.size();
  rm->soa.resize(nm);
  for (std::size_t k = 0; k < nm; ++k) rm->soa.set(k, fine.position[rm->pixel[k]], fine.normal[rm->pixel[k]]);
  common::BlockerList all;
  ProxyList all_ind;
  flat_proxies(ctx.scene, ctx.posed, s.order, &all, ev ? &all_ind : nullptr);
  const int n2 = s.order * s.order;
  std::vector<float> log(nm * n2, 0.0f), rgb(ev ? nm * 3 : 0, 0.0f), omega(ev ? nm : 0, 0.0f);
  rm->visibility.assign(nm * n2, 0.0f);
  if (ev) rm->indirect.assign(nm * 3, 0.0f);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nm, kBlock), [&](const tbb::blocked_range<std::size_t>& br) {
    accumulate_log_range(t, s.rule, s.isa, rm->soa, br.begin(), br.end(), all, log.data());
    exponentiate(t, s.exp, s.ps_degree, s.isa, log.data() + br.begin() * n2, rm->visibility.data() + br.begin() * n2, br.size(), br.begin());
    if (ev) {
      ev->accumulate(rm->soa, br.begin(), br.end(), all_ind, rgb.data(), omega.data(), s.isa);
      normalise(s, rgb.data() + br.begin() * 3, omega.data() + br.begin(), rm->visibility.data() + br.begin() * n2, n2, br.size(),
                rm->indirect.data() + br.begin() * 3, nullptr);
    }
  });
  auto& rec = ctx.record();
  rec.counters["misses"] = static_cast<double>(nm);
  rec.counters["proxies"] = static_cast<double>(all.size());
  rec.counters["pairs"] = static_cast<double>(nm) * static_cast<double>(all.size());
  rec.bytes = (rm->visibility.size() + rm->indirect.size()) * sizeof(float) + nm * 7 * sizeof(float);
  ctx.put<std::shared_ptr<const RobustMisses>>(kRobust, rm);
}

}  // namespace

common::DeviceKernelRegistry<DeviceKernels>& device_kernels() {
  static common::DeviceKernelRegistry<DeviceKernels> r;
  return r;
}

void register_device_kernels(const std::string& backend, DeviceKernels kernels) { device_kernels().add(backend, std::move(kernels)); }

DirectKernels cpu_direct_kernels(render::FramePool* pool) {
  DirectKernels kern;
  kern.surface = [pool](const DirectShader& shader, const render::GBuffer& fine, const Upsampled& up, glm::vec3* e) {
    // Surface pixels in blocks, shaded with O_p interpolated by the eq. 11 weights (section 4.2)
    // inside the kernel.
    const bool shadowed = !up.coarse_visibility.empty();
    const bool lit = shader.shades_lights();
    const std::size_t n2 = static_cast<std::size_t>(shader.order) * shader.order;
    // The coarse samples' transfer rows (common::ShadeTransfer) are interpolated instead of O_p and
    // each pixel takes one dot product, unless the SH product per pixel is asked for. With spherical
    // lights, which read O_p per pixel, the rows carry it.
    const bool transfer = shadowed && shader.interpolate == ShadeInterpolation::Transfer;
    common::ShadeTransfer tr;
    std::vector<float> rows;
    float* rows_base = nullptr;
    if (transfer) {
      tr = common::ShadeTransfer::make(shader.batch(nullptr), lit);
      const std::size_t samples = up.coarse_visibility.size() / n2, m = static_cast<std::size_t>(tr.stride());
      // The rows start on a cache line (rows_base, up to 15 floats into the vector): the kernel reads
      // each row in 64-byte vectors, and a vector's own storage is only 16-byte aligned (malloc),
      // which would split every such load across two lines (about 8 % of shade_direct on `character`
      // at 1024x1024 in the quietest runs, bench/README.md).
      constexpr std::size_t kLine = 64 / sizeof(float);
      rows = pool ? pool->take_for_overwrite<float>(samples * m + kLine) : std::vector<float>(samples * m + kLine);
      const std::size_t misalign = reinterpret_cast<std::uintptr_t>(rows.data()) % 64 / sizeof(float);
      rows_base = rows.data() + (kLine - misalign) % kLine;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples, 1024), [&](const tbb::blocked_range<std::size_t>& br) {
        common::transfer_rows(shader.isa, tr, up.coarse_visibility.data() + br.begin() * n2, br.size(), rows_base + br.begin() * m);
      });
    }
    // Each thread's block buffers, kept across its blocks.
    struct Scratch {
      common::ReceiverSoA soa;
      std::vector<float> g;
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    std::atomic<long long> clamped{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, up.surface.size(), kBlock), [&](const tbb::blocked_range<std::size_t>& br) {
      Scratch& sc = scratch.local();
      common::ReceiverSoA& soa = sc.soa;
      soa.resize(br.size());
      // The positions are read by the spherical lights only.
      for (std::size_t k = br.begin(); k != br.end(); ++k) {
        const std::size_t p = static_cast<std::size_t>(up.surface[k]), j = k - br.begin();
        if (lit) {
          soa.set(j, fine.position[p], fine.normal[p]);
        } else {
          soa.nx[j] = fine.normal[p].x;
          soa.ny[j] = fine.normal[p].y;
          soa.nz[j] = fine.normal[p].z;
        }
      }
      if (!shadowed) {
        clamped += shader.shade(soa, 0, br.size(), static_cast<const float*>(nullptr), e + br.begin());
        return;
      }
      common::BatchShade::Taps taps;
      taps.pixel = up.surface.data() + br.begin();
      taps.index = up.w.index.data();
      taps.weight = up.w.weight.data();
      taps.coarse = transfer ? rows_base : up.coarse_visibility.data();
      if (lit) {
        sc.g.resize(br.size() * n2);
        taps.out = sc.g.data();
      }
      clamped += shader.shade(soa, 0, br.size(), taps, transfer ? &tr : nullptr, e + br.begin());
    });
    if (pool) pool->give(std::move(rows));
    return clamped.load();
  };
  kern.receivers = [](const DirectShader& shader, const common::ReceiverSoA& rec, const float* g, glm::vec3* out) {
    std::atomic<long long> clamped{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rec.size(), kBlock), [&](const tbb::blocked_range<std::size_t>& br) {
      clamped += shader.shade(rec, br.begin(), br.end(), g, out + br.begin());
    });
    return clamped.load();
  };
  return kern;
}

namespace {

// The kernels (k): DirectShader::shade on the CPU, shaders/common/shade.comp on Vulkan.
void pass_shade_direct(State& st, const Settings& s, FrameContext& ctx, const DirectKernels& k) {
  const auto& fine = ctx.get<render::GBuffer>(render::kGBuffer);
  std::shared_ptr<const Upsampled> up_ptr = ctx.get<std::shared_ptr<const Upsampled>>(kUpsampled);
  if (up_ptr->device_visibility && !k.reads_device_visibility) {
    // Host kernels interpolate O_p from its coarse copy: read it back now.
    auto host = std::make_shared<Upsampled>(*up_ptr);
    const auto& occ = *ctx.get<std::shared_ptr<const Field>>(kOcclusion);
    host->coarse_visibility = to_pixels(*ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers), occ.v.data(), occ.channels, ctx.pool());
    host->device_visibility = nullptr;
    up_ptr = host;
  }
  const auto& up = *up_ptr;
  std::shared_ptr<const common::LightLobeTable> lt;
  if (ctx.has(kLightTables)) lt = ctx.get<std::shared_ptr<const common::LightLobeTable>>(kLightTables);
  std::shared_ptr<const RobustMisses> rm;
  if (ctx.has(kRobust)) rm = ctx.get<std::shared_ptr<const RobustMisses>>(kRobust);
  const bool shadowed = !up.coarse_visibility.empty() || up.device_visibility;
  const int n = s.order;
  DirectShader shader = make_direct_shader(env_light(st, ctx.scene, n, s.window_h), n, s.window_h, lt, ctx.posed.lights, s.isa);
  shader.interpolate = s.shade_interpolation;

  // Surface pixels with the eq. 11 interpolation of O_p; the robust misses are shaded apart below.
  // Eq. 10 times the receiver's albedo is the outgoing radiance, written straight to the image:
  // surface pixels from the kernel's output in up.surface order, the robust misses over them, and
  // every other pixel the environment as seen, as the reference draws it (render/vertex_image.hpp).
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const std::size_t np = fine.object.size();
  const std::size_t surface = up.surface.size();
  std::vector<glm::vec3> es = ctx.pool().take_for_overwrite<glm::vec3>(surface);  // k.surface writes every one
  long long clamped = k.surface(shader, fine, up, es.data());
  std::vector<glm::vec3> em;
  if (rm && !rm->pixel.empty()) {
    em.resize(rm->pixel.size());
    clamped += k.receivers(shader, rm->soa, shadowed ? rm->visibility.data() : nullptr, em.data());
  }
  const auto t1 = clock::now();
  Image img = ctx.pool().image_for_overwrite(fine.width, fine.height);
  const render::BackgroundFn background = render::environment_background(ctx.scene.environment);
  // The G-buffer has no view_dir plane (gbuffer_planes): background rays come from the camera.
  const render::PinholeCamera cam = render::make_pinhole_camera(ctx.scene, ctx.width, ctx.height, "image_splat shade_direct");
  const render::BufferRays rays(cam, fine.width, fine.height, fine.scale);
  tbb::parallel_for(tbb::blocked_range<int>(0, fine.height, 4), [&](const tbb::blocked_range<int>& rows) {
    std::vector<glm::vec3> dirs;
    for (int y = rows.begin(); y != rows.end(); ++y) {
      const std::size_t row0 = static_cast<std::size_t>(y) * static_cast<std::size_t>(fine.width);
      // Runs of background pixels, their rays worked out together; runs of surface pixels skipped.
      const std::int32_t* object = &fine.object[row0];
      for (int x = 0; x < fine.width;) {
        const int x1 = render::object_run_end(object, x, fine.width);
        if (object[x] < 0) render::background_run(background, cam, rays, x, y, x1 - x, &img.rgb[row0 + static_cast<std::size_t>(x)], dirs);
        x = x1;
      }
    }
  });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, surface, 4096), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i != br.end(); ++i) {
      const std::size_t p = static_cast<std::size_t>(up.surface[i]);
      img.rgb[p] = es[i] * fine.albedo[p];
    }
  });
  for (std::size_t i = 0; i < em.size(); ++i) {
    const std::size_t p = static_cast<std::size_t>(rm->pixel[i]);
    img.rgb[p] = em[i] * fine.albedo[p];
  }
  ctx.pool().give(std::move(es));
  const auto t2 = clock::now();

  // Section 4.2's cheap fallback: misses take the bilinear interpolation of the shaded coarse receivers.
  std::size_t interpolated = 0;
  if (s.fallback == UpsampleFallback::Shaded && shadowed && ctx.has(kOcclusion) && up.w.misses > 0) {
    const auto& r = *ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
    const auto& occ = *ctx.get<std::shared_ptr<const Field>>(kOcclusion);
    const auto& coarse = ctx.get<render::GBuffer>(render::kReceiverGBuffer);
    std::vector<glm::vec3> ce(r.soa.size());
    k.receivers(shader, r.soa, occ.v.data(), ce.data());
    const std::vector<float> in = to_pixels(r, reinterpret_cast<const float*>(ce.data()), 3, ctx.pool());
    std::vector<float> outv(fine.object.size() * 3);
    for (std::size_t i = 0; i < fine.object.size(); ++i)
      for (int c = 0; c < 3; ++c) outv[3 * i + c] = img.rgb[i][c];
    upsample_apply_bilinear(up.w, plane(coarse), plane(fine), in.data(), 3, outv.data(), &up.w.miss);
    for (std::size_t i = 0; i < fine.object.size(); ++i)
      if (up.w.miss[i] && fine.hit(i)) {
        img.rgb[i] = glm::max(glm::vec3(outv[3 * i], outv[3 * i + 1], outv[3 * i + 2]), glm::vec3(0.0f)) * fine.albedo[i];
        ++interpolated;
      }
  }
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(img.rgb.size());
  rec.counters["surface_pixels"] = static_cast<double>(surface);
  rec.counters["shadowed"] = shadowed;
  rec.counters["lights"] = lt ? static_cast<double>(ctx.posed.lights.size()) : 0.0;
  rec.counters["robust_pixels"] = rm ? static_cast<double>(rm->pixel.size()) : 0.0;
  rec.counters["interpolated_pixels"] = static_cast<double>(interpolated);
  rec.counters["pixels_clamped"] = static_cast<double>(clamped);
  rec.counters["shade_seconds"] = std::chrono::duration<double>(t1 - t0).count();
  rec.counters["image_seconds"] = std::chrono::duration<double>(t2 - t1).count();
  rec.bytes = img.rgb.size() * sizeof(glm::vec3) + np * 6 * sizeof(float);
  ctx.put<Image>(render::kDirect, std::move(img));
}

void pass_shade_indirect(const Settings& s, FrameContext& ctx) {
  const auto& fine = ctx.get<render::GBuffer>(render::kGBuffer);
  const auto& up = *ctx.get<std::shared_ptr<const Upsampled>>(kUpsampled);
  std::shared_ptr<const RobustMisses> rm;
  if (ctx.has(kRobust)) rm = ctx.get<std::shared_ptr<const RobustMisses>>(kRobust);
  const std::size_t np = fine.object.size();
  const bool robust_indirect = rm && !rm->indirect.empty();
  // The upsampled field is read in place; only the shaded fallback changes it, in a copy.
  const bool has_field = up.indirect.size() == np * 3;
  std::vector<float> v;
  const float* field = has_field ? up.indirect.data() : nullptr;
  std::size_t robust = 0, interpolated = 0;
  if (!robust_indirect && s.fallback == UpsampleFallback::Shaded && up.w.misses > 0) {
    // The indirect field is shaded already (I_p . H(N_p) per receiver): bilinear over the coarse receivers.
    if (has_field) {
      v = ctx.pool().take_for_overwrite<float>(np * 3);
      std::copy(up.indirect.begin(), up.indirect.end(), v.begin());
    } else {
      v = ctx.pool().take(np * 3, 0.0f);
    }
    const auto& r = *ctx.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
    const auto& ind = *ctx.get<std::shared_ptr<const Field>>(kIndirectNorm);
    const auto& coarse = ctx.get<render::GBuffer>(render::kReceiverGBuffer);
    const std::vector<float> in = to_pixels(r, ind.v.data(), 3, ctx.pool());
    upsample_apply_bilinear(up.w, plane(coarse), plane(fine), in.data(), 3, v.data(), &up.w.miss);
    for (std::size_t i = 0; i < np; ++i) interpolated += up.w.miss[i] && fine.hit(i);
    field = v.data();
  }
  // Eq. 10's second term, I_p . H(N_p), times the receiver's albedo; SH ringing clamped at 0.
  const auto shade = [&](const glm::vec3& e, std::size_t i) { return glm::max(e, glm::vec3(0.0f)) * fine.albedo[i]; };
  const auto negative = [](const glm::vec3& e) { return e.x < 0.0f || e.y < 0.0f || e.z < 0.0f; };
  Image img = ctx.pool().image_for_overwrite(fine.width, fine.height);
  std::atomic<long long> clamped{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 1 << 14), [&](const tbb::blocked_range<std::size_t>& br) {
    long long neg = 0;
    for (std::size_t i = br.begin(); i != br.end(); ++i) {
      if (!fine.hit(i) || !field) {
        img.rgb[i] = glm::vec3(0.0f);
        continue;
      }
      const glm::vec3 e(field[3 * i], field[3 * i + 1], field[3 * i + 2]);
      neg += negative(e);
      img.rgb[i] = shade(e, i);
    }
    clamped += neg;
  });
  long long neg = clamped.load();
  if (robust_indirect) {
    // The robust misses' own indirect light over the interpolated one (each miss hits a surface).
    for (std::size_t k = 0; k < rm->pixel.size(); ++k) {
      const std::size_t p = static_cast<std::size_t>(rm->pixel[k]);
      const glm::vec3 e(rm->indirect[3 * k], rm->indirect[3 * k + 1], rm->indirect[3 * k + 2]);
      if (field) neg -= negative(glm::vec3(field[3 * p], field[3 * p + 1], field[3 * p + 2]));
      neg += negative(e);
      img.rgb[p] = shade(e, p);
    }
    robust = rm->pixel.size();
  }
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(np);
  rec.counters["robust_pixels"] = static_cast<double>(robust);
  rec.counters["interpolated_pixels"] = static_cast<double>(interpolated);
  rec.counters["pixels_clamped"] = static_cast<double>(neg);
  rec.bytes = img.rgb.size() * sizeof(glm::vec3);
  if (!v.empty()) ctx.pool().give(std::move(v));
  ctx.put<Image>(render::kIndirect, std::move(img));
}

// The frame's large resources (render::Technique::estimate_memory) at display resolution P = w x h
// and receiver resolution C = ceil(w/s) x ceil(h/s), as the passes above and the Vulkan kernels
// (image_splat_vulkan*.cpp, upsample_vulkan.cpp, shade_vulkan.cpp) allocate them. Every pixel is
// taken to hit a surface (receivers = C, surface pixels = P): the bound the scene cannot exceed.
// Left out: tables, the proxy bins (they grow with proxies x tiles), the robust misses (a scene-
// dependent fraction of P) and per-block scratch.
std::vector<render::MemoryItem> memory_items(const render::ParamSet& params, int w, int h) {
  using render::MemoryPlace;
  const Settings s = read_settings(params);
  const std::size_t np = render::pixel_count(w, h);
  const std::size_t nc = render::pixel_count(render::scaled_size(w, s.receiver_scale), render::scaled_size(h, s.receiver_scale));
  const std::size_t f = sizeof(float), i32 = sizeof(std::int32_t), n2 = static_cast<std::size_t>(s.order) * s.order;
  std::vector<render::MemoryItem> m;
  auto host = [&](std::string name, std::size_t bytes, const char* pass, bool transient = false, bool host_only = false) {
    m.push_back({std::move(name), bytes, MemoryPlace::Host, pass, transient, false, host_only});
  };
  auto device = [&](std::string name, std::size_t bytes, const char* pass) {
    m.push_back({std::move(name), bytes, MemoryPlace::Device, pass, false, true, false});
  };
  // Receivers (ReceiverBuffer): SoA position and normal and pixel per receiver, receiver per pixel.
  host(kReceivers, nc * (6 * f + i32) + nc * i32, "receivers");
  host(kLogOcclusion, nc * n2 * f, "accumulate_log", false, true);
  host(kOcclusion, nc * n2 * f, "exponentiate");
  host(kIndirectSums, nc * 4 * f, "accumulate_indirect");
  host(kIndirectNorm, nc * 3 * f, "normalize_indirect");
  // Upsampled: the eq. 11 taps, weights and miss flags per display pixel, the surface pixels, O_p
  // per coarse pixel (when there is O_p), the upsampled indirect shading (when there is indirect).
  host("image_splat.upsample_weights", np * (4 * i32 + 4 * f + 1), "upsample");
  host("image_splat.surface_pixels", np * i32, "upsample");
  host("image_splat.coarse_occlusion", nc * n2 * f, "exponentiate");
  host("image_splat.upsampled_indirect", np * 3 * f, "normalize_indirect");
  host("image_splat upsample input", nc * 3 * f, "upsample", true);
  // Shading: the irradiance of the surface pixels, then the images.
  host("image_splat direct scratch", np * sizeof(glm::vec3), "shade_direct", true);
  host(render::kDirect, render::image_bytes(w, h), "shade_direct");
  host("image_splat indirect scratch", np * 3 * f, "shade_indirect", true);
  host(render::kIndirect, render::image_bytes(w, h), "shade_indirect");
  device("image_splat receivers", nc * 6 * f, "accumulate_log");
  device("image_splat log occlusion", nc * n2 * f, "accumulate_log");
  device("image_splat occlusion", nc * n2 * f, "exponentiate");
  device("image_splat indirect receivers", nc * 6 * f, "accumulate_indirect");
  device("image_splat indirect sums", nc * 4 * f, "accumulate_indirect");
  device("upsample display depth", np * f, "upsample");
  device("upsample display normals", np * 3 * f, "upsample");
  device("upsample receiver depth", nc * f, "upsample");
  device("upsample receiver normals", nc * 3 * f, "upsample");
  device("upsample taps", np * 4 * i32, "upsample");
  device("upsample weights", np * 4 * f, "upsample");
  device("upsample misses", np * 2 * i32, "upsample");
  device("upsample input", nc * 3 * f, "upsample");
  device("upsample output", np * 3 * f, "upsample");
  device("shade receivers", np * 6 * f, "shade_direct");
  device("shade visibility", nc * n2 * f, "shade_direct");
  device("shade tap pixels", np * i32, "shade_direct");
  device("shade tap index", np * 4 * i32, "shade_direct");
  device("shade tap weights", np * 4 * f, "shade_direct");
  device("shading", np * 4 * f, "shade_direct");
  return m;
}

// --- the technique -------------------------------------------------------------------------------

class ImageSplat final : public render::Technique {
 public:
  std::string name() const override { return "image_splat"; }
  // Upsampling and shading read position, normal, depth and albedo; shade_direct derives the
  // background's rays from the camera, so the view_dir plane is left out.
  unsigned gbuffer_planes(const render::ParamSet&) const override { return render::kGBufferSurface | render::kGBufferAlbedo; }
  render::ShadowBlockers shadow_blockers() const override { return render::ShadowBlockers::SphereProxies; }
  std::string description() const override {
    return "image-space proxy accumulation (paper 000, Sloan et al. 2007): sphere proxies splatted to a low-resolution "
           "receiver buffer for SH soft shadows (log accumulation + exponential) and normalised indirect light, "
           "bilateral upsampling to display resolution";
  }
  std::vector<ParamDesc> params() const override { return param_descs(); }

  std::vector<render::ExperimentDef> experiments() const override { return image_splat::experiments(); }

  std::vector<render::MemoryItem> estimate_memory(const scene::Scene&, const render::ParamSet& params, int width,
                                                  int height) const override {
    return memory_items(params, width, height);
  }

  render::PassGraph plan(const scene::Scene& scene, const render::ParamSet& params, std::set<std::string>& empty) override {
    const Settings s = read_settings(params);
    render::add_scene_facts(scene, empty);
    if (scene.lights.empty() || !s.lights) empty.insert(kSphericalLights);
    if (!s.indirect) empty.insert(kIndirectEnabled);

    auto st = state_;
    // Host passes run the same function on every backend; the GPU passes add each registered
    // backend's kernels (a backend's exponential and indirect operator may cover only some methods:
    // the others run the host pass there).
    const auto cpu = render::host_impl;
    const auto kernels = device_kernels().all();
    auto with_kernels = [&kernels, &cpu](render::PassFn host, const std::function<render::PassFn(const DeviceKernels&)>& make) {
      return common::with_kernels<DeviceKernels>(cpu(std::move(host)), kernels, make);
    };
    auto dev_accumulate = [s](const DeviceKernels& k) -> render::PassFn {
      if (s.raster_splats && k.splat_log)
        return [s, f = k.splat_log](FrameContext& c) {
          check_proxies(c);
          common::BlockerList all;
          flat_proxies(c.scene, c.posed, s.order, &all, nullptr);
          const auto& t = *c.get<std::shared_ptr<const ShadowTables>>(kTables);
          f(c, s, t, *c.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers), all, t.support_alpha_shadow, kLogOcclusion);
        };
      if (!k.accumulate_log) return {};
      return [s, f = k.accumulate_log](FrameContext& c) {
        f(c, s, *c.get<std::shared_ptr<const ShadowTables>>(kTables), *c.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers), kBins,
          kLogOcclusion);
      };
    };
    auto dev_exponentiate = [s](const DeviceKernels& k) -> render::PassFn {
      if (!k.exponentiate || !k.exp_supports || !k.exp_supports(s.exp)) return {};
      return [s, f = k.exponentiate](FrameContext& c) {
        f(c, s, *c.get<std::shared_ptr<const ShadowTables>>(kTables), kLogOcclusion, kOcclusion);
      };
    };
    auto dev_accumulate_indirect = [s](const DeviceKernels& k) -> render::PassFn {
      if (!k.accumulate_indirect || !k.indirect_supported) return {};
      const auto splat = s.raster_splats ? k.splat_indirect : nullptr;
      return [s, f = k.accumulate_indirect, splat, ok = k.indirect_supported](FrameContext& c) {
        const auto& ev = *c.get<std::shared_ptr<const IndirectEvaluator>>(kIndirectTables);
        if (!ok(ev.setup().op)) return pass_accumulate_indirect(s, c);
        if (splat) {
          ProxyList all;
          flat_proxies(c.scene, c.posed, s.order, nullptr, &all);
          const double alpha = c.get<std::shared_ptr<const ShadowTables>>(kTables)->support_alpha_indirect;
          c.put<std::shared_ptr<const IndirectSums>>(kIndirectSums, splat(c, *c.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers), all, alpha, ev));
          return;
        }
        c.put<std::shared_ptr<const IndirectSums>>(kIndirectSums, f(c, *c.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers), kBins, ev));
      };
    };
    auto dev_bin = [s](const DeviceKernels& k) -> render::PassFn {
      if (!k.bin_proxies || !s.device_binning) return {};
      return [s, f = k.bin_proxies](FrameContext& c) {
        const BinInputs in = bin_inputs(s, c);
        const auto& r = *c.get<std::shared_ptr<const ReceiverBuffer>>(kReceivers);
        record_bins(c, r, in, f(c, r, in.shadow, in.alpha_shadow, in.indirect, in.alpha_indirect, kBins));
      };
    };
    auto dev_upsample = [s](const DeviceKernels& k) -> render::PassFn {
      if (!k.upsample) return {};
      return [s, f = k.upsample](FrameContext& c) { pass_upsample(s, c, f(c)); };
    };
    auto dev_shade_direct = [st, s](const DeviceKernels& k) -> render::PassFn {
      if (!k.direct) return {};
      return [st, s, f = k.direct](FrameContext& c) { pass_shade_direct(*st, s, c, f(c)); };
    };
    render::PassGraph g;
    g.add_input(render::kScene);
    g.add_input(render::kMovingObjects);
    g.add_input(render::kReradiatingProxies);
    common::blocker_spheres_input("image_splat", s.indirect ? "shadows or indirect light" : "shadows", scene, kBlockerSpheres, g, empty);
    g.add_input(kSphericalLights);
    g.add_input(kIndirectEnabled);
    render::add_gbuffer_pass(g);
    render::add_receiver_gbuffer_pass(g);
    g.add({"tables", {render::kScene, kBlockerSpheres}, {}, {kTables},
           "eta (section 4.1) and the log occlusion ZH table at the shadow order, smoothly clamped at 1/eta",
           cpu([st, s](FrameContext& c) { pass_tables(*st, s, c); })});
    g.add({"indirect_tables", {kTables, render::kReradiatingProxies, kIndirectEnabled}, {}, {kIndirectTables},
           "indirect operator tables (V, D or M, clamped at 1/eta_indirect) and L~ (section 5)",
           cpu([st, s](FrameContext& c) { pass_indirect_tables(*st, s, c); })});
    g.add({"light_tables", {kSphericalLights}, {}, {kLightTables}, "L_H(theta, f) single-lobe ZH table (paper 004 section 7)",
           cpu([st, s](FrameContext& c) { pass_light_tables(*st, s, c); })});
    g.add({"receivers", {render::kReceiverGBuffer}, {}, {kReceivers}, "receiver-buffer hits ordered by screen tile, per-tile AABB",
           cpu([s](FrameContext& c) { pass_receivers(s, c); })});
    g.add({"bin_proxies", {kReceivers, kTables, kBlockerSpheres}, {kIndirectTables}, {kBins},
           "per tile, the proxies whose sphere of influence reaches it (coverage oracle, section 4.1)",
           with_kernels([s](FrameContext& c) { pass_bin(s, c); }, dev_bin)});
    g.add({"accumulate_log", {kReceivers, kTables, kBins}, {}, {kLogOcclusion},
           "sum of proxy log occlusion vectors per receiver (eq. 4; SHEXP kernel and replacement rules)",
           with_kernels([s](FrameContext& c) { pass_accumulate_log(s, c); }, dev_accumulate)});
    g.add({"exponentiate", {kTables, kLogOcclusion}, {}, {kOcclusion}, "O_p = exp of the accumulated log occlusion (eq. 4, HYB)",
           with_kernels([s](FrameContext& c) { pass_exponentiate(s, c); }, dev_exponentiate)});
    g.add({"accumulate_indirect", {kReceivers, kBins, kIndirectTables}, {}, {kIndirectSums},
           "sum of I_i . H(N_p) and omega_i per receiver (section 5, eqs. 13-17)",
           with_kernels([s](FrameContext& c) { pass_accumulate_indirect(s, c); }, dev_accumulate_indirect)});
    auto dev_normalize = [s](const DeviceKernels& k) -> render::PassFn {
      if (!k.field_dc) return {};
      return [s, f = k.field_dc](FrameContext& c) { pass_normalize_indirect(s, c, f); };
    };
    g.add({"normalize_indirect", {kIndirectSums}, {kOcclusion}, {kIndirectNorm}, "xi_p = (1 - O_p)_0 / (omega_p / sqrt(4 pi)) (eq. 12)",
           with_kernels([s](FrameContext& c) { pass_normalize_indirect(s, c); }, dev_normalize)});
    g.add({"upsample", {render::kGBuffer, render::kReceiverGBuffer, kReceivers}, {kOcclusion, kIndirectNorm}, {kUpsampled},
           s.upsample.mode == UpsampleMode::Bilateral ? "bilateral upsampling of O_p and the indirect shading (section 4.2, eq. 11)"
                                                      : "bilinear upsampling of O_p and the indirect shading (Figure 7)",
           with_kernels([s](FrameContext& c) { pass_upsample(s, c, cpu_upsample_kernels(&c.pool())); }, dev_upsample)});
    if (s.fallback == UpsampleFallback::Robust)
      g.add({"robust_misses", {render::kGBuffer, kUpsampled, kTables}, {kIndirectTables}, {kRobust},
             "display pixels no coarse sample matches, accumulated from the full proxy list (section 4.2)",
             cpu([s](FrameContext& c) { pass_robust(s, c); })});
    std::vector<std::string> opt_direct = {kLightTables, kReceivers, kOcclusion};
    std::vector<std::string> opt_indirect = {kReceivers};
    if (s.fallback == UpsampleFallback::Robust) {
      opt_direct.push_back(kRobust);
      opt_indirect.push_back(kRobust);
    }
    g.add({"shade_direct", {render::kGBuffer, render::kReceiverGBuffer, kUpsampled}, opt_direct, {render::kDirect},
           "psi_p's first term O_p . L~(N_p) (eq. 10) and spherical lights, times the albedo",
           with_kernels([st, s](FrameContext& c) { pass_shade_direct(*st, s, c, cpu_direct_kernels(&c.pool())); }, dev_shade_direct)});
    g.add({"shade_indirect", {render::kGBuffer, render::kReceiverGBuffer, kUpsampled, kIndirectNorm}, opt_indirect, {render::kIndirect},
           "psi_p's second term I_p . H(N_p) (eq. 10), times the albedo", cpu([s](FrameContext& c) { pass_shade_indirect(s, c); })});
    render::add_compose_pass(g);
    return g;
  }

 private:
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

}  // namespace

std::unique_ptr<render::Technique> create() { return std::make_unique<ImageSplat>(); }

}  // namespace softgi::techniques::image_splat
