// SHEXP as a technique: pass graph pruning on the null backend, the hierarchy with ratio vectors
// against the flat list, higher-order accumulation against a brute-force reference, renders on the
// CPU backend against the ray-traced proxy-blocker reference (the shadow term where the shadows are,
// the self-shadowing scale factor, the background).
#include <gtest/gtest.h>

#include <algorithm>
#include <any>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "../../techniques/shexp/shexp_internal.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/sh/product.hpp"
#include "softgi/techniques/registry.hpp"
#include "../support/pass_counter.hpp"

using namespace softgi;
using namespace softgi::techniques::shexp;

namespace {

// A grid of n x n vertices in the y = 0 plane, normals +y.
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

// Ground plane plus a small blocker object carrying a proxy set; optionally animated and lit.
scene::Scene test_scene(bool animated, bool proxies, bool light) {
  scene::Scene s;
  s.name = "shexp-test";
  s.source = "test";
  s.materials.push_back(scene::Material{});
  s.meshes.push_back(grid_mesh(12, 4.0f));
  scene::Mesh box = grid_mesh(3, 0.5f);
  box.name = "blocker";
  s.meshes.push_back(box);
  scene::Node ground;
  ground.name = "ground";
  ground.mesh = 0;
  s.nodes.push_back(ground);
  scene::Node blocker;
  blocker.name = "blocker";
  blocker.mesh = 1;
  blocker.translation = {0.0f, 0.8f, 0.0f};
  s.nodes.push_back(blocker);
  if (proxies) {
    scene::ProxySet ps;
    ps.name = "blocker";
    ps.node = 1;
    for (int i = 0; i < 6; ++i) ps.spheres.push_back({glm::vec3(0.15f * i - 0.4f, 0.0f, 0.1f * (i % 2)), 0.2f});
    s.proxies.push_back(ps);
  }
  if (animated) {
    scene::AnimationClip clip;
    clip.name = "move";
    clip.duration = 1.0f;
    scene::AnimationChannel ch;
    ch.node = 1;
    ch.times = {0.0f, 1.0f};
    ch.values = {glm::vec4(0.0f, 0.8f, 0.0f, 0.0f), glm::vec4(1.0f, 0.8f, 0.0f, 0.0f)};
    clip.channels.push_back(ch);
    s.clips.push_back(clip);
    s.active_clip = 0;
  }
  if (light) {
    scene::SphericalLight l;
    l.position = {1.0f, 2.0f, 0.5f};
    l.radius = 0.2f;
    l.radiance = glm::vec3(5.0f);
    s.lights.push_back(l);
  }
  s.camera.width = 16;
  s.camera.height = 16;
  return s;
}

std::vector<std::string> executed(const scene::Scene& s, const std::vector<std::string>& assignments = {}) {
  techniques::register_all();
  auto t = render::create_technique("shexp");
  render::ParamSet p = render::default_params(*t);
  for (const auto& a : assignments) p.set_assignment(a);
  render::NullBackend null;
  render::RenderRequest req;
  req.time = 0.25;
  null.render(*t, s, p, req);
  return null.executed;
}

bool has(const std::vector<std::string>& v, const std::string& x) { return std::find(v.begin(), v.end(), x) != v.end(); }

}  // namespace

// --- the pass graph --------------------------------------------------------------------------------

TEST(ShexpGraph, ProxyUpdateIsPrunedForAStaticSceneAndRunsForAnAnimatedOne) {
  const auto st = executed(test_scene(false, true, false));
  EXPECT_FALSE(has(st, "proxy_update"));
  for (const char* p : {"gbuffer", "tables", "receiver_setup", "hierarchy_build", "blocker_cut", "accumulate_log", "exponentiate",
                        "shade", "to_image", "compose"})
    EXPECT_TRUE(has(st, p)) << p;
  EXPECT_FALSE(has(st, "light_tables"));  // no spherical light in the scene
  const auto an = executed(test_scene(true, true, false));
  ASSERT_TRUE(has(an, "proxy_update"));
  const auto pos = [&](const std::string& n) { return std::find(an.begin(), an.end(), n) - an.begin(); };
  EXPECT_LT(pos("hierarchy_build"), pos("proxy_update"));
  EXPECT_LT(pos("proxy_update"), pos("blocker_cut"));
}

TEST(ShexpGraph, NothingToAccumulateWithoutBlockersTablesOnlyWhenNeeded) {
  const auto e = executed(test_scene(false, false, true));
  for (const char* p : {"tables", "hierarchy_build", "blocker_cut", "accumulate_log", "exponentiate"}) EXPECT_FALSE(has(e, p)) << p;
  for (const char* p : {"receiver_setup", "light_tables", "shade", "to_image"}) EXPECT_TRUE(has(e, p)) << p;
  EXPECT_FALSE(has(executed(test_scene(false, true, true), {"analytic_lights=false"}), "light_tables"));
}

TEST(ShexpGraph, ProductSpaceIsItsOwnPass) {
  const auto e = executed(test_scene(true, true, false), {"exp=product"});
  EXPECT_TRUE(has(e, "product_accumulate"));
  for (const char* p : {"accumulate_log", "exponentiate", "hierarchy_build", "proxy_update"}) EXPECT_FALSE(has(e, p)) << p;
  const auto flat = executed(test_scene(true, true, false), {"hierarchy=false"});
  EXPECT_FALSE(has(flat, "proxy_update"));  // the flat list reads this frame's spheres directly
  EXPECT_TRUE(has(flat, "accumulate_log"));
}

TEST(ShexpGraph, InconsistentParametersAreRejectedByName) {
  techniques::register_all();
  auto t = render::create_technique("shexp");
  render::ParamSet p = render::default_params(*t);
  p.set_assignment("order=5");
  p.set_assignment("accumulation_order=4");
  std::set<std::string> empty;
  try {
    t->plan(test_scene(false, true, false), p, empty);
    FAIL() << "accumulation below the shading order accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("accumulation_order"), std::string::npos) << e.what();
  }
  p.set_assignment("accumulation_order=0");
  p.set_assignment("theta_min_deg=30");
  p.set_assignment("theta_max_deg=20");
  EXPECT_THROW(t->plan(test_scene(false, true, false), p, empty), std::invalid_argument);
  EXPECT_THROW(p.set_assignment("order=7"), std::invalid_argument);
  EXPECT_THROW(p.set_assignment("exp=taylor"), std::invalid_argument);
}

