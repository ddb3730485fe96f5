// SHEXP (paper 004, Ren et al. 2006) as a render::Technique: parameters, pass graph and the CPU
// implementation of every pass. docs/techniques/shexp.md describes the graph and the measurements.
#include "softgi/techniques/shexp.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "shexp_internal.hpp"
#include "shexp_passes.hpp"
#include "../common/device_kernels.hpp"
#include "../common/pass_support.hpp"
#include "../common/receivers.hpp"
#include "../common/shared_params.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/vertex_image.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::techniques::shexp {

std::vector<render::ExperimentDef> experiments();  // shexp_experiments.cpp

Settings read_settings(const render::ParamSet& p) {
  Settings s;
  s.order = p.get_int("order");
  const int acc = p.get_int("accumulation_order");
  if (acc != 0 && acc < s.order)
    throw std::invalid_argument("parameter 'accumulation_order': " + std::to_string(acc) + " is below order " +
                                std::to_string(s.order) + " (expected 0 or a value in [order, 8])");
  s.acc_order = acc == 0 ? s.order : acc;
  const std::string& e = p.get_enum("exp");
  s.mode = e == "hyb" ? Mode::HYB : e == "ol" ? Mode::OL : e == "ps*" ? Mode::PSStar : e == "ps" ? Mode::PS : e == "exact" ? Mode::Exact
         : e == "product" ? Mode::Product : Mode::Projected;
  s.ps_degree = p.get_int("ps_degree");
  s.hierarchy = p.get_bool("hierarchy") && s.mode != Mode::Product && s.mode != Mode::Projected;
  s.ratio_vectors = p.get_bool("ratio_vectors");
  s.theta_max = p.get_float("theta_max_deg") * sh::kPi / 180.0;
  s.theta_min = p.get_float("theta_min_deg") * sh::kPi / 180.0;
  if (s.theta_min >= s.theta_max)
    throw std::invalid_argument("parameter 'theta_min_deg': " + p.get_text("theta_min_deg") +
                                " must be below theta_max_deg = " + p.get_text("theta_max_deg"));
  s.clusters = p.get_int("receiver_clusters");
  s.window_h = common::params::read_window_h(p, s.order);
  s.window_visibility = p.get_bool("window_visibility");
  s.rule = common::params::read_replacement_rule(p);
  s.table_resolution = p.get_int("table_resolution");
  s.log_threshold = p.get_float("log_threshold");
  s.lights = p.get_bool("analytic_lights");
  s.isa = common::params::read_kernel(p);
  return s;
}

// Blockers each receiver processes (mean and max): the cut of its cluster.
void blocker_counters(render::PassRecord& rec, const Receivers& r, const Cuts& cuts, double& pairs) {
  pairs = 0.0;
  std::size_t mx = 0;
  for (std::size_t c = 0; c < r.clusters.size(); ++c) {
    const std::size_t n = cuts.lists[cuts.list_of_cluster[c]].size();
    pairs += static_cast<double>(n) * static_cast<double>(r.clusters[c].end - r.clusters[c].begin);
    if (r.clusters[c].end > r.clusters[c].begin) mx = std::max(mx, n);
  }
  const double nrec = static_cast<double>(r.soa.size());
  rec.counters["receivers"] = nrec;
  rec.counters["pairs"] = pairs;
  rec.counters["blockers_per_receiver_mean"] = nrec > 0 ? pairs / nrec : 0.0;
  rec.counters["blockers_per_receiver_max"] = static_cast<double>(mx);
}

namespace {

using render::FrameContext;
using render::ParamDesc;
using render::PassDesc;


// --- State kept across frames ----------------------------------------------------------------

struct State {
  std::mutex m;
  common::SharedCache<std::tuple<int, int, double>, Tables> tables;
  common::LightTableCache light_tables;
  // Sphere hierarchies, built at the first frame's pose, refit by proxy_update.
  std::string hierarchy_key;
  std::vector<std::unique_ptr<proxies::SphereHierarchy>> trees;
  double hierarchy_build_seconds = 0.0;
  common::ReceiverClustering receivers;
  // Environment SH.
  std::string env_key;
  std::vector<glm::vec3> env_sh;
};


// The hierarchy options SHEXP builds with (paper 004 section 6.3: branching 4).
proxies::HierarchyBuildOptions hierarchy_options() { return proxies::HierarchyBuildOptions{}; }

// 64-bit FNV-1a over 32-bit words in four independent lanes (x, y, z, radius of each sphere, so
// that the multiplications do not wait on each other). Every step is a bijection of the lane's
// state, so sets that differ in one word always get different hashes; sets that differ in several
// collide with probability about 2^-64.
class SphereHash {
 public:
  void word(std::uint32_t w, int lane = 0) { h_[lane] = (h_[lane] ^ w) * kPrime; }
  void spheres(const std::vector<scene::Sphere>& set) {
    word(static_cast<std::uint32_t>(set.size()));
    for (const scene::Sphere& sp : set) {
      word(std::bit_cast<std::uint32_t>(sp.center.x), 0);
      word(std::bit_cast<std::uint32_t>(sp.center.y), 1);
      word(std::bit_cast<std::uint32_t>(sp.center.z), 2);
      word(std::bit_cast<std::uint32_t>(sp.radius), 3);
    }
  }
  std::uint64_t value() const {
    std::uint64_t v = h_[0];
    for (int l = 1; l < 4; ++l) v = (v ^ h_[l]) * kPrime;
    return v;
  }

