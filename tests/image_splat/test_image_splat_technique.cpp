// The image-space technique (paper 000) end to end: its pass graph and pruning, parameter errors,
// renders of every built-in scene in every mode, the receiver buffer at full resolution against a
// per-pixel brute-force evaluation of eq. 10, the eq. 12 bound under heavy proxy overlap, and smooth
// clamping at the boundary of a proxy's sphere of influence.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../techniques/image_splat/image_splat_internal.hpp"
#include "../backends/test_scene_util.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/vertex_image.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/sh/product.hpp"
#include "softgi/techniques/registry.hpp"
#include "../support/pass_counter.hpp"

using namespace softgi;

namespace {

render::FrameResult render_frame(const scene::Scene& sc, const std::vector<std::string>& assignments, int w, int h,
                                 render::Technique* reuse = nullptr, double t = 0.0) {
  techniques::register_all();
  std::unique_ptr<render::Technique> own;
  if (!reuse) {
    own = render::create_technique("image_splat");
    reuse = own.get();
  }
  render::ParamSet p = render::default_params(*reuse);
  for (const auto& a : assignments) p.set_assignment(a);
  backends::CpuBackend cpu;
  render::RenderRequest req;
  req.width = w;
  req.height = h;
  req.time = t;
  return cpu.render(*reuse, sc, p, req);
}

std::vector<std::string> executed(const scene::Scene& s, const std::vector<std::string>& assignments = {}) {
  techniques::register_all();
  auto t = render::create_technique("image_splat");
  render::ParamSet p = render::default_params(*t);
  for (const auto& a : assignments) p.set_assignment(a);
  render::NullBackend null;
  null.render(*t, s, p, render::RenderRequest{});
  return null.executed;
}

bool has(const std::vector<std::string>& v, const std::string& x) { return std::find(v.begin(), v.end(), x) != v.end(); }

// Every pixel finite and >= 0; returns the largest channel value.
float check_image(const Image& img, const std::string& what) {
  float mx = 0.0f;
  for (std::size_t i = 0; i < img.rgb.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = img.rgb[i][c];
      EXPECT_TRUE(std::isfinite(v) && v >= 0.0f) << what << ": pixel " << i << " channel " << c << " = " << v;
      if (!(std::isfinite(v) && v >= 0.0f)) return mx;
      mx = std::max(mx, v);
    }
  return mx;
}

// The display G-buffer of a scene (the shared pass on the CPU backend).
render::GBuffer gbuffer_of(const scene::Scene& sc, int w, int h) {
  backends::CpuBackend backend;
  const render::PassFn* fn = render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName);
  scene::PosedScene posed = scene::evaluate(sc, 0.0);
  render::ParamSet params;
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, w, h, result);
  result.passes.push_back(render::PassRecord{"gbuffer"});
  (*fn)(ctx);
  return ctx.get<render::GBuffer>(render::kGBuffer);
}

// A ground grid (y = 0, `size` across, albedo 0.5) with one proxy set bound to the ground node.
scene::Scene ground_scene(const std::vector<scene::Sphere>& spheres, glm::vec3 proxy_albedo, glm::vec3 cam_pos, glm::vec3 target) {
  scene::Scene s;
  s.name = "ground";
  s.source = "test";
  s.materials.resize(1);
  s.materials[0].albedo = glm::vec3(0.5f);
  scene::Mesh m;
  m.name = "ground";
  const int n = 5;
  const float size = 8.0f;
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
  m.material = 0;
  s.meshes.push_back(m);
  scene::Node node;
  node.name = "ground";
  node.mesh = 0;
  s.nodes.push_back(node);
  if (!spheres.empty()) {
    scene::ProxySet ps;
    ps.name = "cluster";
    ps.node = 0;
    ps.spheres = spheres;
    ps.albedo = proxy_albedo;
    s.proxies.push_back(ps);
  }
  s.camera.position = cam_pos;
  s.camera.target = target;
  s.camera.fov_y_deg = 40.0f;
  return s;
}

}  // namespace

// --- the pass graph --------------------------------------------------------------------------------

TEST(ImageSplatGraph, FullGraphWithProxies) {
  const auto e = executed(softgi::testing::with_proxies(softgi::testing::make_plane_sphere_scene(16, 12)));
  for (const char* p : {"gbuffer", "receiver_gbuffer", "tables", "indirect_tables", "receivers", "bin_proxies", "accumulate_log",
                        "exponentiate", "accumulate_indirect", "normalize_indirect", "upsample", "robust_misses", "shade_direct",
                        "shade_indirect", "compose"})
    EXPECT_TRUE(has(e, p)) << p;
  EXPECT_FALSE(has(e, "light_tables"));  // no spherical light
  const auto pos = [&](const std::string& n) { return std::find(e.begin(), e.end(), n) - e.begin(); };
  EXPECT_LT(pos("gbuffer"), pos("receiver_gbuffer"));
  EXPECT_LT(pos("bin_proxies"), pos("accumulate_log"));
  EXPECT_LT(pos("exponentiate"), pos("normalize_indirect"));
  EXPECT_LT(pos("upsample"), pos("robust_misses"));
  EXPECT_LT(pos("robust_misses"), pos("shade_direct"));
}

