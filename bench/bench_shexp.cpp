// SHEXP (paper 004) measurements, each side by side in one run (docs/techniques/shexp.md):
//  - BM_FmaPeak: this machine's FMA peak (an FMA-bound loop vectorised across both cores);
//  - BM_StreamTriad: this machine's memory bandwidth (a STREAM triad, bandwidth.hpp), the reference
//    of the display-resolution passes' shares (gbuffer, to_image, compose in BM_Frame);
//  - BM_Kernel/<order>/<isa>: the accumulation kernel's receiver-blocker pairs per second, achieved
//    GFLOP/s and share of that peak;
//  - BM_Products/<order>/<isa>/<0 squares, 1 products>: the batched SH squares and products, GFLOP/s
//    and share of that peak;
//  - BM_Figure8/<order>: SHEXP-HYB and -PS*-2 against product-space accumulation, 200 x 200 ground
//    vertices and 60 spheres, no hierarchy (paper Figure 8: 3.4x at n = 4, 11x at n = 6);
//  - BM_Figure9: product space, PS-21, OL, HYB, PS*-2 on the bunny (63 fitted spheres, 128 x 128
//    ground): time and error against product space;
//  - BM_Figure7/<scene>: errors of (b) ray traced with sphere blockers, (c) product space n = 4,
//    (d) SHEXP n = 4, (e) SHEXP accumulated at n = 6 and shaded at n = 4 against (a) ray traced with
//    the real geometry, all under order-4 SH lighting;
//  - BM_CrowdHierarchy: hierarchy with ratio vectors against the flat list on `crowd`;
//  - BM_Frame/<scene>/<backend>: whole frames on the CPU or Vulkan backend (`--backend`), the
//    accumulation passes' pairs per second, GFLOP/s and share of the FMA peak, and the display
//    passes' bytes moved (a lower bound) and share of the triad bandwidth (frame_bench.hpp);
//    BM_Frame/<scene>/<backend>/no_pool the same with the backend's frame pool off.
// GCC 12 reports its own AVX-512 intrinsics as maybe uninitialised (see techniques/common/kernel.cpp).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <immintrin.h>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <tbb/parallel_for.h>

#include "../techniques/shexp/shexp_internal.hpp"
#include "fma_peak.hpp"
#include "frame_bench.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/proxies/sphere_fit.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/registry.hpp"