 private:
  static constexpr std::uint64_t kPrime = 1099511628211ull;
  std::uint64_t h_[4] = {14695981039346656037ull, 14695981039346656037ull ^ 1, 14695981039346656037ull ^ 2,
                         14695981039346656037ull ^ 3};
};

// What the trees depend on: the build options and every set's rest-pose spheres, node and skin
// binding (all of them: an edit anywhere in a set must rebuild). Animated scenes refit the trees to
// each frame's spheres (proxy_update), so their pose is not part of the key; a static scene runs
// no refit and uses the bounds as built, so its posed spheres are (an edited node transform must
// rebuild too).
std::string hierarchy_signature(const scene::Scene& scene, const scene::PosedScene& posed, const proxies::HierarchyBuildOptions& opt) {
  SphereHash h;
  for (const auto& p : scene.proxies) {
    h.word(static_cast<std::uint32_t>(p.node));
    h.spheres(p.spheres);
    h.word(static_cast<std::uint32_t>(p.joints.size()));
    for (const glm::u16vec4& j : p.joints) {
      h.word(static_cast<std::uint32_t>(j.x) | static_cast<std::uint32_t>(j.y) << 16);
      h.word(static_cast<std::uint32_t>(j.z) | static_cast<std::uint32_t>(j.w) << 16);
    }
    h.word(static_cast<std::uint32_t>(p.weights.size()));
    for (const glm::vec4& w : p.weights)
      for (int c = 0; c < 4; ++c) h.word(std::bit_cast<std::uint32_t>(w[c]));
  }
  std::set<std::string> empty;
  render::add_scene_facts(scene, empty);
  const bool refit_per_frame = empty.count(render::kMovingObjects) == 0;
  if (!refit_per_frame)
    for (const auto& set : posed.proxies) h.spheres(set);
  std::ostringstream os;
  os << "sets " << scene.proxies.size() << " posed " << !refit_per_frame << " branching " << opt.branching << " max_children "
     << opt.max_children << " lloyd " << opt.lloyd_iterations << " fit " << opt.fit_evaluations << " hash " << std::hex
     << h.value();
  return os.str();
}

glm::vec3 vertex_albedo(const scene::Scene& scene, const scene::PosedObject& o, std::size_t v) {
  glm::vec3 a(0.8f);
  if (o.material >= 0 && o.material < static_cast<int>(scene.materials.size())) {
    const scene::Material& m = scene.materials[o.material];
    a = m.albedo;
    if (m.albedo_texture >= 0 && m.albedo_texture < static_cast<int>(scene.textures.size()) && o.source &&
        v < o.source->uvs.size())
      a *= scene.textures[m.albedo_texture].sample(o.source->uvs[v]);
  }
  if (o.source && v < o.source->colors.size()) a *= o.source->colors[v];
  return a;
}


// --- Passes ------------------------------------------------------------------------------------

void pass_tables(State& st, const Settings& s, FrameContext& ctx) {
  bool cached = false;
  const std::shared_ptr<const Tables> t = st.tables.get(
      std::make_tuple(s.acc_order, s.table_resolution, s.log_threshold),
      [&s] {
        auto tab = std::make_shared<Tables>();
        tab->acc_order = s.acc_order;
        tab->sh = common::accumulation_tables(s.acc_order, s.table_resolution, s.log_threshold);
        tab->log = make_zh_table(tab->sh->cap_log(), s.acc_order, true);
        tab->vis = make_zh_table(tab->sh->cap_visibility(), s.acc_order, false);
        return std::shared_ptr<const Tables>(tab);
      },
      cached);
  auto& rec = ctx.record();
  rec.counters["order"] = s.acc_order;
  rec.counters["rows"] = s.table_resolution;
  rec.counters["cached"] = cached;
  rec.counters["table_bytes_used"] = static_cast<double>(t->bytes_used());
  rec.bytes = t->sh->bytes() + t->log.bytes() + t->vis.bytes();
  ctx.put<std::shared_ptr<const Tables>>(kTables, t);
}

void pass_light_tables(State& st, const Settings& s, FrameContext& ctx) { st.light_tables.run_pass(s.order, s.window_h, ctx, kLightTables); }

// Blocker spheres must be finite with radius >= 0: a bad one would turn every receiver's log vector
// into NaN. The error names the proxy set and the sphere.
void check_proxies(const FrameContext& ctx) { common::check_proxy_spheres("shexp", ctx, false); }

void pass_hierarchy(State& st, FrameContext& ctx) {
  const proxies::HierarchyBuildOptions opt = hierarchy_options();
  const std::string key = hierarchy_signature(ctx.scene, ctx.posed, opt);
  bool cached = true;
  std::lock_guard<std::mutex> lock(st.m);
  if (st.hierarchy_key != key) {
    cached = false;
    auto t0 = std::chrono::steady_clock::now();
    st.trees.clear();
    check_proxies(ctx);
    for (const auto& set : ctx.posed.proxies) {
      if (set.empty()) {
        st.trees.push_back(nullptr);
        continue;
      }
      st.trees.push_back(std::make_unique<proxies::SphereHierarchy>(proxies::SphereHierarchy::build(set, opt)));
    }
    st.hierarchy_key = key;
    st.hierarchy_build_seconds = common::seconds_since(t0);
  }
  auto res = std::make_shared<HierarchyRes>();
  std::size_t nodes = 0, leaves = 0;
  int depth = 0;
  for (const auto& t : st.trees) {
    res->trees.push_back(t.get());
    if (!t) continue;
    nodes += t->nodes().size();
    depth = std::max(depth, t->depth());
    for (const auto& nd : t->nodes()) leaves += nd.children.empty();
  }
  auto& rec = ctx.record();
  rec.counters["cached"] = cached;
  rec.counters["trees"] = static_cast<double>(res->trees.size());
  rec.counters["leaves"] = static_cast<double>(leaves);
  rec.counters["nodes"] = static_cast<double>(nodes);
  rec.counters["depth"] = depth;
  rec.counters["build_seconds"] = st.hierarchy_build_seconds;
  rec.bytes = nodes * sizeof(proxies::SphereNode);
  ctx.put<std::shared_ptr<const HierarchyRes>>(kHierarchy, res);
}

void pass_proxy_update(State& st, FrameContext& ctx) {
  check_proxies(ctx);
  std::lock_guard<std::mutex> lock(st.m);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < st.trees.size() && i < ctx.posed.proxies.size(); ++i) {
    if (!st.trees[i]) continue;
    st.trees[i]->update(ctx.posed.proxies[i]);  // section 6.3: bottom-up sphere-pair refit
    moved += ctx.posed.proxies[i].size();
  }
  ctx.record().counters["spheres"] = static_cast<double>(moved);
  ctx.put<int>(kProxyPose, 1);
}