TEST(ImageSplatGraph, NoProxiesPrunesShadowAndIndirectPasses) {
  const auto e = executed(softgi::testing::make_plane_sphere_scene(16, 12));
  for (const char* p : {"tables", "indirect_tables", "bin_proxies", "accumulate_log", "exponentiate", "accumulate_indirect",
                        "normalize_indirect", "robust_misses", "shade_indirect"})
    EXPECT_FALSE(has(e, p)) << p;
  for (const char* p : {"gbuffer", "receiver_gbuffer", "receivers", "upsample", "shade_direct", "compose"}) EXPECT_TRUE(has(e, p)) << p;
}

TEST(ImageSplatGraph, IndirectOffPrunesIndirectPassesAndShadedFallbackHasNoRobustPass) {
  const scene::Scene s = softgi::testing::with_proxies(softgi::testing::make_plane_sphere_scene(16, 12));
  const auto e = executed(s, {"indirect=false"});
  for (const char* p : {"indirect_tables", "accumulate_indirect", "normalize_indirect", "shade_indirect"}) EXPECT_FALSE(has(e, p)) << p;
  for (const char* p : {"tables", "accumulate_log", "exponentiate", "shade_direct"}) EXPECT_TRUE(has(e, p)) << p;
  EXPECT_FALSE(has(executed(s, {"fallback=shaded"}), "robust_misses"));
  EXPECT_FALSE(has(executed(s, {"fallback=none"}), "robust_misses"));
  // The CPU backend produces no indirect image when indirect light is off.
  const render::FrameResult r = render_frame(s, {"indirect=false"}, 16, 12);
  EXPECT_TRUE(r.indirect.empty());
  EXPECT_FALSE(r.final_image.empty());
}

TEST(ImageSplatGraph, InconsistentParametersAreRejectedByName) {
  techniques::register_all();
  auto t = render::create_technique("image_splat");
  const scene::Scene s = softgi::testing::with_proxies(softgi::testing::make_plane_sphere_scene(16, 12));
  const auto expect_error = [&](const std::vector<std::string>& a, const std::vector<std::string>& names) {
    render::ParamSet p = render::default_params(*t);
    for (const auto& x : a) p.set_assignment(x);
    std::set<std::string> empty;
    try {
      t->plan(s, p, empty);
      ADD_FAILURE() << a[0] << " accepted";
    } catch (const std::invalid_argument& e) {
      for (const auto& n : names) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
    }
  };
  expect_error({"indirect_order=4"}, {"indirect_operator", "indirect_order"});
  expect_error({"receiver_scale=3"}, {"receiver_scale"});
  expect_error({"eta_shadow=0.5"}, {"eta_shadow"});
  expect_error({"eta_indirect=1"}, {"eta_indirect"});
  expect_error({"window_h=0.5"}, {"window_h"});
  render::ParamSet p = render::default_params(*t);
  p.set_assignment("indirect_order=4");
  p.set_assignment("indirect_operator=averaged");
  std::set<std::string> empty;
  EXPECT_NO_THROW(t->plan(s, p, empty));
  EXPECT_THROW(p.set_assignment("receiver_scale=16"), std::invalid_argument);
  EXPECT_THROW(p.set_assignment("indirect_operator=magic"), std::invalid_argument);
  EXPECT_THROW(p.set_assignment("upsample=nearest"), std::invalid_argument);
  EXPECT_THROW(p.set_assignment("fallback=ignore"), std::invalid_argument);
  EXPECT_THROW(p.set_assignment("tile_size=1"), std::invalid_argument);
}

TEST(ImageSplatGraph, NonFiniteProxySpheresAreNamed) {
  scene::Scene s = softgi::testing::with_proxies(softgi::testing::make_plane_sphere_scene(16, 12));
  s.proxies[0].spheres.push_back({glm::vec3(0.0f, std::numeric_limits<float>::infinity(), 0.0f), 0.1f});
  try {
    render_frame(s, {}, 16, 12);
    FAIL() << "infinite sphere accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("proxy set 'sphere'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sphere 1"), std::string::npos) << e.what();
  }
}

// --- every scene, every mode -------------------------------------------------------------------------