TEST(ShexpGraph, NonFiniteProxySpheresAreNamed) {
  techniques::register_all();
  backends::CpuBackend cpu;
  for (const char* h : {"hierarchy=true", "hierarchy=false"}) {
    scene::Scene s = test_scene(false, true, false);
    s.proxies[0].spheres[3].radius = std::numeric_limits<float>::quiet_NaN();
    auto t = render::create_technique("shexp");
    render::ParamSet p = render::default_params(*t);
    p.set_assignment(h);
    try {
      cpu.render(*t, s, p, render::RenderRequest{});
      ADD_FAILURE() << "NaN sphere accepted with " << h;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("proxy set 'blocker'"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("sphere 3"), std::string::npos) << e.what();
    }
  }
}

// --- hierarchy with ratio vectors vs the flat list (section 6.3) -------------------------------------

namespace {
struct Crowd {
  std::vector<std::vector<scene::Sphere>> sets;
  ReceiverSoA rec;
  std::vector<ReceiverCluster> clusters;
};

// 9 "characters" of 40 random spheres each (a 0.35 m x 1.8 m column) on a 3 x 3 grid 2.2 m apart,
// and a 64 x 64-vertex ground of 9 m, clustered into 48 receiver clusters.
Crowd make_crowd(unsigned seed) {
  Crowd c;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int gx = -1; gx <= 1; ++gx)
    for (int gz = -1; gz <= 1; ++gz) {
      std::vector<scene::Sphere> set;
      for (int i = 0; i < 40; ++i) {
        const float a = 6.2832f * u(rng), rr = 0.2f * u(rng);
        set.push_back({glm::vec3(2.2f * gx + rr * std::cos(a), 0.25f + 1.5f * u(rng), 2.2f * gz + rr * std::sin(a)),
                       0.08f + 0.12f * u(rng)});
      }
      c.sets.push_back(set);
    }
  std::vector<glm::vec3> pts;
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 64; ++i) pts.emplace_back(9.0f * (i / 63.0f - 0.5f), 0.0f, 9.0f * (j / 63.0f - 0.5f));
  LloydResult lr = lloyd_cluster(pts, 48, 30, 11);
  const int k = static_cast<int>(lr.centres.size());
  std::vector<std::vector<int>> members(k);
  for (std::size_t i = 0; i < pts.size(); ++i) members[lr.assignment[i]].push_back(static_cast<int>(i));
  c.rec.resize(pts.size());
  std::size_t at = 0;
  for (int cl = 0; cl < k; ++cl) {
    ReceiverCluster rc;
    rc.begin = at;
    float best = 1e30f;
    for (int i : members[cl]) {
      c.rec.set(at++, pts[i], glm::vec3(0.0f, 1.0f, 0.0f));
      rc.radius = std::max(rc.radius, glm::length(pts[i] - lr.centres[cl]));
      if (glm::length(pts[i] - lr.centres[cl]) < best) {
        best = glm::length(pts[i] - lr.centres[cl]);
        rc.star = pts[i];
      }
    }
    rc.end = at;
    rc.centre = lr.centres[cl];
    c.clusters.push_back(rc);
  }
  return c;
}

// Shaded value per receiver (environment: sky-like lobe) for the given per-cluster blocker lists.
std::vector<double> shade_all(const Crowd& c, const std::vector<BlockerList>& lists, const sh::ShTables& tables,
                              const ZhTable& t) {
  const int n = t.order, n2 = n * n;
  std::vector<float> f(c.rec.size() * n2);
  for (std::size_t k = 0; k < c.clusters.size(); ++k)
    accumulate_log(best_kernel_isa(), t, ReplacementRule::Continuous, c.rec, c.clusters[k].begin, c.clusters[k].end,
                   lists[k], f.data());
  std::vector<double> L = sh::project(n, sh::make_sphere_quadrature(n + 8), [](const sh::Vec3<double>& s) {
    const double cz = std::max(0.0, 0.4 * s.x + 0.8 * s.y + 0.45 * s.z);
    return 0.2 + 3.0 * cz * cz;
  });
  std::array<double, sh::kMaxCoeffs> H{}, gd{}, HG{};
  sh::irradiance_weight(n, sh::Vec3<double>{0.0, 1.0, 0.0}, H.data());
  std::vector<double> v(c.rec.size());
  std::vector<float> g(n2);
  sh::ExpOptions opt;
  for (std::size_t i = 0; i < c.rec.size(); ++i) {
    sh::exp<float>(n, f.data() + i * n2, g.data(), opt, &tables);
    for (int k = 0; k < n2; ++k) gd[k] = g[k];
    sh::TripleProduct::get(n).product(H.data(), gd.data(), HG.data());
    double s = 0.0;
    for (int k = 0; k < n2; ++k) s += HG[k] * L[k];
    v[i] = s;
  }
  return v;
}

struct Diff {
  double mean_rel = 0.0, max_rel = 0.0;
};
Diff diff(const std::vector<double>& a, const std::vector<double>& ref) {
  double sum = 0.0, mean_ref = 0.0, mx = 0.0, max_ref = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sum += std::abs(a[i] - ref[i]);
    mean_ref += std::abs(ref[i]);
    mx = std::max(mx, std::abs(a[i] - ref[i]));
    max_ref = std::max(max_ref, std::abs(ref[i]));
  }
  return {sum / mean_ref, mx / max_ref};
}
}  // namespace

// With theta_max = 25 degrees and ratio vectors the cut changes the shaded crowd ground by at most
// 1% on average and 8% at worst relative to the flat list (Figure 6c); without ratio vectors the
// bounding spheres overblock visibly (Figure 6b), so ratio vectors must at least halve the error.
constexpr double kHierarchyMeanTol = 0.01;
constexpr double kHierarchyMaxTol = 0.08;