void pass_receivers(State& st, const Settings& s, FrameContext& ctx) {
  common::warn_coarse_receivers("shexp", ctx);
  auto r = st.receivers.update("shexp", ctx, s.clusters);
  ctx.record().bytes = r->bytes();
  ctx.put<std::shared_ptr<const Receivers>>(kReceivers, r);
}

void pass_cut(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  auto cuts = std::make_shared<Cuts>();
  const int nc = static_cast<int>(r.clusters.size());
  CutStats total;
  if (s.hierarchy) {
    const auto& h = *ctx.get<std::shared_ptr<const HierarchyRes>>(kHierarchy);
    CutOptions opt;
    opt.theta_max = s.theta_max;
    opt.theta_min = s.theta_min;
    opt.ratio_vectors = s.ratio_vectors;
    cuts->lists.resize(nc);
    cuts->list_of_cluster.resize(nc);
    tbb::combinable<CutStats> stats;
    tbb::parallel_for(0, nc, [&](int c) {
      const ReceiverCluster& rc = r.clusters[c];
      cuts->lists[c] = make_cut(h.trees, ctx.posed.proxies, t.log, rc.centre, rc.radius, rc.star, opt, &stats.local());
      cuts->list_of_cluster[c] = c;
    });
    stats.combine_each([&](const CutStats& cs) { total += cs; });
  } else {
    check_proxies(ctx);
    cuts->lists.push_back(flat_list(ctx.posed.proxies, t.acc_order));
    cuts->list_of_cluster.assign(nc, 0);
  }
  auto& rec = ctx.record();
  rec.counters["clusters"] = nc;
  rec.counters["hierarchy"] = s.hierarchy;
  rec.counters["cut_mean"] = cuts->mean_size();
  rec.counters["cut_max"] = static_cast<double>(cuts->max_size());
  rec.counters["leaves_in_cuts"] = static_cast<double>(total.leaves);
  rec.counters["inner_in_cuts"] = static_cast<double>(total.inner);
  rec.counters["nodes_visited"] = static_cast<double>(total.nodes_visited);
  rec.counters["detail_spheres"] = static_cast<double>(total.detail_spheres);
  rec.bytes = cuts->bytes();
  ctx.put<std::shared_ptr<const Cuts>>(kCuts, cuts);
}