TEST(ImageSplatRender, EveryBuiltinSceneGivesFiniteNonNegativeImages) {
  for (const auto& info : scene::builtin_scenes()) {
    // Only a scene that needs the asset set may be missing; any other error fails the test.
    scene::Scene sc;
    try {
      sc = scene::make_builtin(info.name);
    } catch (const std::runtime_error& e) {
      if (!info.needs_assets) throw;
      std::cout << "skipping " << info.name << " (its assets are absent: run scripts/fetch-assets.sh): " << e.what() << "\n";
      continue;
    }
    const render::FrameResult r = render_frame(sc, {}, 64, 48, nullptr, 0.3);
    check_image(r.final_image, info.name + " final");
    const float d = check_image(r.direct, info.name + " direct");
    EXPECT_GT(d, 0.0f) << info.name;
    bool proxies = false;
    for (const auto& p : sc.proxies) proxies = proxies || !p.spheres.empty();
    EXPECT_EQ(r.indirect.empty(), !proxies) << info.name;
    // The proxies re-radiate the environment's light: under a dark environment (scenes lit by local
    // lights only) their indirect light is zero.
    const auto& env = sc.environment;
    const bool dark = env.kind == scene::Environment::Kind::Sky && env.zenith == glm::vec3(0.0f) && env.horizon == glm::vec3(0.0f) &&
                      env.ground == glm::vec3(0.0f) && env.sun_radiance == glm::vec3(0.0f);
    if (!r.indirect.empty() && !dark) { EXPECT_GT(check_image(r.indirect, info.name + " indirect"), 0.0f) << info.name; }
  }
}

TEST(ImageSplatRender, EveryModeGivesFiniteNonNegativeImages) {
  const scene::Scene sc = scene::make_builtin("cornell");  // proxies and a spherical light
  techniques::register_all();
  auto t = render::create_technique("image_splat");
  const std::vector<std::vector<std::string>> modes = {
      {"indirect_operator=point"},  {"indirect_operator=averaged"}, {"indirect_operator=exact"},
      {"indirect_operator=averaged", "indirect_order=5"},             {"upsample=bilinear", "fallback=robust"},
      {"upsample=bilinear", "fallback=shaded"},                       {"upsample=bilinear", "fallback=none"},
      {"fallback=shaded"},          {"fallback=none"},              {"receiver_scale=1"},
      {"receiver_scale=8", "tile_size=4"},                            {"exp=ol"},
      {"exp=ps*"},                  {"exp=exact", "order=3"},       {"coverage=environment"},
      {"coverage=paper"},           {"coverage=off"},               {"smooth_clamp=false"},
      {"replacement_rule=printed"}, {"self_shadow_rules=false"},    {"normalize_indirect=false"},
      {"analytic_lights=false"},    {"window_h=0", "order=6"},      {"eta_shadow=4", "eta_indirect=3"},
      {"kernel=scalar"}};
  for (const auto& m : modes) {
    std::string name;
    for (const auto& a : m) name += a + " ";
    const render::FrameResult r = render_frame(sc, m, 40, 30, t.get(), 0.5);
    check_image(r.final_image, name + "final");
    EXPECT_GT(check_image(r.indirect, name + "indirect"), 0.0f) << name;
  }
}

// shade_interpolation: interpolating transfer rows (with O_p alongside for the spherical lights) and
// interpolating O_p then taking the SH product per pixel are the same sum reassociated
// (common::ShadeTransfer), so the direct images agree to float
// rounding: kReassociationTol of the brightest pixel (sums of 16-48 O(1) float terms, about 1e-6 each,
// with room for the clamp at 0). Both paths must have run: the transfer path rounds differently, so
// some pixels differ in their last bits (bit-identical images would mean the parameter was ignored).
TEST(ImageSplatRender, TransferRowsShadeAsTheInterpolatedVisibility) {
  constexpr double kReassociationTol = 2e-5;
  techniques::register_all();
  for (const char* scene_name : {"spheres", "character", "cornell"}) {  // cornell: a spherical light
    const scene::Scene sc = scene::make_builtin(scene_name);
    const render::FrameResult a = render_frame(sc, {"indirect=false", "shade_interpolation=transfer"}, 96, 72);
    const render::FrameResult b = render_frame(sc, {"indirect=false", "shade_interpolation=visibility"}, 96, 72);
    ASSERT_EQ(a.direct.rgb.size(), b.direct.rgb.size());
    float peak = 0.0f;
    for (const auto& c : b.direct.rgb) peak = std::max({peak, c.x, c.y, c.z});
    ASSERT_GT(peak, 0.0f) << scene_name;
    double worst = 0.0;
    std::size_t differ = 0;
    for (std::size_t i = 0; i < a.direct.rgb.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double d = std::abs(static_cast<double>(a.direct.rgb[i][c]) - b.direct.rgb[i][c]);
        worst = std::max(worst, d);
        differ += d > 0.0;
      }
    EXPECT_LE(worst, kReassociationTol * peak) << scene_name;
    EXPECT_GT(differ, 0u) << scene_name << ": identical images, so one path was not taken";
    std::printf("[transfer] %-9s worst difference %.3g of the brightest pixel, %zu channels differ\n", scene_name, worst / peak, differ);
  }
}

// --- receiver_scale = 1 against eq. 10 evaluated per pixel ---------------------------------------------