namespace {

using namespace softgi;
namespace sx = softgi::techniques::shexp;

// --- FMA peak (bench/fma_peak.hpp) ----------------------------------------------------------

using softgi::bench::fma_gflops;
using softgi::bench::peak_gflops;

using softgi::bench::BM_FmaPeak;
BENCHMARK(BM_FmaPeak)->Arg(1)->Arg(2)->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();
using softgi::bench::BM_StreamTriad;
BENCHMARK(BM_StreamTriad)->Arg(1)->Arg(2)->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();

// --- the accumulation kernel --------------------------------------------------------------------

// 64k receivers on a 256 x 256 ground grid in clusters of 256 consecutive vertices (16 x 16 tiles),
// 60 blocker spheres, continuous replacement rules: the accumulate_log pass's inner loop. Geometry
// 0: the spheres float above the ground (Figure 8; the rules' fast path); 1: every sphere straddles
// the ground plane (the rules run for every pair).
void BM_Kernel(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto isa = static_cast<sx::KernelIsa>(state.range(1));
  const bool straddling = state.range(2) != 0;
  if (!sx::kernel_isa_supported(isa)) {
    state.SkipWithError("this CPU cannot run this kernel");
    return;
  }
  sh::TableOptions o;
  o.order = order;
  o.measure_error = false;
  sh::ShTables tables(o);
  const sx::ZhTable t = sx::make_zh_table(tables.cap_log(), order, true);
  constexpr int kSide = 256;
  sx::ReceiverSoA rec;
  rec.resize(kSide * kSide);
  std::size_t at = 0;
  for (int ty = 0; ty < kSide / 16; ++ty)
    for (int tx = 0; tx < kSide / 16; ++tx)
      for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
          rec.set(at++, glm::vec3(8.0f * ((tx * 16 + x) / float(kSide) - 0.5f), 0.0f, 8.0f * ((ty * 16 + y) / float(kSide) - 0.5f)),
                  glm::vec3(0.0f, 1.0f, 0.0f));
  sx::BlockerList b;
  b.order = order;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 60; ++i) {
    const float r = 0.1f + 0.1f * std::abs(u(rng));
    b.push(glm::vec3(1.5f * u(rng), straddling ? 0.5f * r * u(rng) : 1.0f + 0.7f * u(rng), 1.5f * u(rng)), r, nullptr);
  }
  std::vector<float> out(rec.size() * order * order);
  const int clusters = kSide * kSide / 256;
  const double peak = peak_gflops();
  double secs = 0.0;
  for (auto _ : state) {
    auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(0, clusters, [&](int c) {
      sx::accumulate_log(isa, t, sx::ReplacementRule::Continuous, rec, static_cast<std::size_t>(c) * 256,
                         static_cast<std::size_t>(c + 1) * 256, b, out.data());
    });
    benchmark::DoNotOptimize(out.data());
    secs += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const double pairs = static_cast<double>(rec.size()) * b.size() * static_cast<double>(state.iterations());
  const double fpp = sx::kernel_flops_per_pair(order, sx::ReplacementRule::Continuous, straddling);
  const double gflops = pairs * fpp / secs * 1e-9;
  state.counters["Mpairs/s"] = pairs / secs * 1e-6;
  state.counters["GFLOP/s"] = gflops;
  state.counters["flops/pair"] = fpp;
  state.counters["peak_GFLOP/s"] = peak;
  state.counters["share_of_peak"] = gflops / peak;
  state.SetLabel(std::string(sx::to_string(isa)) + (straddling ? " straddling" : " above"));
}

// --- batched SH squares and products -----------------------------------------------------------

// square_batch / product_batch (the exponentials' squarings and the shading's products) over 65536
// vectors of random coefficients in [-0.5, 0.5], on both cores in runs of 1024; arg 2: 0 squares,
// 1 products. Flops per vector from the plan: a square's term is a multiply and a multiply-add (3),
// a product's off-diagonal term two multiply-adds and a multiply (5) and its diagonal term 3, and
// each output sums its four partial sums (3); the transposes into and out of the lanes are timed
// but not counted.
void BM_Products(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto isa = static_cast<sx::KernelIsa>(state.range(1));
  const bool product = state.range(2) != 0;
  if (!sx::kernel_isa_supported(isa)) {
    state.SkipWithError("this CPU cannot run this kernel");
    return;
  }
  const int n2 = order * order;
  constexpr std::size_t kVectors = 65536, kRun = 1024;
  std::vector<float> f(kVectors * n2), g(kVectors * n2), out(kVectors * n2);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  for (float& v : f) v = u(rng);
  for (float& v : g) v = u(rng);
  const sx::ProductPlan& p = sx::ProductPlan::get(order);
  double flops = 3.0 * n2;
  for (int i = 0; i < n2; ++i) {
    const int terms = p.sq_begin[i + 1] - p.sq_begin[i], off = p.pr_offdiag_end[i] - p.pr_begin[i];
    flops += product ? 5.0 * off + 3.0 * (terms - off) : 3.0 * terms;
  }
  const double peak = peak_gflops();
  double secs = 0.0;
  for (auto _ : state) {
    auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(std::size_t{0}, kVectors / kRun, [&](std::size_t r) {
      const std::size_t at = r * kRun * n2;
      if (product)
        sx::product_batch(isa, order, f.data() + at, g.data() + at, out.data() + at, kRun);
      else
        sx::square_batch(isa, order, f.data() + at, out.data() + at, kRun);
    });
    benchmark::DoNotOptimize(out.data());
    secs += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const double vectors = static_cast<double>(kVectors) * static_cast<double>(state.iterations());
  const double gflops = vectors * flops / secs * 1e-9;
  state.counters["Mvectors/s"] = vectors / secs * 1e-6;
  state.counters["GFLOP/s"] = gflops;
  state.counters["flops/vector"] = flops;
  state.counters["peak_GFLOP/s"] = peak;
  state.counters["share_of_peak"] = gflops / peak;
  state.SetLabel(std::string(sx::to_string(isa)) + (product ? " products" : " squares"));
}

// --- scenes -------------------------------------------------------------------------------------

scene::Mesh grid_mesh(int n, float size) {
  scene::Mesh m;
  m.name = "ground";
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      m.positions.emplace_back(size * (i / float(n - 1) - 0.5f), 0.0f, size * (j / float(n - 1) - 0.5f));
      m.normals.emplace_back(0.0f, 1.0f, 0.0f);
    }
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      unsigned a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      m.triangles.push_back({a, c, b});
      m.triangles.push_back({b, c, d});
    }
  return m;
}