void pass_accumulate(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& cuts = *ctx.get<std::shared_ptr<const Cuts>>(kCuts);
  auto f = std::make_shared<Field>();
  f->order = t.acc_order;
  const std::size_t n2 = static_cast<std::size_t>(f->order) * f->order;
  f->v.assign(r.soa.size() * n2, 0.0f);
  auto t0 = std::chrono::steady_clock::now();
  // One task per receiver cluster: its receivers share the cut, 16 (or 8) at a time (kernel.cpp).
  tbb::parallel_for(tbb::blocked_range<int>(0, static_cast<int>(r.clusters.size()), 1), [&](const tbb::blocked_range<int>& cr) {
    for (int c = cr.begin(); c != cr.end(); ++c) {
      const ReceiverCluster& rc = r.clusters[c];
      accumulate_log(s.isa, t.log, s.rule, r.soa, rc.begin, rc.end, cuts.lists[cuts.list_of_cluster[c]], f->v.data());
    }
  });
  const double secs = common::seconds_since(t0);
  auto& rec = ctx.record();
  double pairs = 0.0;
  blocker_counters(rec, r, cuts, pairs);
  // Flops of the rules' fast path (spheres in front of the tangent plane): a lower bound where the rules run.
  const double fpp = kernel_flops_per_pair(f->order, s.rule);
  rec.counters["kernel_lanes"] = kernel_lanes(s.isa);
  rec.counters["flops_per_pair"] = fpp;
  rec.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  rec.counters["gflops"] = secs > 0.0 ? pairs * fpp / secs * 1e-9 : 0.0;
  rec.bytes = f->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kLogVisibility, f);
}

void pass_exponentiate(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& f = *ctx.get<std::shared_ptr<const Field>>(kLogVisibility);
  auto g = std::make_shared<Field>();
  g->order = s.order;
  const int na = f.order, n2a = na * na, n2 = s.order * s.order;
  g->v.assign(r.soa.size() * n2, 0.0f);
  sh::ExpOptions opt;
  opt.method = s.mode == Mode::HYB ? sh::ExpMethod::HYB
               : s.mode == Mode::OL ? sh::ExpMethod::OL
               : s.mode == Mode::PSStar ? sh::ExpMethod::PSStar
               : s.mode == Mode::PS ? sh::ExpMethod::PS
                                    : sh::ExpMethod::Exact;
  opt.degree = s.ps_degree;
  tbb::combinable<sh::ExpStats> stats;
  const bool batched = exp_batch_supports(opt.method);
  BatchExp be;
  be.order = na;
  be.method = opt.method;
  be.degree = opt.degree;
  be.tables = t.sh.get();
  be.plan = &ProductPlan::get(na);
  // Blocks of 256 receivers (a multiple of every lane count): HYB, OL, PS* and PS run batched across
  // receivers (kernel.cpp), the exact exponential per receiver through sh::exp.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.soa.size(), 256), [&](const tbb::blocked_range<std::size_t>& br) {
    std::vector<float> out(br.size() * n2a);
    auto& st = stats.local();
    try {
      if (batched) {
        exp_batch(s.isa, be, f.v.data() + br.begin() * n2a, out.data(), br.size(), br.begin(), st);
      } else {
        for (std::size_t i = br.begin(); i != br.end(); ++i)
          sh::exp<float>(na, f.v.data() + i * n2a, out.data() + (i - br.begin()) * n2a, opt, t.sh.get(), &st);
      }
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string("shexp exponentiate (receivers of objects ") + std::to_string(r.object[br.begin()]) + ".." +
                               std::to_string(r.object[br.end() - 1]) + "): " + e.what());
    }
    // Figure 7e: accumulated and exponentiated at order na, truncated to the shading order.
    for (std::size_t i = br.begin(); i != br.end(); ++i)
      std::copy(out.begin() + (i - br.begin()) * n2a, out.begin() + (i - br.begin()) * n2a + n2, g->v.begin() + i * n2);
  });
  sh::ExpStats total;
  stats.combine_each([&](const sh::ExpStats& e) {
    total.squarings += e.squarings;
    total.squares += e.squares;
    total.products += e.products;
  });
  auto& rec = ctx.record();
  const double nrec = static_cast<double>(r.soa.size());
  rec.counters["receivers"] = nrec;
  rec.counters["squarings"] = total.squarings;
  rec.counters["squares"] = total.squares;
  rec.counters["products"] = total.products;
  rec.counters["squarings_per_receiver"] = nrec > 0 ? total.squarings / nrec : 0.0;
  rec.bytes = g->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kVisibility, g);
}

void pass_product(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& cuts = *ctx.get<std::shared_ptr<const Cuts>>(kCuts);
  const int na = t.acc_order, n2a = na * na, n2 = s.order * s.order;
  std::vector<float> acc(r.soa.size() * n2a, 0.0f);
  std::atomic<long long> products{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, static_cast<int>(r.clusters.size()), 1), [&](const tbb::blocked_range<int>& cr) {
    for (int c = cr.begin(); c != cr.end(); ++c) {
      const ReceiverCluster& rc = r.clusters[c];
      products += accumulate_product_batch(s.isa, t.vis, s.rule, r.soa, rc.begin, rc.end, cuts.lists[cuts.list_of_cluster[c]], acc.data());
    }
  });
  auto g = std::make_shared<Field>();
  g->order = s.order;
  g->v.assign(r.soa.size() * n2, 0.0f);
  for (std::size_t i = 0; i < r.soa.size(); ++i)
    std::copy(acc.begin() + i * n2a, acc.begin() + i * n2a + n2, g->v.begin() + i * n2);
  auto& rec = ctx.record();
  double pairs = 0.0;
  blocker_counters(rec, r, cuts, pairs);
  rec.counters["products"] = static_cast<double>(products.load());
  rec.bytes = (acc.size() + g->v.size()) * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kVisibility, g);
}