// Everything in double from the closed forms of the SH core: log occlusion ZH of each (rule-adjusted)
// sphere (paper 004 eq. 34 with sh::cap_log_zh), exact exponential, H(N) * O dotted with L (eq. 10's
// first term); the averaged operator with D by quadrature (eq. 15), the order-3 proxy visibility
// 1 - cap visibility, omega = 2 pi (1 - cos theta) (eq. 2), xi by eq. 12. coverage=off, so no sphere of
// influence: the technique's float tables (256 rows in theta, linear interpolation) are the only
// approximation on its side.
TEST(ImageSplatRender, FullResolutionReceiversMatchPerPixelBruteForce) {
  // Linear interpolation of the 256-row tables in theta (up to about 1e-4 relative in the log vector
  // near small angles), float accumulation and the float exact exponential against double closed
  // forms: measured 3e-5 of the image's largest value; 5e-4 leaves room for other ISAs' rounding
  // without hiding a wrong term (a missing band or a swapped channel costs > 1e-2).
  constexpr double kRelTol = 5e-4;
  const int W = 40, H = 30;
  const scene::Scene sc = softgi::testing::with_proxies(softgi::testing::make_plane_sphere_scene(W, H));
  const render::FrameResult r = render_frame(
      sc, {"receiver_scale=1", "coverage=off", "exp=exact", "window_h=0", "indirect_operator=averaged", "fallback=none"}, W, H);
  for (const auto& p : r.passes)
    if (p.name == "upsample") { EXPECT_EQ(p.counters.at("misses"), 0.0) << "scale 1 must not miss"; }
  const render::GBuffer gb = gbuffer_of(sc, W, H);
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const int n = 4, n2 = 16, ni = 3, ni2 = 9;
  const std::vector<glm::vec3> env = scene::environment_sh(sc.environment, n);
  std::array<std::vector<double>, 3> L, Lt;
  for (int c = 0; c < 3; ++c) {
    L[c].resize(n2);
    for (int k = 0; k < n2; ++k) L[c][k] = env[k][c];
    Lt[c].resize(ni2);
    sh::irradiance_env<double>(ni, L[c].data(), Lt[c].data());
  }
  const double s4pi = sh::kSqrt4Pi;
  double max_direct = 0.0, max_indirect = 0.0, err_direct = 0.0, err_indirect = 0.0;
  int pixels = 0, shadowed = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    if (!gb.hit(i)) continue;
    const glm::vec3 p = gb.position[i], N = gb.normal[i];
    std::vector<double> f(n2, 0.0), tmp(n2), Hn(n2), H3(ni2);
    sh::irradiance_weight<double>(n, {N.x, N.y, N.z}, Hn.data());
    sh::irradiance_weight<double>(ni, {N.x, N.y, N.z}, H3.data());
    glm::dvec3 ind(0.0);
    double omega = 0.0;
    for (const auto& sp : posed.proxies[0]) {
      const auto a = techniques::common::apply_replacement_rule(techniques::common::ReplacementRule::Continuous, p, N, sp.center, sp.radius);
      if (!(a.radius > 0.0f)) continue;
      const glm::dvec3 dv = glm::dvec3(a.center) - glm::dvec3(p);
      const double d = glm::length(dv);
      const sh::Vec3<double> dir{dv.x / d, dv.y / d, dv.z / d};
      const double alpha = std::min(1.0, a.radius / d), theta = std::asin(alpha);
      const std::vector<double> z = sh::cap_log_zh(n, theta, 0.02);
      sh::zh_rotate<double>(n, z.data(), dir, tmp.data());
      for (int k = 0; k < n2; ++k) f[k] += tmp[k];
      // Indirect, averaged operator: kappa = rot(D, d) . L~, I . H = kappa (V . H).
      const std::vector<double> D = sh::indirect_D_quadrature(ni, alpha), cv = sh::cap_visibility_zh(ni, theta);
      std::vector<double> Dr(ni2), Vz(ni), Vr(ni2);
      sh::zh_rotate<double>(ni, D.data(), dir, Dr.data());
      for (int l = 0; l < ni; ++l) Vz[l] = (l == 0 ? s4pi : 0.0) - cv[l];
      sh::zh_rotate<double>(ni, Vz.data(), dir, Vr.data());
      double vh = 0.0;
      for (int k = 0; k < ni2; ++k) vh += Vr[k] * H3[k];
      for (int c = 0; c < 3; ++c) {
        double kappa = 0.0;
        for (int k = 0; k < ni2; ++k) kappa += Dr[k] * Lt[c][k];
        ind[c] += sc.proxies[0].albedo[c] / sh::kPi * kappa * vh;
      }
      omega += 2.0 * sh::kPi * (1.0 - std::cos(theta));
    }
    std::vector<double> O(n2);
    sh::ExpOptions eo;
    eo.method = sh::ExpMethod::Exact;
    sh::exp<double>(n, f.data(), O.data(), eo, nullptr);
    const std::vector<double> HO = sh::product<double>(n, Hn, O);
    const double xi = omega > 1e-7 ? std::clamp((s4pi - O[0]) / (omega / s4pi), 0.0, 1.0) : 1.0;
    shadowed += O[0] < 0.99 * s4pi;
    for (int c = 0; c < 3; ++c) {
      double e = 0.0;
      for (int k = 0; k < n2; ++k) e += HO[k] * L[c][k];
      const double direct = std::max(0.0, e) * gb.albedo[i][c];
      const double indirect = std::max(0.0, xi * ind[c]) * gb.albedo[i][c];
      max_direct = std::max(max_direct, direct);
      max_indirect = std::max(max_indirect, indirect);
      err_direct = std::max(err_direct, std::abs(direct - r.direct.rgb[i][c]));
      err_indirect = std::max(err_indirect, std::abs(indirect - r.indirect.rgb[i][c]));
    }
    ++pixels;
  }
  ASSERT_GT(pixels, 200);
  ASSERT_GT(shadowed, 20) << "the proxy must shadow part of the image";
  ASSERT_GT(max_indirect, 1e-3 * max_direct) << "indirect light must be visible";
  EXPECT_LE(err_direct, kRelTol * max_direct) << "max direct " << max_direct;
  EXPECT_LE(err_indirect, kRelTol * max_indirect) << "max indirect " << max_indirect;
}