// make_cut_posed takes every node's sphere as posed this frame (spherical lights pose their parent
// SLs themselves). Given the spheres make_cut reads (the leaves and the build-time bounds) it is
// make_cut to the bit; given them all moved by T, with the cluster moved by T, it is the same cut
// moved by T (the spheres as given, ratio vectors within 1e-4: the log vectors at p* + T are the
// ones at p* up to the rounding of the translated coordinates); a cut that read the build-time bounds of the inner nodes would test them against
// receivers 40 m away.
TEST(ShexpHierarchy, PosedCutIsTheCutOfTheSpheresAsGiven) {
  const int order = 4;
  sh::TableOptions o;
  o.order = order;
  o.measure_error = false;
  sh::ShTables tables(o);
  const ZhTable t = make_zh_table(tables.cap_log(), order, true);
  Crowd c = make_crowd(1);
  std::vector<proxies::SphereHierarchy> trees;
  for (const auto& set : c.sets) trees.push_back(proxies::SphereHierarchy::build(set, 4));
  std::vector<const proxies::SphereHierarchy*> tp;
  for (const auto& tr : trees) tp.push_back(&tr);
  const glm::vec3 T(40.0f, 0.0f, -25.0f);
  std::vector<std::vector<scene::Sphere>> rest(trees.size()), moved(trees.size());
  for (std::size_t k = 0; k < trees.size(); ++k)
    for (const auto& nd : trees[k].nodes()) {
      const scene::Sphere sp = nd.children.empty() ? c.sets[k][static_cast<std::size_t>(nd.leaf)] : nd.bound;
      rest[k].push_back(sp);
      moved[k].push_back(scene::Sphere{sp.center + T, sp.radius});
    }
  CutOptions opt;
  int inner = 0;
  for (const auto& rc : c.clusters) {
    const BlockerList a = make_cut(tp, c.sets, t, rc.centre, rc.radius, rc.star, opt, nullptr);
    const BlockerList b = make_cut_posed(tp, rest, t, rc.centre, rc.radius, rc.star, opt, nullptr);
    EXPECT_EQ(a.cx, b.cx);
    EXPECT_EQ(a.r, b.r);
    EXPECT_EQ(a.w, b.w);
    const BlockerList m = make_cut_posed(tp, moved, t, rc.centre + T, rc.radius, rc.star + T, opt, nullptr);
    ASSERT_EQ(m.size(), a.size());
    for (std::size_t j = 0; j < a.size(); ++j) {
      EXPECT_EQ(m.r[j], a.r[j]);
      EXPECT_EQ(m.cx[j], a.cx[j] + T.x);  // the caller's sphere, pushed as given
      EXPECT_EQ(m.cz[j], a.cz[j] + T.z);
    }
    ASSERT_EQ(m.w.size(), a.w.size());
    for (std::size_t j = 0; j < a.w.size(); ++j) EXPECT_NEAR(m.w[j], a.w[j], 1e-4f * std::max(1.0f, std::abs(a.w[j])));
    for (std::size_t j = 0; j < a.size(); ++j) inner += a.w[j * order] != 1.0f;
  }
  EXPECT_GT(inner, 0) << "cuts with inner nodes, whose spheres the posed cut must take from the caller";
  std::vector<std::vector<scene::Sphere>> short_list = rest;
  short_list[0].pop_back();
  EXPECT_THROW(make_cut_posed(tp, short_list, t, c.clusters[0].centre, c.clusters[0].radius, c.clusters[0].star, opt, nullptr),
               std::invalid_argument);
}

TEST(ShexpHierarchy, RatioVectorsKeepTheCutCloseToTheFlatList) {
  const int order = 4;
  sh::TableOptions o;
  o.order = order;
  o.measure_error = false;
  sh::ShTables tables(o);
  const ZhTable t = make_zh_table(tables.cap_log(), order, true);
  for (unsigned seed : {1u, 2u}) {
    Crowd c = make_crowd(seed);
    std::vector<proxies::SphereHierarchy> trees;
    for (const auto& s : c.sets) trees.push_back(proxies::SphereHierarchy::build(s, 4));
    std::vector<const proxies::SphereHierarchy*> tp;
    for (const auto& tr : trees) tp.push_back(&tr);
    const BlockerList flat = flat_list(c.sets, order);
    std::vector<BlockerList> flat_lists(c.clusters.size(), flat), cut_lists, plain_lists;
    CutOptions with, without;
    without.ratio_vectors = false;
    CutStats stats;
    double cut_size = 0.0;
    for (const auto& rc : c.clusters) {
      cut_lists.push_back(make_cut(tp, c.sets, t, rc.centre, rc.radius, rc.star, with, &stats));
      plain_lists.push_back(make_cut(tp, c.sets, t, rc.centre, rc.radius, rc.star, without, nullptr));
      cut_size += cut_lists.back().size();
    }
    cut_size /= c.clusters.size();
    EXPECT_LT(cut_size, 0.5 * flat.size()) << "the cut should save work";
    EXPECT_GT(stats.inner, 0);
    const std::vector<double> ref = shade_all(c, flat_lists, tables, t);
    const Diff dc = diff(shade_all(c, cut_lists, tables, t), ref);
    const Diff dp = diff(shade_all(c, plain_lists, tables, t), ref);
    EXPECT_LT(dc.mean_rel, kHierarchyMeanTol) << "seed " << seed;
    EXPECT_LT(dc.max_rel, kHierarchyMaxTol) << "seed " << seed;
    EXPECT_LT(dc.mean_rel, 0.5 * dp.mean_rel) << "seed " << seed << ": ratio vectors should help";
    std::printf("[measured] crowd seed %u: cut %.1f of %zu spheres; mean/max rel. error %.4f/%.4f with ratio vectors, %.4f/%.4f without\n",
                seed, cut_size, flat.size(), dc.mean_rel, dc.max_rel, dp.mean_rel, dp.max_rel);
  }
}

// --- higher-order accumulation (Figure 7e) ------------------------------------------------------------