// Quadrature bands of the projected-visibility mode: 4n + 8 bands (2 (4n + 8)^2 directions, 1152 at
// n = 4) resolve the binary visibility's order-n projection of one sphere to 0.07 in reconstruction
// at worst (max over directions, caps of 1 to 60 degrees, n = 3..6; the binary cap edge is what the
// quadrature misses), measured by ShexpSingleSphere.ProjectedVisibilityIsTheCapVisibility.
void pass_projected(const Settings& s, FrameContext& ctx) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& cuts = *ctx.get<std::shared_ptr<const Cuts>>(kCuts);
  auto g = std::make_shared<Field>();
  g->order = s.order;
  const int n2 = s.order * s.order;
  g->v.assign(r.soa.size() * n2, 0.0f);
  tbb::parallel_for(tbb::blocked_range<int>(0, static_cast<int>(r.clusters.size()), 1), [&](const tbb::blocked_range<int>& cr) {
    for (int c = cr.begin(); c != cr.end(); ++c) {
      const ReceiverCluster& rc = r.clusters[c];
      project_visibility(s.order, 4 * s.order + 8, s.rule, r.soa, rc.begin, rc.end, cuts.lists[cuts.list_of_cluster[c]], g->v.data());
    }
  });
  auto& rec = ctx.record();
  double pairs = 0.0;
  blocker_counters(rec, r, cuts, pairs);
  rec.counters["directions"] = 2.0 * (4 * s.order + 8) * (4 * s.order + 8);
  rec.bytes = g->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(kVisibility, g);
}

// kernel: a backend's shading of the receivers -- (H(N) * g) . L, the analytic lights and the clamp
// (common::vulkan_shade, shaders/common/shade.comp); null: the host's. The light and the per-vertex
// results around it are the same host code.
void pass_shade(State& st, const Settings& s, FrameContext& ctx, const common::ShadeKernel* kernel = nullptr) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const int n = s.order, n2 = n * n;
  // A device kernel reads the visibility where the GPU exponential left it: no host copy is made.
  const bool shadowed = ctx.has(kVisibility);
  const bool vis_on_device = kernel && shadowed && ctx.is_deferred(kVisibility);
  std::shared_ptr<const Field> vis;
  if (shadowed && !vis_on_device) vis = ctx.get<std::shared_ptr<const Field>>(kVisibility);
  std::shared_ptr<const LightLobeTable> lt;
  if (ctx.has(kLightTables)) lt = ctx.get<std::shared_ptr<const LightLobeTable>>(kLightTables);

  auto sh_out = std::make_shared<Shading>();
  sh_out->order = n;
  {
    const std::string key = common::environment_signature(ctx.scene.environment) + std::to_string(n) + '|' + std::to_string(s.window_h);
    std::lock_guard<std::mutex> lock(st.m);
    if (st.env_key != key) {
      st.env_sh = common::windowed_environment_sh("shexp", ctx.scene, n, s.window_h);
      st.env_key = key;
    }
    sh_out->env = st.env_sh;
  }
  std::array<std::vector<float>, 3> L;
  for (int c = 0; c < 3; ++c) {
    L[c].resize(n2);
    for (int i = 0; i < n2; ++i) L[c][i] = sh_out->env[i][c];
  }
  // (L, H(N), g) = (H(N) * g) . L (eq. 9 and the triple-product identity of section 3): one SH
  // product per receiver serves all three colour channels; batched across receivers (kernel.cpp).
  std::vector<float> Lflat(3 * n2), hcoef(n2), gwin(n2, 1.0f);
  const std::vector<double> cc = sh::clamped_cosine_zh(n);
  for (int l = 0; l < n; ++l)
    for (int m = -l; m <= l; ++m) {
      const int k = sh::index(l, m);
      hcoef[k] = static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / sh::kPi);
      if (shadowed && s.window_visibility && s.window_h > 0.0) gwin[k] = static_cast<float>(sh::window_factor(l, s.window_h));
    }
  for (int c = 0; c < 3; ++c) std::copy(L[c].begin(), L[c].end(), Lflat.begin() + c * n2);
  const BatchShade bs = BatchShade::make(n, Lflat.data(), hcoef.data(), gwin.data(), vis ? vis->v.data() : nullptr);
  std::vector<glm::vec3> shade(r.soa.size());
  long long clamped = 0;
  if (kernel) {
    // The whole shading on the device: product, spherical lights and the clamp.
    GpuShade in{&bs, lt.get(), &ctx.posed.lights, false, nullptr};
    if (vis_on_device) in.visibility_resource = kVisibility;
    clamped = (*kernel)(ctx, in, r.soa, shade.data());
  } else {
    std::atomic<long long> cl{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.soa.size(), 256), [&](const tbb::blocked_range<std::size_t>& br) {
      shade_batch(s.isa, bs, r.soa, br.begin(), br.end(), shade.data() + br.begin());
      cl += add_lights_and_clamp(s.isa, lt.get(), ctx.posed.lights, n, gwin.data(), r.soa, br.begin(), br.end(), bs.g, false,
                                 shade.data() + br.begin());
    });
    clamped = cl.load();
  }

  const scene::PosedScene& posed = ctx.posed;
  sh_out->irradiance.resize(posed.objects.size());
  std::vector<std::vector<glm::vec3>> radiance(posed.objects.size());
  for (std::size_t o = 0; o < posed.objects.size(); ++o) {
    const auto& obj = posed.objects[o];
    sh_out->irradiance[o].resize(obj.positions.size());
    radiance[o].resize(obj.positions.size());
    for (std::size_t v = 0; v < obj.positions.size(); ++v) {
      const glm::vec3 e = shade[r.index[o][v]];
      sh_out->irradiance[o][v] = e;
      radiance[o][v] = e * vertex_albedo(ctx.scene, obj, v);
    }
  }
  ctx.result.vertex_radiance = std::move(radiance);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(r.soa.size());
  rec.counters["shadowed"] = shadowed ? 1.0 : 0.0;
  rec.counters["lights"] = lt ? static_cast<double>(ctx.posed.lights.size()) : 0.0;
  rec.counters["vertices_clamped"] = static_cast<double>(clamped);
  rec.bytes = r.soa.size() * 2 * sizeof(glm::vec3);
  ctx.put<std::shared_ptr<const Shading>>(kShading, sh_out);
}