// --- eq. 12 under heavy overlap --------------------------------------------------------------------------

// 200 proxies around one spot above a ground plane. Without shadowing between proxies, the radiance any
// proxy shows is at most max albedo / pi * max_s L~(s); the receiver sees radiance no brighter than that
// over at most its hemisphere, and H integrates to 1 there, so I_p . H(N_p) cannot exceed that bound.
// eq. 12 keeps it there by normalising with the union's solid angle; the plain sum (normalize_indirect =
// false) counts every overlap again and exceeds it many times.
TEST(ImageSplatRender, OverlappingProxiesNeverExceedTheUnshadowedBound) {
  // The union's solid angle comes from the HYB exponential of 200 accumulated logs (paper 004: DC errors
  // of a few percent under heavy overlap), and the order-3 truncation of V . H rings by a few percent:
  // 10% of the bound.
  constexpr double kExpTol = 0.10;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<scene::Sphere> spheres;
  for (int k = 0; k < 200; ++k)
    spheres.push_back({glm::vec3(0.3f * u(rng), 0.6f + 0.2f * u(rng), 0.3f * u(rng)), 0.18f + 0.07f * u(rng)});
  const glm::vec3 proxy_albedo(0.9f, 0.6f, 0.3f);
  scene::Scene sc = ground_scene(spheres, proxy_albedo, {0.0f, 3.5f, 3.0f}, {0.0f, 0.0f, 0.0f});
  // A uniform environment: every point of every proxy shows the same radiance albedo L, so the bound
  // is tight (a receiver whose hemisphere were all proxy would reach it).
  sc.environment.zenith = sc.environment.horizon = sc.environment.ground = glm::vec3(1.0f, 0.8f, 0.6f);
  sc.environment.sun_radiance = sc.environment.zenith;  // the sun disk replaces the sky: same radiance
  // L~ the proxies re-radiate: the windowed (h = 2n = 8) order-4 light truncated to order 3, convolved.
  const std::vector<glm::vec3> env = scene::environment_sh(sc.environment, 4);
  std::vector<glm::vec3> Lw(env);
  for (int l = 0; l < 4; ++l)
    for (int m = -l; m <= l; ++m) Lw[sh::index(l, m)] *= static_cast<float>(sh::window_factor(l, 8.0));
  const std::vector<glm::vec3> Lt = techniques::image_splat::irradiance_sh(Lw, 3);
  glm::dvec3 bound(0.0);
  for (int a = 0; a <= 180; ++a)
    for (int b = 0; b < 360; ++b) {
      const double th = sh::kPi * a / 180.0, ph = 2.0 * sh::kPi * b / 360.0;
      std::array<double, 9> y{};
      sh::eval_basis<double>(3, {std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph)}, y.data());
      for (int c = 0; c < 3; ++c) {
        double v = 0.0;
        for (int k = 0; k < 9; ++k) v += Lt[k][c] * y[k];
        bound[c] = std::max(bound[c], proxy_albedo[c] / sh::kPi * v);
      }
    }
  const glm::vec3 ground_albedo(0.5f);
  for (bool normalise : {true, false}) {
    const render::FrameResult r =
        render_frame(sc, {"receiver_scale=1", normalise ? "normalize_indirect=true" : "normalize_indirect=false"}, 32, 24);
    double worst = 0.0;  // largest I . H relative to the bound
    for (const auto& px : r.indirect.rgb)
      for (int c = 0; c < 3; ++c) worst = std::max(worst, px[c] / ground_albedo[c] / bound[c]);
    // docs/techniques/image_splat.md quotes this line.
    std::cout << (normalise ? "eq. 12 normalised" : "plain sum") << ": largest I . H / unshadowed bound = " << worst << "\n";
    if (normalise) {
      EXPECT_LE(worst, 1.0 + kExpTol);
      EXPECT_GT(worst, 0.1) << "the cluster must light the ground";
    } else {
      EXPECT_GT(worst, 2.0) << "the plain sum must exceed the bound (else this test cannot fail)";
    }
  }
}