// Paper 004 Figure 8's setting: a 200 x 200-vertex ground plane shadowed by 60 spheres (a loose
// figure-sized group 0.2..2 m above it); the spheres are the blockers of the ground node itself.
scene::Scene figure8_scene() {
  scene::Scene s;
  s.name = "figure8";
  s.source = "bench:figure8";
  s.materials.push_back(scene::Material{});
  s.meshes.push_back(grid_mesh(200, 6.0f));
  scene::Node g;
  g.name = "ground";
  g.mesh = 0;
  s.nodes.push_back(g);
  scene::ProxySet ps;
  ps.name = "spheres";
  ps.node = 0;
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 60; ++i)
    ps.spheres.push_back({glm::vec3(0.6f * u(rng), 1.1f + 0.8f * u(rng), 0.6f * u(rng)), 0.08f + 0.1f * std::abs(u(rng))});
  s.proxies.push_back(ps);
  s.camera.position = {0.0f, 5.0f, 5.0f};
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.width = 128;
  s.camera.height = 128;
  return s;
}

struct Timed {
  render::FrameResult frame;
  double visibility = 0.0;  // accumulate_log + exponentiate, or product_accumulate
  double products = 0.0, squares = 0.0;
  std::size_t table_bytes = 0, buffer_bytes = 0;
};

Timed render_timed(render::Technique& t, const scene::Scene& s, const std::vector<std::string>& params, double time = 0.0,
                   int width = 0, int height = 0) {
  render::Backend& cpu = softgi::bench::backend_named(render::reference_backend_name());
  render::ParamSet p = render::default_params(t);
  for (const auto& a : params) p.set_assignment(a);
  render::RenderRequest req;
  req.time = time;
  req.width = width;
  req.height = height;
  Timed r;
  r.frame = cpu.render(t, s, p, req);
  for (const auto& pass : r.frame.passes) {
    if (pass.name == "accumulate_log" || pass.name == "exponentiate" || pass.name == "product_accumulate") r.visibility += pass.wall_seconds;
    if (pass.counters.count("products")) r.products += pass.counters.at("products");
    if (pass.counters.count("squares")) r.squares += pass.counters.at("squares");
    if (pass.name == "tables" || pass.name == "light_tables") r.table_bytes += pass.bytes;
    else r.buffer_bytes += pass.bytes;
  }
  return r;
}

// --- Figure 8 -----------------------------------------------------------------------------------