namespace {
// Brute-force (L, V, max(N.s, 0))/pi by quadrature with the binary visibility of the spheres, L the
// order-4 light (paper 004 Figure 7: "Lighting is SH order n=4").
double brute_force(const std::vector<double>& L4, const glm::vec3& p, const std::vector<scene::Sphere>& spheres,
                   const sh::SphereQuadrature& q) {
  double sum = 0.0;
  std::array<double, 16> y{};
  for (std::size_t k = 0; k < q.dirs.size(); ++k) {
    const auto& s = q.dirs[k];
    if (s.y <= 0.0) continue;
    bool blocked = false;
    for (const auto& sp : spheres) {
      const glm::dvec3 oc = glm::dvec3(p) - glm::dvec3(sp.center);
      const double b = oc.x * s.x + oc.y * s.y + oc.z * s.z, c = glm::dot(oc, oc) - double(sp.radius) * sp.radius;
      if (b * b - c >= 0.0 && -b - std::sqrt(std::max(0.0, b * b - c)) > 0.0) blocked = true;
    }
    if (blocked) continue;
    sh::eval_basis(4, s, y.data());
    double l = 0.0;
    for (int i = 0; i < 16; ++i) l += L4[i] * y[i];
    sum += q.weights[k] * l * s.y / sh::kPi;
  }
  return sum;
}
}  // namespace

TEST(ShexpAccumulationOrder, AccumulatingAtOrder6ReducesErrorAgainstBruteForce) {
  std::vector<double> L4 = sh::project(4, sh::make_sphere_quadrature(16), [](const sh::Vec3<double>& s) {
    const double c = std::max(0.0, 0.3 * s.x + 0.9 * s.y - 0.3 * s.z);
    return 0.1 + 6.0 * c * c * c * c;
  });
  const sh::SphereQuadrature q = sh::make_sphere_quadrature(120);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  // A blob of 12 overlapping spheres above a plane (heavy overlap: where product truncation bites).
  std::vector<scene::Sphere> spheres;
  for (int i = 0; i < 12; ++i) spheres.push_back({glm::vec3(0.35f * u(rng), 1.0f + 0.3f * u(rng), 0.35f * u(rng)), 0.25f + 0.1f * u(rng)});
  double err4 = 0.0, err6 = 0.0;
  for (int order_acc : {4, 6}) {
    sh::TableOptions o;
    o.order = order_acc;
    o.measure_error = false;
    sh::ShTables tables(o);
    const ZhTable t = make_zh_table(tables.cap_log(), order_acc, true);
    const int na2 = order_acc * order_acc;
    BlockerList b = flat_list({spheres}, order_acc);
    double err = 0.0;
    int count = 0;
    for (int i = 0; i < 7; ++i)
      for (int j = 0; j < 7; ++j) {
        const glm::vec3 p(0.25f * (i - 3), 0.0f, 0.25f * (j - 3));
        ReceiverSoA rec;
        rec.resize(1);
        rec.set(0, p, glm::vec3(0.0f, 1.0f, 0.0f));
        std::vector<float> f(na2), g(na2);
        accumulate_log(best_kernel_isa(), t, ReplacementRule::Off, rec, 0, 1, b, f.data());
        sh::ExpOptions opt;
        opt.method = sh::ExpMethod::PSStar;  // Figure 7 uses PS*-2
        sh::exp<float>(order_acc, f.data(), g.data(), opt, &tables);
        // Truncate to order 4 and shade: (H(N) * g) . L.
        std::array<double, 16> H{}, gd{}, HG{};
        for (int k = 0; k < 16; ++k) gd[k] = g[k];
        sh::irradiance_weight(4, sh::Vec3<double>{0.0, 1.0, 0.0}, H.data());
        sh::TripleProduct::get(4).product(H.data(), gd.data(), HG.data());
        double v = 0.0;
        for (int k = 0; k < 16; ++k) v += HG[k] * L4[k];
        err += std::abs(v - brute_force(L4, p, spheres, q));
        ++count;
      }
    (order_acc == 4 ? err4 : err6) = err / count;
  }
  std::printf("[measured] mean |shaded - brute force|: accumulated at n=4 %.5f, at n=6 %.5f\n", err4, err6);
  EXPECT_LT(err6, err4);
}

// --- CPU backend on the built-in `spheres` scene ---------------------------------------------------

TEST(ShexpRender, SpheresOnTheCpuBackendIsFiniteNonNegativeAndNearTheReference) {
  techniques::register_all();
  scene::Scene s = scene::make_builtin("spheres");
  backends::CpuBackend cpu;
  auto t = render::create_technique("shexp");
  render::ParamSet p = render::default_params(*t);
  p.set_assignment("window_h=0");  // the reference's SH light is not windowed
  render::RenderRequest req;
  req.width = 64;
  req.height = 48;
  req.time = 0.5;
  render::FrameResult r = cpu.render(*t, s, p, req);
  ASSERT_EQ(r.direct.width, 64);
  ASSERT_EQ(r.direct.height, 48);
  for (const auto& px : r.direct.rgb)
    for (int c = 0; c < 3; ++c) {
      ASSERT_TRUE(std::isfinite(px[c]));
      ASSERT_GE(px[c], 0.0f);
    }
  scene::PosedScene posed = scene::evaluate(s, req.time);
  ASSERT_EQ(r.vertex_radiance.size(), posed.objects.size());
  for (std::size_t o = 0; o < posed.objects.size(); ++o) EXPECT_EQ(r.vertex_radiance[o].size(), posed.objects[o].positions.size());
  bool saw_accumulate = false;
  for (const auto& pass : r.passes)
    if (pass.name == "accumulate_log") {
      saw_accumulate = true;
      EXPECT_GT(pass.counters.at("receivers"), 1000.0);
      EXPECT_GT(pass.counters.at("blockers_per_receiver_mean"), 0.0);
      EXPECT_GT(pass.bytes, 0u);
    }
  EXPECT_TRUE(saw_accumulate);

  // Reference: ray traced with the sphere proxies as blockers under the order-4 SH light, direct only
  // (Figure 7b's setting at n = 4).
  reference::ReferenceOptions ro;
  ro.spp = 16;
  ro.blockers = reference::ReferenceOptions::Blockers::Proxies;
  ro.light_sh_order = 4;
  ro.indirect = false;
  ro.time = req.time;
  ro.width = req.width;
  ro.height = req.height;
  ro.jitter = false;
  reference::ReferenceResult ref = reference::render_reference(s, ro);
  metrics::Metrics m = metrics::compare(r.direct, ref.direct);
  std::printf("[measured] spheres 64x48 vs reference (proxies, SH4 light, 16 spp): relMSE %.4f SSIM %.4f\n", m.relmse, m.ssim);
  // A whole-image sanity bound only: vertex-rate shading, order-4 visibility and 16 spp of noise
  // (measured: relMSE 0.014, SSIM 0.85). It cannot see the shadows: the same frame with them left
  // out measured relMSE 0.035, SSIM 0.83. ShexpShadows.* test where the shadows are.
  EXPECT_LT(m.relmse, 0.05);
  EXPECT_GT(m.ssim, 0.8);
}