// --- smooth clamping at the boundary of the sphere of influence --------------------------------------------

// One proxy directly above a ground receiver moves away through the boundary of its sphere of
// influence in small steps; the receiver's direct shading is followed. With smooth clamping the
// clamped log table w(theta) F(theta) changes by at most its full value F over one table row (w rises
// from 0 to 1 over several rows), so per step the shading moves by at most J * (rows crossed per step) *
// 1.5, J the proxy's whole effect at the end of the ramp (1.5: the shading is not exactly linear in the
// log vector). With a hard cut at eta r the whole effect at eta r vanishes in one step.
TEST(ImageSplatRender, SmoothClampingLeavesNoJumpAtTheBoundaryOfInfluence) {
  constexpr double kNonlinearity = 1.5;
  const float r = 0.05f;
  const int W = 9, H = 9;  // the centre pixel sees the target, the origin
  scene::Scene sc = ground_scene({{glm::vec3(0.0f, 1.0f, 0.0f), r}}, glm::vec3(0.5f), {0.0f, 2.0f, 2.0f}, {0.0f, 0.0f, 0.0f});
  const std::size_t centre = static_cast<std::size_t>(H / 2) * W + W / 2;
  techniques::register_all();
  auto t = render::create_technique("image_splat");
  // eta from the technique's own derivation (the tables pass records it).
  const render::FrameResult probe = render_frame(sc, {"receiver_scale=1", "indirect=false"}, W, H, t.get());
  double eta = 0.0;
  for (const auto& p : probe.passes)
    if (p.name == "tables") eta = p.counters.at("eta_shadow");
  ASSERT_GT(eta, 1.0);
  const int rows = 256;
  const double row = (sh::kPi / 2.0) / (rows - 1);
  // Ramp: zero up to the first row at or above asin(1/eta), full kClampRampRows + 1 rows later.
  const int k0 = static_cast<int>(std::ceil(std::asin(1.0 / eta) / row - 1e-9));
  // Steps uniform in the half-angle, from the end of the ramp to one row before its start.
  const double th_near = (k0 + techniques::image_splat::kClampRampRows + 2) * row, th_far = (k0 - 1) * row;
  const auto dist = [&](int k, int steps) { return r / std::sin(th_near + (th_far - th_near) * k / steps); };
  ASSERT_LT(dist(0, 1), eta * r);
  ASSERT_GT(dist(1, 1), eta * r);
  const auto shade_at = [&](double d, bool smooth) {
    sc.proxies[0].spheres[0].center = glm::vec3(0.0f, static_cast<float>(d), 0.0f);
    const render::FrameResult f = render_frame(sc, {"receiver_scale=1", "indirect=false", smooth ? "smooth_clamp=true" : "smooth_clamp=false"},
                                               W, H, t.get());
    return static_cast<double>(f.direct.rgb[centre].y);
  };
  sc.proxies[0].spheres[0].center = glm::vec3(0.0f, 50.0f, 0.0f);
  const double unshadowed = shade_at(50.0, true);
  const double J = unshadowed - shade_at(dist(0, 1), true);
  ASSERT_GT(J, 1e-5 * unshadowed) << "the proxy must shadow the receiver at the end of the ramp";
  const int steps = 600;
  const double rows_per_step = (th_near - th_far) / row / steps;
  const double bound = J * rows_per_step * kNonlinearity;
  for (bool smooth : {true, false}) {
    double prev = shade_at(dist(0, steps), smooth), max_step = 0.0;
    for (int k = 1; k <= steps; ++k) {
      const double s = shade_at(dist(k, steps), smooth);
      max_step = std::max(max_step, std::abs(s - prev));
      prev = s;
    }
    // docs/techniques/image_splat.md quotes this line.
    std::cout << (smooth ? "smooth clamp" : "hard cut") << ": largest shading change per step " << max_step << " (bound " << bound
              << ", " << steps << " steps)\n";
    EXPECT_NEAR(prev, unshadowed, 1e-6 * unshadowed) << "beyond the sphere of influence the proxy has no effect";
    if (smooth) {
      EXPECT_LE(max_step, bound) << "J " << J << " rows per step " << rows_per_step;
    } else {
      EXPECT_GT(max_step, bound) << "a hard cut must jump (else this test cannot fail)";
    }
  }
}

// --- bilateral upsampling at a depth discontinuity (section 4.2) --------------------------------------------