void pass_to_image(FrameContext& ctx) {
  const auto& gb = ctx.get<render::GBuffer>(render::kGBuffer);
  const auto& shading = *ctx.get<std::shared_ptr<const Shading>>(kShading);
  // Background: the environment as seen, the function the reference draws its background with.
  const render::BackgroundFn bg = render::environment_background(ctx.scene.environment);
  // Irradiance is interpolated per vertex (section 8: vertex-rate shading); albedo is per pixel, so
  // textures keep their detail.
  // The G-buffer holds the visibility planes only (gbuffer_planes): albedo and the background's ray
  // directions are derived here, in the one pass over the pixels.
  const render::PinholeCamera cam = render::make_pinhole_camera(ctx.scene, ctx.width, ctx.height, "to_image");
  Image img = render::interpolate_vertex_values(gb, ctx.posed, shading.irradiance, bg,
                                                ctx.pool().image_for_overwrite(gb.width, gb.height), true,
                                                render::DerivedPlanes{&ctx.scene, &cam});
  const std::size_t np = img.rgb.size();
  auto& rec = ctx.record();
  rec.counters["pixels"] = static_cast<double>(np);
  rec.bytes = np * sizeof(glm::vec3);
  ctx.put<Image>(render::kDirect, std::move(img));
}

// --- The technique ----------------------------------------------------------------------------

common::DeviceKernelRegistry<DeviceKernels>& device_kernels() {
  static common::DeviceKernelRegistry<DeviceKernels> r;
  return r;
}

// The frame's large resources (render::Technique::estimate_memory): per vertex of the scene V and
// per display pixel, as the passes above and the Vulkan kernels (shexp_vulkan.cpp, shade_vulkan.cpp)
// allocate them. Left out: tables, hierarchies and cuts (they grow with the blockers, not with the
// frame), and per-block scratch.
std::vector<render::MemoryItem> memory_items(const scene::Scene& scene, const render::ParamSet& params, int w, int h) {
  using render::MemoryPlace;
  const Settings s = read_settings(params);
  const std::size_t v = render::scene_vertex_count(scene), f = sizeof(float);
  const std::size_t n2 = static_cast<std::size_t>(s.order) * s.order, n2a = static_cast<std::size_t>(s.acc_order) * s.acc_order;
  const char* vis_pass = s.mode == Mode::Projected ? "project_visibility" : s.mode == Mode::Product ? "product_accumulate" : "exponentiate";
  std::vector<render::MemoryItem> m;
  auto host = [&](std::string name, std::size_t bytes, const char* pass, bool transient = false, bool host_only = false) {
    m.push_back({std::move(name), bytes, MemoryPlace::Host, pass, transient, false, host_only});
  };
  auto device = [&](std::string name, std::size_t bytes, const char* pass) {
    m.push_back({std::move(name), bytes, MemoryPlace::Device, pass, false, true, false});
  };
  // Receivers: SoA position and normal, object, vertex and index; the clusters kept for the next
  // frame (assignment and last positions), and Lloyd's assignment while it runs.
  host(kReceivers, v * (6 * f + 3 * sizeof(int)), "receiver_setup");
  host("shexp receiver clusters", v * (sizeof(int) + sizeof(glm::vec3)), "receiver_setup");
  host("shexp Lloyd assignment", v * sizeof(int), "receiver_setup", true);
  host(kLogVisibility, v * n2a * f, "accumulate_log", false, true);
  host(kVisibility, v * n2 * f, vis_pass, false, true);
  if (s.mode == Mode::Product) host("shexp product accumulator", v * n2a * f, "product_accumulate", true);
  // Shading: the per-receiver result while it is scattered, irradiance and radiance per vertex.
  host("shexp shade scratch", v * sizeof(glm::vec3), "shade", true);
  host(kShading, v * sizeof(glm::vec3), "shade");
  host("vertex radiance", v * sizeof(glm::vec3), "shade");
  // The direct image (the frame result takes it over when the frame ends, a move, not a copy).
  host(render::kDirect, render::image_bytes(w, h), "to_image");
  device("shexp receivers", v * 6 * f, "accumulate_log");
  device("shexp log vectors", v * n2a * f, "accumulate_log");
  device("shexp visibility", v * n2 * f, "exponentiate");
  device("shade receivers", v * 6 * f, "shade");
  device("shading", v * 4 * f, "shade");
  return m;
}