// Speedup of log-space accumulation over product space, both vectorised across receivers the same
// way (kernel=auto), and both scalar (kernel=scalar): visibility passes (accumulate_log +
// exponentiate against product_accumulate) and whole frames.
void BM_Figure8(benchmark::State& state) {
  softgi::bench::register_builtin();
  const int order = static_cast<int>(state.range(0));
  const scene::Scene s = figure8_scene();
  const std::string o = "order=" + std::to_string(order);
  struct Method {
    std::string name;
    std::vector<std::string> params;
    std::unique_ptr<render::Technique> tech;
    double vis = 0.0, frame = 0.0;
    Timed last;
  };
  std::vector<Method> m;
  for (const auto& [name, extra] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"hyb", {"exp=hyb"}}, {"psstar", {"exp=ps*"}}, {"product", {"exp=product"}},
           {"hyb_scalar", {"exp=hyb", "kernel=scalar"}}, {"product_scalar", {"exp=product", "kernel=scalar"}}}) {
    Method x;
    x.name = name;
    x.params = {o, "hierarchy=false", "window_h=0", "analytic_lights=false"};
    x.params.insert(x.params.end(), extra.begin(), extra.end());
    x.tech = render::create_technique("shexp");
    render_timed(*x.tech, s, x.params);  // first frame: tables and clusters (cached afterwards)
    m.push_back(std::move(x));
  }
  for (auto _ : state)
    for (auto& x : m) {
      x.last = render_timed(*x.tech, s, x.params);
      x.vis += x.last.visibility;
      x.frame += x.last.frame.total_seconds;
    }
  const double it = static_cast<double>(state.iterations());
  for (const auto& x : m) state.counters[x.name + "_vis_ms"] = x.vis / it * 1e3;
  for (const auto& pass : m[0].last.frame.passes)
    if (pass.name == "accumulate_log" || pass.name == "exponentiate") state.counters["hyb_" + pass.name + "_ms"] = pass.wall_seconds * 1e3;
  state.counters["speedup_hyb"] = m[2].vis / m[0].vis;
  state.counters["speedup_psstar"] = m[2].vis / m[1].vis;
  state.counters["speedup_hyb_scalar"] = m[4].vis / m[3].vis;
  state.counters["frame_speedup_hyb"] = m[2].frame / m[0].frame;
  state.counters["frame_speedup_psstar"] = m[2].frame / m[1].frame;
  state.counters["frame_speedup_hyb_scalar"] = m[4].frame / m[3].frame;
  state.counters["products_per_receiver"] = m[2].last.products / 40000.0;
  state.counters["table_bytes"] = static_cast<double>(m[0].last.table_bytes);
  state.counters["buffer_bytes"] = static_cast<double>(m[0].last.buffer_bytes);
}

// --- Figure 9 -----------------------------------------------------------------------------------