namespace {
// A quad facing +z at depth z (camera at the origin looking down -z), spanning [x0, x1] x [y0, y1].
scene::Mesh facing_quad(const std::string& name, float x0, float x1, float y0, float y1, float z) {
  scene::Mesh m;
  m.name = name;
  m.positions = {{x0, y0, z}, {x1, y0, z}, {x1, y1, z}, {x0, y1, z}};
  m.normals.assign(4, glm::vec3(0.0f, 0.0f, 1.0f));
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  m.material = 0;
  return m;
}
}  // namespace

// Two parallel planes facing the camera: a near one (depth 2) over the left of the image, a far one
// (depth 6) behind. Proxies hover just in front of the far plane and darken it; they are behind the
// near plane's tangent plane, so the replacement rules drop them there and the near plane is bright.
// Eq. 11 with equal normals weighs a sample of the other plane by eps / (eps + |dz|) relative to a
// perfect match (eps = 0.01 z); a pixel that is not a miss has matching weight >= miss_threshold, so
// the other plane's share of its value is at most c = r / (miss_threshold + r), r = eps / (eps + |dz|).
// Hence at every pixel |bilateral - full resolution| <= c * contrast + (the interpolation error inside one
// plane); misses go to the robust pass. Plain bilinear upsampling mixes the planes and exceeds it.
TEST(ImageSplatRender, BilateralUpsamplingDoesNotMixTwoPlanesAtADepthEdge) {
  scene::Scene sc;
  sc.name = "two_planes";
  sc.source = "test";
  sc.materials.resize(1);
  sc.materials[0].albedo = glm::vec3(0.5f);
  sc.meshes = {facing_quad("near", -3.0f, 0.3f, -3.0f, 3.0f, -2.0f), facing_quad("far", -12.0f, 12.0f, -12.0f, 12.0f, -6.0f)};
  for (int k = 0; k < 2; ++k) {
    scene::Node n;
    n.name = sc.meshes[k].name;
    n.mesh = k;
    sc.nodes.push_back(n);
  }
  scene::ProxySet ps;
  ps.name = "veil";
  ps.node = 1;
  for (int i = -4; i <= 4; ++i)
    for (int j = -3; j <= 3; ++j) ps.spheres.push_back({glm::vec3(0.7f * i, 0.7f * j, -5.4f), 0.35f});
  sc.proxies.push_back(ps);
  sc.camera.position = glm::vec3(0.0f);
  sc.camera.target = glm::vec3(0.0f, 0.0f, -1.0f);
  sc.camera.fov_y_deg = 40.0f;
  const int W = 96, H = 64, S = 4;
  techniques::register_all();
  auto t = render::create_technique("image_splat");
  const std::vector<std::string> common = {"indirect=false", "fallback=robust"};
  auto with = [&](std::vector<std::string> a) {
    a.insert(a.end(), common.begin(), common.end());
    return render_frame(sc, a, W, H, t.get());
  };
  const render::FrameResult ref = with({"receiver_scale=1"});
  const render::GBuffer gb = gbuffer_of(sc, W, H);
  float lo = std::numeric_limits<float>::max(), hi = 0.0f;
  int near_pixels = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    ASSERT_TRUE(gb.hit(i));
    lo = std::min(lo, ref.direct.rgb[i].y);
    hi = std::max(hi, ref.direct.rgb[i].y);
    near_pixels += gb.object[i] == 0;
  }
  ASSERT_GT(near_pixels, W * H / 5);
  ASSERT_LT(near_pixels, W * H * 4 / 5);
  const float contrast = hi - lo;
  ASSERT_GT(contrast, 0.3f * hi) << "the planes must be shaded differently";
  // The largest share of the other plane eq. 11 can leave in a non-miss pixel (the far plane's eps is larger).
  constexpr double kMissThreshold = 0.05, kEpsRel = 0.01;
  const double eps = kEpsRel * 6.0, r = eps / (eps + 4.0), c = r / (kMissThreshold + r);
  // Pixels whose bilinear footprint (+-S display pixels) lies on one plane measure the interpolation
  // error within a plane; the others are at the edge.
  const auto interior = [&](int x, int y) {
    const int o = gb.object[static_cast<std::size_t>(y) * W + x];
    for (int v = std::max(0, y - S); v <= std::min(H - 1, y + S); ++v)
      for (int u = std::max(0, x - S); u <= std::min(W - 1, x + S); ++u)
        if (gb.object[static_cast<std::size_t>(v) * W + u] != o) return false;
    return true;
  };
  const auto errors = [&](const render::FrameResult& f, double& inner, double& edge) {
    inner = edge = 0.0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * W + x;
        const double e = std::abs(f.direct.rgb[i].y - ref.direct.rgb[i].y);
        (interior(x, y) ? inner : edge) = std::max(interior(x, y) ? inner : edge, e);
      }
  };
  double inner_bl = 0.0, edge_bl = 0.0, inner_li = 0.0, edge_li = 0.0;
  errors(with({"receiver_scale=4", "upsample=bilateral"}), inner_bl, edge_bl);
  errors(with({"receiver_scale=4", "upsample=bilinear"}), inner_li, edge_li);
  const double bound = c * contrast + inner_bl;
  EXPECT_LE(edge_bl, bound) << "contrast " << contrast << " c " << c << " interior error " << inner_bl;
  EXPECT_GT(edge_li, bound) << "bilinear must mix the planes (else this test cannot fail)";
}