class Shexp final : public render::Technique {
 public:
  std::string name() const override { return "shexp"; }
  render::ShadowBlockers shadow_blockers() const override { return render::ShadowBlockers::SphereProxies; }
  std::string description() const override {
    return "SHEXP (paper 004, Ren et al. 2006): soft shadows of sphere-set blockers under low-frequency light by "
           "accumulating log visibility in SH and exponentiating; per-vertex receivers; no indirect light";
  }
  std::vector<ParamDesc> params() const override {
    std::vector<ParamDesc> d;
    // Quality ladder (softgi report): the SH order bounds the shadows' sharpness (paper 004 section 7),
    // theta_max_deg how far the hierarchy cut coarsens distant blockers (eq. 36).
    d.push_back(common::params::order(4, "lighting, visibility and shading").with_ladder({"3", "4", "5", "6"}));
    d.push_back(ParamDesc::integer("accumulation_order", 0, 0, kMaxAccOrder,
                                   "order at which blockers are accumulated and exponentiated before truncation to "
                                   "`order` (0 = order; Figure 7e: 6 with order 4)"));
    d.push_back(common::params::exp({"hyb", "ol", "ps*", "ps", "exact", "product", "projected"},
                                    "SH exponential (section 4.3; exact = eq. 28, slow), or product = product-space "
                                    "accumulation of Zhou et al. 2005 (eq. 6, the baseline), or projected = order-n "
                                    "projection of the exact sphere visibility (quadrature, for error analysis)"));
    d.push_back(ParamDesc::integer("ps_degree", 2, 1, 30, "series degree p of ps* and ps (PS*-2, PS-21 in Figure 9)"));
    d.push_back(common::params::hierarchy("sphere hierarchy cuts per receiver cluster (section 6.3); product ignores it"));
    d.push_back(common::params::theta_max_deg().with_ladder({"40", "30", "25", "15"}));
    d.push_back(ParamDesc::real("theta_min_deg", 0.0, 0.0, 30.0,
                                "detail pruning: f_d stops at nodes subtending less than this at p* (0 = every leaf)"));
    d.push_back(ParamDesc::boolean("ratio_vectors", true, "eq. 37 ratio vectors on cut nodes (off: Figure 6b)"));
    d.push_back(common::params::receiver_clusters());
    d.push_back(common::params::window_h());
    d.push_back(ParamDesc::boolean("window_visibility", true, "window the visibility vector too (section 7), not only the light"));
    d.push_back(common::params::self_shadow_rules());
    d.push_back(common::params::replacement_rule());
    d.push_back(common::params::table_resolution());
    d.push_back(common::params::log_threshold());
    d.push_back(common::params::analytic_lights());
    d.push_back(common::params::kernel());
    return d;
  }

  std::vector<render::ExperimentDef> experiments() const override { return shexp::experiments(); }

  std::vector<render::MemoryItem> estimate_memory(const scene::Scene& scene, const render::ParamSet& params, int width,
                                                  int height) const override {
    return memory_items(scene, params, width, height);
  }