// --- shadows against a converged proxy-blocker reference ---------------------------------------------

namespace {

double luminance(const glm::vec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

render::FrameResult render_shexp(const scene::Scene& s, const std::vector<std::string>& assignments, const render::RenderRequest& req) {
  techniques::register_all();
  backends::CpuBackend cpu;
  auto t = render::create_technique("shexp");
  render::ParamSet p = render::default_params(*t);
  for (const auto& a : assignments) p.set_assignment(a);
  return cpu.render(*t, s, p, req);
}

// The shadow term as a deficit per pixel, D = 1 - (direct with the blockers) / (direct without them),
// NaN where it is undefined (no surface, no unshadowed light).
constexpr double kNoDeficit = std::numeric_limits<double>::quiet_NaN();

// SHEXP's: without the blockers is its render of the scene without proxy sets (no visibility:
// unshadowed). With window_h = 0 the light is the reference's order-n projection, unwindowed.
struct TechDeficits {
  render::GBuffer gb;
  std::vector<double> d;
};
TechDeficits shexp_deficits(const scene::Scene& s, std::vector<std::string> assignments, const reference::ReferenceOptions& ro) {
  render::RenderRequest req;
  req.width = ro.width;
  req.height = ro.height;
  req.time = ro.time;
  req.outputs = {"final", render::kGBuffer};
  assignments.push_back("window_h=0");
  const render::FrameResult shadowed = render_shexp(s, assignments, req);
  scene::Scene bare = s;
  bare.proxies.clear();
  const render::FrameResult unshadowed = render_shexp(bare, assignments, req);
  TechDeficits t;
  t.gb = std::any_cast<const render::GBuffer&>(shadowed.resources.at(render::kGBuffer));
  t.d.assign(t.gb.object.size(), kNoDeficit);
  for (std::size_t i = 0; i < t.d.size(); ++i) {
    const double u = luminance(unshadowed.direct.rgb[i]);
    if (t.gb.hit(i) && u > 0.0) t.d[i] = 1.0 - luminance(shadowed.direct.rgb[i]) / u;
  }
  return t;
}

// The reference's: without the blockers is a geometry-blocker render of the scene without the proxy
// sets and without the meshes they stand for. Sample k of a pixel draws the same random numbers in
// both renders (they depend only on seed, pixel and k, and no draw depends on visibility), and a
// receiver pixel's camera ray hits the same point, so the two estimates share their samples: where
// no sample is blocked D is exactly 0, and the ratio's noise comes from the blocked samples alone.
// half_diff = (d1 - d2)/2, with d1 the deficit of the running estimates after spp/2 samples and d2
// that of the other half (h2 = 2 full - h1): independent halves with D ~ (d1 + d2)/2, so half_diff
// is distributed as D's noise.
struct RefDeficits {
  std::vector<double> d, half_diff;
};
RefDeficits reference_deficits(const scene::Scene& s, const reference::ReferenceOptions& ro) {
  struct Halves {
    reference::ReferenceResult full;
    Image half;
  };
  auto render = [](const scene::Scene& sc, const reference::ReferenceOptions& o) {
    Halves h;
    h.full = reference::render_reference(sc, o, {}, [&](int spp_done, const reference::ReferenceResult& running) {
      if (spp_done == o.spp / 2) h.half = running.direct;
    });
    EXPECT_EQ(h.half.width, o.width) << "spp " << o.spp << " has no pass at spp/2";
    return h;
  };
  const Halves with = render(s, ro);
  scene::Scene bare = s;
  bare.proxies.clear();
  for (const auto& ps : s.proxies)
    if (ps.node >= 0) bare.nodes[ps.node].mesh = -1;
  reference::ReferenceOptions ro_bare = ro;
  ro_bare.blockers = reference::ReferenceOptions::Blockers::Geometry;
  const Halves without = render(bare, ro_bare);
  RefDeficits r;
  r.d.assign(with.full.direct.rgb.size(), kNoDeficit);
  r.half_diff.assign(r.d.size(), kNoDeficit);
  for (std::size_t i = 0; i < r.d.size(); ++i) {
    const double full = luminance(with.full.direct.rgb[i]), full_u = luminance(without.full.direct.rgb[i]);
    const double h1 = luminance(with.half.rgb[i]), h1_u = luminance(without.half.rgb[i]);
    const double h2 = 2.0 * full - h1, h2_u = 2.0 * full_u - h1_u;
    if (!(full_u > 0.0) || !(h1_u > 0.0) || !(h2_u > 0.0)) continue;
    r.d[i] = 1.0 - full / full_u;
    r.half_diff[i] = 0.5 * ((1.0 - h1 / h1_u) - (1.0 - h2 / h2_u));
  }
  return r;
}

// Shadow error over the pixels whose G-buffer surface belongs to the node `receiver` (and passes
// `select`), in blocks of kShadowBlock x kShadowBlock pixels: sum_b |sum_{i in b} (D_tech - D_ref)| /
// sum D_ref. 0 when SHEXP's shadows are the reference's, 1 when it draws none (D_tech = 0), up to 2
// when they lie a block or more away from the reference's. Summing over a block before taking the
// magnitude averages the reference's per-pixel noise down (by about the block's edge) and keeps
// every misplacement larger than a block. The reference's noise adds at most noise_floor =
// sum_b |noise_b| / sum D_ref (|b + n| <= |b| + |n|), with noise_b the block's sum of half_diff.
constexpr int kShadowBlock = 4;
struct ShadowError {
  double error = 0.0, noise_floor = 0.0, mean_deficit = 0.0;
  std::size_t pixels = 0;
};
ShadowError shadow_error(const scene::Scene& s, double time, const std::string& receiver, const TechDeficits& t,
                         const RefDeficits& r, const std::function<bool(const glm::vec3&)>& select = {}) {
  const scene::PosedScene posed = scene::evaluate(s, time);
  std::map<std::pair<int, int>, std::pair<double, double>> blocks;  // block -> (sum of differences, sum of noise)
  ShadowError e;
  double sum = 0.0;
  for (std::size_t i = 0; i < t.d.size(); ++i) {
    if (!t.gb.hit(i) || std::isnan(t.d[i]) || std::isnan(r.d[i])) continue;
    const int node = posed.objects[t.gb.object[i]].node;
    if (node < 0 || s.nodes[node].name != receiver) continue;
    if (select && !select(t.gb.position[i])) continue;
    const int x = static_cast<int>(i % static_cast<std::size_t>(t.gb.width)), y = static_cast<int>(i / static_cast<std::size_t>(t.gb.width));
    auto& b = blocks[{x / kShadowBlock, y / kShadowBlock}];
    b.first += t.d[i] - r.d[i];
    b.second += r.half_diff[i];
    sum += r.d[i];
    ++e.pixels;
  }
  double diff = 0.0, noise = 0.0;
  for (const auto& [key, b] : blocks) {
    diff += std::abs(b.first);
    noise += std::abs(b.second);
  }
  e.mean_deficit = e.pixels ? sum / static_cast<double>(e.pixels) : 0.0;
  e.error = sum > 0.0 ? diff / sum : 1.0;
  e.noise_floor = sum > 0.0 ? noise / sum : 1.0;
  return e;
}

}  // namespace

// The reference's noise must stay far below the error of a missing shadow (1), so that the tolerances
// below are SHEXP's own approximation plus a small allowance for the noise.
constexpr double kMaxNoiseFloor = 0.05;
// SHEXP's shadows on the `spheres` ground under the order-4 sky against the proxy reference: order-4
// visibility (the triple product truncates V H, which the reference integrates exactly), HYB
// exponentiation, hierarchy cuts and vertex-rate interpolation of the contact shadows. Measured 0.087
// with a noise floor of 0.012 at 4096 spp (0.091 / 0.033 at the 512 spp used here). Allowed: 0.12
// plus twice the floor.
constexpr double kSpheresShadowTol = 0.12;

TEST(ShexpShadows, OnTheSpheresGroundTheyAreWhereTheReferenceHasThem) {
  const scene::Scene s = scene::make_builtin("spheres");
  reference::ReferenceOptions ro;
  ro.spp = 512;
  ro.blockers = reference::ReferenceOptions::Blockers::Proxies;
  ro.light_sh_order = 4;
  ro.indirect = false;
  ro.time = 0.5;
  ro.width = 96;
  ro.height = 72;
  ro.jitter = false;  // the G-buffer's pixel-centre rays
  const ShadowError e = shadow_error(s, ro.time, "ground", shexp_deficits(s, {}, ro), reference_deficits(s, ro));
  std::printf("[measured] spheres ground shadow error %.4f (noise floor %.4f at %d spp, %zu pixels, mean reference deficit %.4f)\n",
              e.error, e.noise_floor, ro.spp, e.pixels, e.mean_deficit);
  ASSERT_GT(e.pixels, 2000u);
  EXPECT_GT(e.mean_deficit, 0.02) << "the ground should be visibly shadowed";
  EXPECT_LT(e.noise_floor, kMaxNoiseFloor) << "the reference is too noisy at " << ro.spp << " spp to see the shadows";
  EXPECT_LT(e.error, kSpheresShadowTol + 2.0 * e.noise_floor);
}

// Paper 004 section 6.2's scale factor where its readings differ: a proxy sphere (r = 1/2) whose
// centre lies h = 0.35 above the ground it stands in, so that ground receivers within d =
// sqrt(r^2 - h^2) beyond the disc it cuts are on the ramp of the factor (constant sky: the shadow is
// the sphere's cosine-weighted solid angle). SHEXP and the reference read the factor through the same
// definition (proxies::apply_replacement_rule), so their shadows on the ramp agree under either
// reading; SHEXP against a reference that reads it the other way is far off. Measured at 2048 spp:
// 0.022 continuous (noise floor 0.010), 0.089 clamped (0.021: its jump at the edge of S is smeared
// by the vertex interpolation), 2.19 across readings.
constexpr double kRampShadowTol = 0.05;
constexpr double kRampShadowTolClamped = 0.12;

TEST(ShexpShadows, ScaleFactorReadAsTheReferenceReadsIt) {
  scene::Scene s;
  s.name = "ramp";
  s.source = "test";
  s.materials.push_back(scene::Material{});
  s.meshes.push_back(grid_mesh(161, 4.0f));
  scene::Node ground;
  ground.name = "ground";
  ground.mesh = 0;
  s.nodes.push_back(ground);
  constexpr float kR = 0.5f, kH = 0.35f;
  const glm::vec3 centre(0.2f, kH, -0.1f);
  scene::ProxySet ps;
  ps.name = "sunk";
  ps.node = -1;  // world space, no mesh: only a blocker
  ps.spheres.push_back({centre, kR});
  s.proxies.push_back(ps);
  s.environment.kind = scene::Environment::Kind::Sky;
  s.environment.zenith = s.environment.horizon = s.environment.ground = glm::vec3(1.0f);
  s.environment.sun_radius = 0.0f;
  s.environment.sun_radiance = glm::vec3(0.0f);
  s.camera.position = {0.2f, 2.5f, 1.5f};
  s.camera.target = {0.2f, 0.0f, -0.1f};
  s.camera.fov_y_deg = 45.0f;

  const float d = std::sqrt(kR * kR - kH * kH);
  auto on_ramp = [&](const glm::vec3& p) {
    const float dist = glm::length(glm::vec2(p.x - centre.x, p.z - centre.z));  // |p - q1|
    return dist > d && dist < 2.0f * d;
  };
  reference::ReferenceOptions ro;
  ro.spp = 512;
  ro.blockers = reference::ReferenceOptions::Blockers::Proxies;
  ro.light_sh_order = 4;
  ro.indirect = false;
  ro.width = 64;
  ro.height = 48;
  ro.jitter = false;
  const TechDeficits t_cont = shexp_deficits(s, {"replacement_rule=continuous"}, ro);
  const TechDeficits t_clamped = shexp_deficits(s, {"replacement_rule=clamped"}, ro);
  ro.replacement_rule = proxies::ReplacementRule::Continuous;
  const RefDeficits r_cont = reference_deficits(s, ro);
  ro.replacement_rule = proxies::ReplacementRule::Clamped;
  const RefDeficits r_clamped = reference_deficits(s, ro);
  const ShadowError cont = shadow_error(s, 0.0, "ground", t_cont, r_cont, on_ramp);
  const ShadowError clamped = shadow_error(s, 0.0, "ground", t_clamped, r_clamped, on_ramp);
  const ShadowError across = shadow_error(s, 0.0, "ground", t_cont, r_clamped, on_ramp);
  std::printf("[measured] ramp shadow error at %d spp: continuous %.4f (noise floor %.4f, %zu pixels, mean deficit %.4f), "
              "clamped %.4f (noise floor %.4f), continuous SHEXP vs clamped reference %.4f\n",
              ro.spp, cont.error, cont.noise_floor, cont.pixels, cont.mean_deficit, clamped.error, clamped.noise_floor, across.error);
  ASSERT_GT(cont.pixels, 200u);
  EXPECT_GT(cont.mean_deficit, 0.1) << "the ramp should be visibly shadowed";
  EXPECT_LT(cont.noise_floor, kMaxNoiseFloor);
  EXPECT_LT(clamped.noise_floor, kMaxNoiseFloor);
  EXPECT_LT(cont.error, kRampShadowTol + 2.0 * cont.noise_floor) << "SHEXP and the reference read the default rule differently";
  EXPECT_LT(clamped.error, kRampShadowTolClamped + 2.0 * clamped.noise_floor) << "SHEXP and the reference read 'clamped' differently";
  // The case is one where the reading matters: across readings the error is far beyond either tolerance.
  EXPECT_GT(across.error, 4.0 * (kRampShadowTolClamped + 2.0 * clamped.noise_floor));
}

// --- background pixels -------------------------------------------------------------------------------

// Where no surface is seen, the technique's final image and the reference's show the same thing: the
// environment along the pixel-centre ray, by the same function (render::background_radiance), whatever
// light model the reference shades the surfaces with. Both evaluate it on the same float direction
// (one camera model), and the reference's average of identical samples is exact in double, so only
// the final float conversion may differ.
constexpr double kBackgroundRelTol = 1e-6;

TEST(ShexpRender, BackgroundPixelsEqualTheReference) {
  scene::Scene s = scene::make_builtin("spheres");
  s.camera.target = {0.0f, 1.2f, 0.0f};  // raise the view so that the horizon and the sky are in it
  render::RenderRequest req;
  req.width = 48;
  req.height = 36;
  req.outputs = {"final", render::kGBuffer};
  const render::FrameResult r = render_shexp(s, {}, req);
  const auto& gb = std::any_cast<const render::GBuffer&>(r.resources.at(render::kGBuffer));
  for (int sh_order : {0, 4}) {
    reference::ReferenceOptions ro;
    ro.spp = 2;
    ro.width = req.width;
    ro.height = req.height;
    ro.jitter = false;
    ro.light_sh_order = sh_order;
    const reference::ReferenceResult ref = reference::render_reference(s, ro);
    std::size_t background = 0;
    double worst = 0.0;
    for (std::size_t i = 0; i < gb.object.size(); ++i) {
      if (gb.hit(i)) continue;
      ++background;
      for (int c = 0; c < 3; ++c) {
        const double a = r.final_image.rgb[i][c], b = ref.final_image.rgb[i][c];
        worst = std::max(worst, std::abs(a - b) / std::max(1e-30, std::abs(b)));
      }
    }
    std::printf("[measured] %zu background pixels, worst relative difference %.3g (reference light SH order %d)\n", background,
                worst, sh_order);
    ASSERT_GT(background, 100u) << "the view should show the sky";
    EXPECT_LE(worst, kBackgroundRelTol) << "reference light SH order " << sh_order;
  }
}

// The reference of the technique's own problem (blockers = ProxiesOnly, order-n SH light): on
// `thin_wall`, which has no proxy set, shexp shadows nothing, and neither does that reference, so the
// two agree up to the order-4 shading of the light and the reference's noise; against the real
// geometry (the wall, the room) they are far apart. This is what lets the report's error budget put
// the walls under proxy geometry rather than under the technique's approximation.
TEST(ShexpRender, MatchesTheProxiesOnlyReferenceOnASceneWithoutProxies) {
  const scene::Scene s = scene::make_builtin("thin_wall");
  ASSERT_TRUE(s.proxies.empty());
  render::RenderRequest req;
  req.width = 32;
  req.height = 24;
  req.outputs = {"final", render::kGBuffer};
  const render::FrameResult r = render_shexp(s, {}, req);
  const auto& gb = std::any_cast<const render::GBuffer&>(r.resources.at(render::kGBuffer));
  Mask surface{req.width, req.height, std::vector<std::uint8_t>(gb.object.size(), 0)};
  for (std::size_t i = 0; i < gb.object.size(); ++i) surface.on[i] = gb.hit(i) ? 1 : 0;
  reference::ReferenceOptions ro;
  ro.spp = 64;
  ro.width = req.width;
  ro.height = req.height;
  ro.jitter = false;
  ro.light_sh_order = 4;
  ro.blockers = reference::ReferenceOptions::Blockers::ProxiesOnly;
  const double own = metrics::compare(r.final_image, reference::render_reference(s, ro).final_image, surface).relmse;
  ro.blockers = reference::ReferenceOptions::Blockers::Geometry;
  const double real = metrics::compare(r.final_image, reference::render_reference(s, ro).final_image, surface).relmse;
  std::printf("[measured] thin_wall 32x24: relMSE %.4g against its own problem, %.4g against the real geometry\n", own, real);
  // Measured 0.0016 and 0.58 (the quick report at 64 px: approximation 0.0003-0.0021, total
  // 0.59-0.61). 0.01 leaves room for the 64-spp reference's noise; 0.1 is far below what the walls'
  // missing shadows cost.
  EXPECT_LT(own, 0.01);
  EXPECT_GT(real, 0.1);
}

TEST(ShexpRender, SecondFrameReusesTablesHierarchyAndClusters) {
  techniques::register_all();
  scene::Scene s = test_scene(false, true, true);
  backends::CpuBackend cpu;
  auto t = render::create_technique("shexp");
  render::ParamSet p = render::default_params(*t);
  render::RenderRequest req;
  cpu.render(*t, s, p, req);
  render::FrameResult r2 = cpu.render(*t, s, p, req);
  for (const auto& pass : r2.passes) {
    if (pass.name == "tables" || pass.name == "hierarchy_build" || pass.name == "light_tables") {
      EXPECT_EQ(pass.counters.at("cached"), 1.0) << pass.name;
    }
    if (pass.name == "receiver_setup") {
      EXPECT_EQ(pass.counters.at("reclustered"), 0.0);
    }
  }
}

double pass_counter(const render::FrameResult& r, const std::string& pass, const std::string& counter) {
  for (const auto& rec : r.passes)
    if (rec.name == pass) return rec.counters.at(counter);
  ADD_FAILURE() << "no pass " << pass;
  return -1.0;
}

TEST(ShexpRender, EditedProxySetRebuildsTheHierarchy) {
  // The hierarchy is cached in the technique across frames; an edit of one sphere in the middle of
  // a set (same Scene object, same sphere count, same first sphere) must rebuild it, and the frame
  // must then equal a fresh technique's frame of the edited scene. Static scenes also key on the
  // posed spheres (no per-frame refit): moving the blocker node must rebuild as well.
  techniques::register_all();
  backends::CpuBackend cpu;
  for (bool animated : {false, true}) {
    SCOPED_TRACE(animated ? "animated" : "static");
    // The blocker 2 m up and receiver clusters of about 9 vertices: the eq. 36 cut takes inner
    // nodes whole, so a stale tree's bounds would change the shadow, not only the counter.
    scene::Scene s = test_scene(animated, true, true);
    s.nodes[1].translation.y = 2.0f;
    for (auto& clip : s.clips)
      for (auto& ch : clip.channels)
        for (glm::vec4& v : ch.values) v.y = 2.0f;
    auto t = render::create_technique("shexp");
    render::ParamSet p = render::default_params(*t);
    p.set("receiver_clusters", "16");
    render::RenderRequest req;
    req.width = 48;
    req.height = 36;
    req.time = 0.25;
    cpu.render(*t, s, p, req);
    EXPECT_EQ(pass_counter(cpu.render(*t, s, p, req), "hierarchy_build", "cached"), 1.0);
    std::vector<std::function<void(scene::Scene&)>> edits = {
        [](scene::Scene& e) { e.proxies[0].spheres[3].center += glm::vec3(0.0f, 0.3f, 0.25f); },
        [](scene::Scene& e) { e.proxies[0].spheres[2].radius *= 1.5f; }};
    if (!animated) edits.push_back([](scene::Scene& e) { e.nodes[1].translation += glm::vec3(0.3f, 0.0f, 0.0f); });
    for (size_t k = 0; k < edits.size(); ++k) {
      SCOPED_TRACE("edit " + std::to_string(k));
      edits[k](s);
      const render::FrameResult edited = cpu.render(*t, s, p, req);
      EXPECT_EQ(pass_counter(edited, "hierarchy_build", "cached"), 0.0);
      EXPECT_GT(pass_counter(edited, "blocker_cut", "inner_in_cuts"), 0.0) << "the cut should take inner nodes";
      auto fresh_t = render::create_technique("shexp");
      const render::FrameResult fresh = cpu.render(*fresh_t, s, p, req);
      ASSERT_EQ(edited.final_image.rgb.size(), fresh.final_image.rgb.size());
      // Same inputs, same deterministic passes: the images agree bit for bit.
      std::size_t differ = 0;
      for (std::size_t i = 0; i < fresh.final_image.rgb.size(); ++i) differ += edited.final_image.rgb[i] != fresh.final_image.rgb[i];
      EXPECT_EQ(differ, 0u) << "pixels that differ from a fresh technique's frame";
    }
  }
}

TEST(ShexpRender, TheGBufferHoldsOnlyThePlanesToImageReads) {
  // to_image reads the visibility planes and derives albedo and the background's directions itself:
  // the frame's G-buffer leaves out every other plane, and the image is the one a frame with the
  // whole G-buffer (requested as an output, so to_image reads the planes) makes, to the bit.
  techniques::register_all();
  backends::CpuBackend cpu;
  auto t = render::create_technique("shexp");
  const render::ParamSet p = render::default_params(*t);
  EXPECT_EQ(t->gbuffer_planes(p), render::kGBufferVisibility);
  scene::Scene s = scene::make_builtin("character");
  s.camera.width = 64;
  s.camera.height = 48;
  render::RenderRequest plain;
  render::RenderRequest whole;
  whole.outputs = {render::kDirect, render::kGBuffer};
  const render::FrameResult a = cpu.render(*t, s, p, plain);
  const render::FrameResult b = cpu.render(*t, s, p, whole);
  ASSERT_EQ(a.direct.rgb.size(), b.direct.rgb.size());
  for (std::size_t i = 0; i < a.direct.rgb.size(); ++i) ASSERT_EQ(a.direct.rgb[i], b.direct.rgb[i]) << "pixel " << i;
  const auto& gb = std::any_cast<const render::GBuffer&>(b.resources.at(render::kGBuffer));
  EXPECT_EQ(gb.planes, unsigned(render::kGBufferAll));
  EXPECT_EQ(gb.position.size(), gb.object.size());
  auto pass_bytes = [](const render::FrameResult& r) { return test::pass_counter(r, "gbuffer", "bytes_moved"); };
  const auto n = static_cast<double>(s.camera.width * s.camera.height);
  EXPECT_EQ(pass_bytes(a), n * 16.0) << "object, primitive, barycentric";
  EXPECT_EQ(pass_bytes(b), n * 68.0) << "every plane";
}