// The tables pass records the eta it uses. With the light normalised to peak radiance 1
// (eta_light=unit_peak) the derivation reproduces the paper's stated values (section 4.1: "roughly
// eta = 15" for order-4 shadows, 10 for order-3 indirect); with the text's unit-shading
// normalisation it is larger (a stricter sphere of influence). kPaperAgreement: "roughly" in the
// paper; the derivation gives 14.5 and 9.3 (splat_math tests pin the values themselves).
TEST(ImageSplatRender, EtaLightNormalisationSelectsThePapersValues) {
  constexpr double kPaperAgreement = 0.1;  // relative
  const scene::Scene sc = scene::make_builtin("spheres");
  auto eta_of = [&](const std::string& light) {
    const render::FrameResult r = render_frame(sc, {"eta_light=" + light}, 32, 24, nullptr, 0.0);
    for (const auto& p : r.passes)
      if (p.name == "tables") return std::make_pair(p.counters.at("eta_shadow"), p.counters.at("eta_indirect"));
    ADD_FAILURE() << "no tables pass";
    return std::make_pair(0.0, 0.0);
  };
  const auto peak = eta_of("unit_peak");
  const auto shading = eta_of("unit_shading");
  EXPECT_NEAR(peak.first, 15.0, 15.0 * kPaperAgreement);
  EXPECT_NEAR(peak.second, 10.0, 10.0 * kPaperAgreement);
  EXPECT_GT(shading.first, peak.first * 1.5);
  EXPECT_GT(shading.second, peak.second * 1.2);
}

namespace {

TEST(ImageSplatRender, TheGBufferLeavesOutViewDirAndTheImageIsUnchanged) {
  // Upsampling and shading read the surface planes and albedo; shade_direct takes the background's
  // rays from the camera. The frame's G-buffer leaves view_dir out (and the CPU G-buffer then tests
  // the sides of surfaces with unnormalised rays); the image equals, to the bit, that of a frame with
  // the whole G-buffer (requested as an output), and every background pixel is the environment seen
  // along that G-buffer's view_dir.
  techniques::register_all();
  backends::CpuBackend cpu;
  auto t = render::create_technique("image_splat");
  const render::ParamSet p = render::default_params(*t);
  EXPECT_EQ(t->gbuffer_planes(p), unsigned(render::kGBufferSurface | render::kGBufferAlbedo));
  scene::Scene s = scene::make_builtin("character");
  s.camera.width = 64;
  s.camera.height = 48;
  render::RenderRequest plain;
  plain.outputs = {render::kFinal, render::kDirect};
  render::RenderRequest whole;
  whole.outputs = {render::kFinal, render::kDirect, render::kGBuffer};
  const render::FrameResult a = cpu.render(*t, s, p, plain);
  const render::FrameResult b = cpu.render(*t, s, p, whole);
  ASSERT_EQ(a.final_image.rgb.size(), b.final_image.rgb.size());
  for (std::size_t i = 0; i < a.final_image.rgb.size(); ++i) ASSERT_EQ(a.final_image.rgb[i], b.final_image.rgb[i]) << "pixel " << i;
  const auto& gb = std::any_cast<const render::GBuffer&>(b.resources.at(render::kGBuffer));
  ASSERT_EQ(gb.planes, unsigned(render::kGBufferAll));
  const render::BackgroundFn bg = render::environment_background(s.environment);
  const render::PinholeCamera cam = render::make_pinhole_camera(s, s.camera.width, s.camera.height, "test");
  std::size_t background = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    if (gb.hit(i)) continue;
    ++background;
    const int x = static_cast<int>(i % static_cast<std::size_t>(gb.width)), y = static_cast<int>(i / static_cast<std::size_t>(gb.width));
    ASSERT_EQ(gb.view_dir[i], cam.buffer_direction(x, y, 1)) << "background pixel " << i;
    ASSERT_EQ(a.direct.rgb[i], bg(gb.view_dir[i])) << "background pixel " << i;
  }
  EXPECT_GT(background, 0u) << "the view should show some sky";
  EXPECT_LT(background, gb.object.size()) << "and some surface";
  auto pass_bytes = [](const render::FrameResult& r) { return test::pass_counter(r, "gbuffer", "bytes_moved"); };
  const auto n = static_cast<double>(s.camera.width * s.camera.height);
  EXPECT_EQ(pass_bytes(a), n * 56.0) << "every plane but view_dir";
  EXPECT_EQ(pass_bytes(b), n * 68.0) << "every plane";
}

}  // namespace