// The built-in bunny scene (128 x 128 ground) with a 63-sphere fit, as paper 004 Figure 9 (nS = 63).
const scene::Scene* bunny63(std::string& why) {
  static scene::Scene s;
  static std::string error;
  static bool done = false;
  if (!done) {
    done = true;
    try {
      s = scene::make_builtin("bunny");
      for (auto& ps : s.proxies) {
        const scene::Node& node = s.nodes[ps.node];
        proxies::FitOptions opt;
        opt.spheres = 63;
        ps.spheres = proxies::fit_sphere_set(proxies::trimesh_of(s.meshes[node.mesh]), opt).spheres;
        ps.joints.clear();
        ps.weights.clear();
      }
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  why = error;
  return error.empty() ? &s : nullptr;
}

double vertex_rel_rmse(const render::FrameResult& a, const render::FrameResult& ref) {
  double se = 0.0, mean = 0.0;
  std::size_t n = 0;
  for (std::size_t o = 0; o < ref.vertex_radiance.size(); ++o)
    for (std::size_t v = 0; v < ref.vertex_radiance[o].size(); ++v) {
      const glm::vec3 d = a.vertex_radiance[o][v] - ref.vertex_radiance[o][v];
      se += glm::dot(d, d) / 3.0;
      mean += (ref.vertex_radiance[o][v].x + ref.vertex_radiance[o][v].y + ref.vertex_radiance[o][v].z) / 3.0;
      ++n;
    }
  return n ? std::sqrt(se / n) / (mean / n) : 0.0;
}

void BM_Figure9(benchmark::State& state) {
  softgi::bench::register_builtin();
  std::string why;
  const scene::Scene* s = bunny63(why);
  if (!s) {
    state.SkipWithError(("bunny needs the asset set (scripts/fetch-assets.sh): " + why).c_str());
    return;
  }
  const std::vector<std::pair<std::string, std::vector<std::string>>> methods = {
      {"product", {"exp=product"}}, {"ps21", {"exp=ps", "ps_degree=21"}}, {"ol", {"exp=ol"}}, {"hyb", {"exp=hyb"}}, {"psstar2", {"exp=ps*", "ps_degree=2"}}};
  std::vector<std::unique_ptr<render::Technique>> techs;
  for (std::size_t i = 0; i < methods.size(); ++i) techs.push_back(render::create_technique("shexp"));
  auto params = [&](std::size_t i) {
    std::vector<std::string> v = {"order=4", "hierarchy=false", "window_h=0", "analytic_lights=false"};
    v.insert(v.end(), methods[i].second.begin(), methods[i].second.end());
    return v;
  };
  const double t = 0.0;
  for (std::size_t i = 0; i < methods.size(); ++i) render_timed(*techs[i], *s, params(i), t);
  std::vector<double> vis(methods.size(), 0.0);
  std::vector<Timed> last(methods.size());
  for (auto _ : state)
    for (std::size_t i = 0; i < methods.size(); ++i) {
      last[i] = render_timed(*techs[i], *s, params(i), t);
      vis[i] += last[i].visibility;
    }
  const double it = static_cast<double>(state.iterations());
  std::size_t receivers = 0;
  for (const auto& v : last[0].frame.vertex_radiance) receivers += v.size();
  state.counters["receivers"] = static_cast<double>(receivers);
  for (std::size_t i = 0; i < methods.size(); ++i) {
    const std::string& m = methods[i].first;
    state.counters[m + "_ms"] = vis[i] / it * 1e3;
    state.counters[m + "_speedup"] = vis[0] / vis[i];
    state.counters[m + "_products"] = last[i].products;
    state.counters[m + "_squares"] = last[i].squares;
    if (i > 0) state.counters[m + "_relrmse_vs_product"] = vertex_rel_rmse(last[i].frame, last[0].frame);
  }
}

// --- Figure 7 -----------------------------------------------------------------------------------

// A technique that only runs the G-buffer and writes a 1/0 surface mask into `direct`: the error
// measures count surface pixels only (vertex_image.hpp: backgrounds differ by convention).
class MaskTechnique : public render::Technique {
 public:
  std::string name() const override { return "mask"; }
  std::string description() const override { return "G-buffer coverage"; }
  std::vector<render::ParamDesc> params() const override { return {}; }
  render::PassGraph plan(const scene::Scene&, const render::ParamSet&, std::set<std::string>&) override {
    render::PassGraph g;
    render::add_gbuffer_pass(g);
    render::PassDesc p{"mask", {render::kGBuffer}, {}, {render::kDirect}, "", {}};
    p.impl[render::kHostImpl] = [](render::FrameContext& ctx) {
      const auto& gb = ctx.get<render::GBuffer>(render::kGBuffer);
      Image m(gb.width, gb.height);
      for (std::size_t i = 0; i < m.rgb.size(); ++i) m.rgb[i] = glm::vec3(gb.object[i] >= 0 ? 1.0f : 0.0f);
      ctx.result.direct = m;
      ctx.put<Image>(render::kDirect, std::move(m));
    };
    g.add(std::move(p));
    return g;
  }
};

void BM_Figure7(benchmark::State& state) {
  softgi::bench::register_builtin();
  const std::string name = state.range(0) == 0 ? "spheres" : "bunny";
  scene::Scene s;
  try {
    s = scene::make_builtin(name);
  } catch (const std::exception& e) {
    state.SkipWithError((name + ": " + e.what()).c_str());
    return;
  }
  // 1024 samples per pixel keep the reference's Monte Carlo noise (reported as a_noise: two seeds
  // against each other) below the differences being measured.
  constexpr int kW = 256, kH = 192, kSpp = 1024;
  const double t = 0.5;
  render::Backend& cpu = softgi::bench::backend_named(render::reference_backend_name());
  MaskTechnique mt;
  render::RenderRequest mreq;
  mreq.time = t;
  mreq.width = kW;
  mreq.height = kH;
  mreq.outputs = {"direct"};
  const Image maskimg = cpu.render(mt, s, render::ParamSet{}, mreq).direct;
  Mask mask;
  mask.width = kW;
  mask.height = kH;
  for (const auto& px : maskimg.rgb) mask.on.push_back(px.x > 0.5f ? 1 : 0);

  for (auto _ : state) {
    reference::ReferenceOptions ro;
    ro.spp = kSpp;
    ro.light_sh_order = 4;
    ro.indirect = false;
    ro.time = t;
    ro.width = kW;
    ro.height = kH;
    ro.jitter = false;  // the visibility a one-sample-per-pixel G-buffer sees
    const Image a = reference::render_reference(s, ro).direct;
    ro.seed = 2;
    const Image a2 = reference::render_reference(s, ro).direct;
    ro.seed = 1;
    ro.blockers = reference::ReferenceOptions::Blockers::Proxies;
    const Image b = reference::render_reference(s, ro).direct;
    auto shexp = [&](const std::vector<std::string>& extra) {
      auto tech = render::create_technique("shexp");
      std::vector<std::string> p = {"order=4", "window_h=0", "hierarchy=false"};
      p.insert(p.end(), extra.begin(), extra.end());
      return render_timed(*tech, s, p, t, kW, kH).frame.direct;
    };
    const Image c = shexp({"exp=product"});
    const Image d = shexp({"exp=ps*"});
    const Image dh = shexp({"exp=hyb"});
    const Image e = shexp({"exp=ps*", "accumulation_order=6"});
    const Image eh = shexp({"exp=hyb", "accumulation_order=6"});
    const Image f = shexp({"exp=projected"});
    auto put = [&](const std::string& key, const Image& x, const Image& ref) {
      const metrics::Metrics m = metrics::compare(x, ref, mask);
      state.counters[key + "_relmse"] = m.relmse;
      state.counters[key + "_rmse"] = m.rmse;
      state.counters[key + "_ssim"] = m.ssim;
    };
    put("a_noise", a2, a);
    put("b_raytraced_spheres", b, a);
    put("c_product4", c, a);
    put("d_shexp4_psstar", d, a);
    put("d_shexp4_hyb", dh, a);
    put("e_acc6_shade4_psstar", e, a);
    put("e_acc6_shade4_hyb", eh, a);
    put("d_vs_c", d, c);
    put("f_projected4", f, a);  // the exact sphere visibility projected to order 4: the floor of (c)-(e)
  }
  state.SetLabel(name);
}

// --- hierarchy on crowd ------------------------------------------------------------------------

void BM_CrowdHierarchy(benchmark::State& state) {
  softgi::bench::register_builtin();
  const scene::Scene s = scene::make_builtin("crowd");
  auto flat = render::create_technique("shexp"), hier = render::create_technique("shexp");
  const std::vector<std::string> pf = {"hierarchy=false"}, ph = {"hierarchy=true"};
  const double t = 1.0;
  render_timed(*flat, s, pf, t, 256, 192);
  render_timed(*hier, s, ph, t, 256, 192);
  double tf = 0, th = 0, cf = 0, ch = 0;
  Timed a, b;
  for (auto _ : state) {
    a = render_timed(*flat, s, pf, t, 256, 192);
    b = render_timed(*hier, s, ph, t, 256, 192);
    tf += a.visibility;
    th += b.visibility;
    for (const auto& p : a.frame.passes)
      if (p.name == "blocker_cut") cf += p.wall_seconds;
    for (const auto& p : b.frame.passes)
      if (p.name == "blocker_cut") ch += p.wall_seconds;
  }
  const double it = static_cast<double>(state.iterations());
  state.counters["flat_ms"] = (tf + cf) / it * 1e3;
  state.counters["hier_ms"] = (th + ch) / it * 1e3;
  state.counters["hier_cut_ms"] = ch / it * 1e3;
  for (const auto& p : a.frame.passes)
    if (p.name == "accumulate_log") state.counters["flat_blockers_mean"] = p.counters.at("blockers_per_receiver_mean");
  for (const auto& p : b.frame.passes)
    if (p.name == "accumulate_log") {
      state.counters["hier_blockers_mean"] = p.counters.at("blockers_per_receiver_mean");
      state.counters["hier_blockers_max"] = p.counters.at("blockers_per_receiver_max");
    }
  state.counters["vertex_relrmse"] = vertex_rel_rmse(b.frame, a.frame);
  const metrics::Metrics m = metrics::compare(b.frame.direct, a.frame.direct);
  state.counters["image_relmse"] = m.relmse;
  state.counters["image_ssim"] = m.ssim;
}

// --- whole frames on both backends ----------------------------------------------------------------

// SHEXP with its default parameters (HYB, order 4, hierarchy cuts) on a built-in scene at 512 x 512,
// one frame per iteration 1/30 s apart, on the CPU or the Vulkan backend (`--backend`,
// frame_bench.hpp): accumulate_log's pairs per second, GFLOP/s and share of the FMA peak with
// kernel_flops_per_pair (the GLSL kernel follows the CPU kernel's arithmetic), exponentiate's
// receivers per second and GFLOP/s (its squares and products). Manual time: the two passes' walls.
// pool = false: the backend's frame pool off (every frame allocates its buffers), for the
// before/after of the display passes in one run.
void BM_Frame(benchmark::State& state, const std::string& scene_name, const std::string& backend, bool pool) {
  constexpr int kFrameSide = 512;  // docs/backends.md's timing table
  constexpr double kStep = 1.0 / 30.0;
  render::Backend* be = softgi::bench::backend_or_skip(state, backend);
  if (!be) return;
  be->frame_pool().set_mode(pool ? render::FramePool::Mode::On : render::FramePool::Mode::Off);
  struct Restore {
    render::Backend* be;
    ~Restore() { be->frame_pool().set_mode(render::FramePool::Mode::On); }
  } restore{be};
  const scene::Scene sc = scene::make_builtin(scene_name);
  auto tech = render::create_technique("shexp");
  const render::ParamSet params = render::default_params(*tech);
  softgi::bench::FlopModel fm;
  const int acc = params.get_int("accumulation_order");
  fm.acc_order = acc == 0 ? params.get_int("order") : acc;
  fm.rule = params.get_bool("self_shadow_rules") ? sx::parse_replacement_rule(params.get_enum("replacement_rule")) : sx::ReplacementRule::Off;
  render::RenderRequest req;
  req.width = req.height = kFrameSide;
  req.time = 0.0;
  try {
    be->recycle(be->render(*tech, sc, params, req));  // warm-up: tables, clusters, hierarchy, pipelines
  } catch (const std::exception& e) {
    state.SkipWithError((std::string("shexp failed: ") + e.what()).c_str());
    return;
  }
  std::map<std::string, softgi::bench::PassSums> sums;
  std::map<std::string, double> wall, moved;  // every pass, for the display passes' bandwidth
  double frame = 0.0, bvh = 0.0, trace = 0.0, resolve = 0.0;  // the CPU G-buffer's split: BVH update, trace, resolve
  for (auto _ : state) {
    req.time += kStep;
    render::FrameResult r = be->render(*tech, sc, params, req);
    for (const auto& p : r.passes) {
      wall[p.name] += p.wall_seconds;
      if (const auto c = p.counters.find("bytes_moved"); c != p.counters.end()) moved[p.name] += c->second;
      if (p.name != "gbuffer") continue;
      if (const auto c = p.counters.find("bvh_update_seconds"); c != p.counters.end()) bvh += c->second;
      if (const auto c = p.counters.find("visibility_seconds"); c != p.counters.end()) trace += c->second;
      if (const auto c = p.counters.find("resolve_seconds"); c != p.counters.end()) resolve += c->second;
    }
    double t = 0.0;
    for (const auto& p : r.passes)
      if (p.name == "accumulate_log" || p.name == "exponentiate") {
        sums[p.name].add(p);
        t += p.wall_seconds;
      }
    frame += r.total_seconds;
    state.SetIterationTime(t);
    be->recycle(std::move(r));
  }
  if (sums["accumulate_log"].pairs <= 0.0) {
    state.SkipWithError("the frame ran no accumulate_log pass with pairs (pass names or counters changed?)");
    return;
  }
  state.counters["frame_ms"] = frame / static_cast<double>(state.iterations()) * 1e3;
  if (trace > 0.0) {
    state.counters["gbuffer_bvh_ms"] = bvh / static_cast<double>(state.iterations()) * 1e3;
    state.counters["gbuffer_trace_ms"] = trace / static_cast<double>(state.iterations()) * 1e3;
    state.counters["gbuffer_resolve_ms"] = resolve / static_cast<double>(state.iterations()) * 1e3;
  }
  state.counters["receivers"] = sums["accumulate_log"].receivers / static_cast<double>(state.iterations());
  softgi::bench::Row base;
  base.bench = "shexp";
  base.scene = scene_name;
  base.technique = "shexp";
  base.backend = backend;
  if (!pool) base.variant = "(no frame pool)";
  softgi::bench::report_passes(state, sums, fm, base);
  softgi::bench::report_display_passes(state, wall, moved, static_cast<int>(state.iterations()), kFrameSide, kFrameSide, base);
}

}  // namespace


BENCHMARK(BM_Kernel)
    ->ArgsProduct({{3, 4, 5, 6, 8}, {static_cast<long>(sx::KernelIsa::Avx512)}, {0, 1}})
    ->Args({4, static_cast<long>(sx::KernelIsa::Avx2), 0})
    ->Args({4, static_cast<long>(sx::KernelIsa::Scalar), 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Products)
    ->ArgsProduct({{3, 4, 5, 6, 8}, {static_cast<long>(sx::KernelIsa::Avx512)}, {0, 1}})
    ->Args({4, static_cast<long>(sx::KernelIsa::Avx2), 0})
    ->Args({4, static_cast<long>(sx::KernelIsa::Scalar), 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Figure8)->Arg(4)->Arg(6)->Iterations(5)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_Figure9)->Iterations(5)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_Figure7)->Arg(0)->Arg(1)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_CrowdHierarchy)->Iterations(3)->Unit(benchmark::kSecond)->UseRealTime();

// --backend=cpu|vulkan|both (default both), parsed before benchmark::Initialize: BM_Frame/<scene>/<backend>
// on `character` and `crowd`.
int main(int argc, char** argv) {
  return softgi::bench::frame_bench_main(argc, argv, [](const std::vector<std::string>& backends) {
    for (const std::string scene : {"character", "crowd"})
      for (const auto& b : backends)
        for (const bool pool : {false, true})
          benchmark::RegisterBenchmark(("BM_Frame/" + scene + "/" + b + (pool ? "" : "/no_pool")).c_str(),
                                       [=](benchmark::State& st) { BM_Frame(st, scene, b, pool); })
              ->Iterations(5)
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond);
  });
}