  // to_image reads the visibility planes and derives albedo and the background's ray directions
  // itself: the other planes, most of the G-buffer's cost at display resolution, are left out.
  unsigned gbuffer_planes(const render::ParamSet&) const override { return render::kGBufferVisibility; }
  render::PassGraph plan(const scene::Scene& scene, const render::ParamSet& params, std::set<std::string>& empty) override {
    const Settings s = read_settings(params);
    render::add_scene_facts(scene, empty);
    if (scene.lights.empty() || !s.lights) empty.insert(kSphericalLights);

    auto st = state_;
    // Host passes run the same function on every backend (tables, receivers, hierarchy, cuts and
    // image composition); the GPU passes add each registered backend's kernels.
    const auto cpu = render::host_impl;
    const auto kernels = device_kernels().all();
    render::PassGraph g;
    g.add_input(render::kScene);
    g.add_input(render::kMovingObjects);
    common::blocker_spheres_input("shexp", "shadows", scene, kBlockerSpheres, g, empty);
    g.add_input(kSphericalLights);
    // SHEXP has no indirect pass: compose reads the indirect image optionally, as an empty input.
    g.add_input(render::kIndirect);
    empty.insert(render::kIndirect);
    render::add_gbuffer_pass(g);
    g.add({"tables", {render::kScene, kBlockerSpheres}, {}, {kTables},
           "cap log / visibility ZH and OL tables at the accumulation order only (section 6.1, eq. 24)",
           cpu([st, s](FrameContext& c) { pass_tables(*st, s, c); })});
    g.add({"light_tables", {kSphericalLights}, {}, {kLightTables}, "L_H(theta, f) single-lobe ZH table (section 7)",
           cpu([st, s](FrameContext& c) { pass_light_tables(*st, s, c); })});
    g.add({"receiver_setup", {render::kScene}, {}, {kReceivers},
           "per-vertex receivers of every posed object, Lloyd receiver clusters (section 6.3)",
           cpu([st, s](FrameContext& c) { pass_receivers(*st, s, c); })});
    std::vector<std::string> cut_reads = {kReceivers, kTables, kBlockerSpheres}, cut_opt;
    if (s.hierarchy) {
      g.add({"hierarchy_build", {render::kScene, kBlockerSpheres}, {}, {kHierarchy},
             "sphere hierarchy per proxy set, built once (section 6.3)", cpu([st](FrameContext& c) { pass_hierarchy(*st, c); })});
      g.add({"proxy_update", {kHierarchy, render::kMovingObjects}, {}, {kProxyPose},
             "refit the hierarchies to this frame's proxies (section 6.3, Animation)",
             cpu([st](FrameContext& c) { pass_proxy_update(*st, c); })});
      cut_reads.push_back(kHierarchy);
      cut_opt.push_back(kProxyPose);
    }
    g.add({"blocker_cut", cut_reads, cut_opt, {kCuts},
           s.hierarchy ? "per receiver cluster: eq. 36 cut and eq. 37 ratio vectors at p*" : "flat list of every leaf sphere",
           cpu([s](FrameContext& c) { pass_cut(s, c); })});
    if (s.mode == Mode::Projected) {
      g.add({"project_visibility", {kReceivers, kCuts}, {}, {kVisibility},
             "order-n projection of the exact binary visibility of the spheres (quadrature; error analysis)",
             cpu([s](FrameContext& c) { pass_projected(s, c); })});
    } else if (s.mode == Mode::Product) {
      g.add({"product_accumulate", {kReceivers, kTables, kCuts}, {}, {kVisibility},
             "product-space accumulation of blocker visibility (eq. 6, Zhou et al. 2005)",
             cpu([s](FrameContext& c) { pass_product(s, c); })});
    } else {
      g.add({"accumulate_log", {kReceivers, kTables, kCuts}, {}, {kLogVisibility},
             "sum of blocker log vectors per receiver (eqs. 8, 34, 38; rules of section 6.2)",
             common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_accumulate(s, c); }), kernels,
                          [s](const DeviceKernels& k) -> render::PassFn {
                            if (!k.accumulate) return {};
                            return [s, f = k.accumulate](FrameContext& c) { f(s, c); };
                          })});
      // A backend's exponential may cover only some methods (Vulkan: not the exact one, eq. 28):
      // the others run the host pass there.
      g.add({"exponentiate", {kReceivers, kTables, kLogVisibility}, {}, {kVisibility},
             "SH exponential per receiver (section 4), truncated to the shading order",
             common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_exponentiate(s, c); }), kernels,
                          [s](const DeviceKernels& k) -> render::PassFn {
                            if (!k.exponentiate || !k.exp_supports || !k.exp_supports(s.mode)) return {};
                            return [s, f = k.exponentiate](FrameContext& c) { f(s, c); };
                          })});
    }
    g.add({"shade", {kReceivers}, {kVisibility, kLightTables}, {kShading},
           "L_H(N) . g per vertex, environment and spherical lights (section 7)",
           common::with_kernels<DeviceKernels>(cpu([st, s](FrameContext& c) { pass_shade(*st, s, c); }), kernels,
                        [st, s](const DeviceKernels& k) -> render::PassFn {
                          if (!k.shade) return {};
                          return [st, s, f = k.shade](FrameContext& c) { pass_shade(*st, s, c, &f); };
                        })});
    g.add({"to_image", {render::kGBuffer, kShading}, {}, {render::kDirect}, "per-vertex radiance through the G-buffer",
           cpu([](FrameContext& c) { pass_to_image(c); })});
    render::add_compose_pass(g);
    return g;
  }

 private:
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

}  // namespace

std::unique_ptr<render::Technique> create() { return std::make_unique<Shexp>(); }

void register_device_kernels(const std::string& backend, DeviceKernels kernels) { device_kernels().add(backend, std::move(kernels)); }

}  // namespace softgi::techniques::shexp
