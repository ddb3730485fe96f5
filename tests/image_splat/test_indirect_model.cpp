// Paper 000's indirect estimator (section 5, eqs. 10, 12, 15) for one proxy over a plane, in closed
// form, against the technique's per-pixel indirect image and against the Embree reference restricted
// to the situation where the paper's model is exact but for its SH truncation.
//
// Closed form. Receiver p with normal N, one proxy of radius r, albedo a at distance d in direction
// dhat, alpha = sin theta = r / d (eq. 1), c = cos theta, t = dhat . N. Under a uniform environment of
// radiance L0, L~ = pi L0 everywhere and is exact at every SH order, so every operator of section 5
// gives kappa = pi L0 (the averaged radiance of a disk of constant radiance). The proxy's radiance is
// (a / pi) kappa = a L0, and eq. 10's second term per unit receiver albedo is a L0 V . H(N) with
// H(N) = (1/pi) int max(0, s . N) y(s) ds. With the order-3 ZH of the proxy's visibility cap,
// V_l = 2 pi sqrt((2l+1)/(4pi)) int_c^1 P_l, and of the clamped cosine, g = (sqrt(pi)/2, sqrt(pi/3),
// sqrt(5 pi)/8), the addition theorem gives V . H = sum_l V_l g_l P_l(t) / pi:
//     F(alpha, t) = (1 - c)/2 + (alpha^2 / 2) t + (5/16) c alpha^2 P_2(t),     P_2(t) = (3t^2 - 1)/2,
// and the receiver's outgoing indirect radiance is rho a L0 F (one proxy: xi = 1 in eq. 12).
// The unshadowed physical value (a sphere of radiance a L0 entirely above the receiver's horizon) is
// rho a L0 alpha^2 t (its form factor); F / (alpha^2 t) - 1 is the cost of the order-3 truncation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "../backends/test_scene_util.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/registry.hpp"

using namespace softgi;

namespace {

constexpr double kPi = 3.14159265358979323846;

render::FrameResult render_splat(const scene::Scene& sc, const std::vector<std::string>& assignments, int w, int h) {
  techniques::register_all();
  auto t = render::create_technique("image_splat");
  render::ParamSet p = render::default_params(*t);
  for (const auto& a : assignments) p.set_assignment(a);
  backends::CpuBackend cpu;
  render::RenderRequest req;
  req.width = w;
  req.height = h;
  return cpu.render(*t, sc, p, req);
}

render::GBuffer gbuffer_of(const scene::Scene& sc, int w, int h) {
  const render::PassFn* fn = render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName);
  scene::PosedScene posed = scene::evaluate(sc, 0.0);
  render::ParamSet params;
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, w, h, result);
  result.passes.push_back(render::PassRecord{"gbuffer"});
  (*fn)(ctx);
  return ctx.get<render::GBuffer>(render::kGBuffer);
}

// The closed form above: V . H(N) / pi of the order-3 model for a cap of sine alpha at cosine t
// from the normal.
double model_F(double alpha, double t) {
  const double c = std::sqrt(std::max(0.0, 1.0 - alpha * alpha)), a2 = alpha * alpha;
  return 0.5 * (1.0 - c) + 0.5 * a2 * t + 5.0 / 16.0 * c * a2 * 0.5 * (3.0 * t * t - 1.0);
}

// Uniform environment of radiance L0 (the sun disk given the same radiance: it vanishes).
void make_uniform(scene::Scene& sc, const glm::vec3& L0) {
  sc.environment.zenith = sc.environment.horizon = sc.environment.ground = sc.environment.sun_radiance = L0;
}

const glm::vec3 kL0(1.0f, 0.8f, 0.6f);
const glm::vec3 kProxyAlbedo(0.9f, 0.6f, 0.3f);

// The plane-and-sphere scene (sphere r = 0.5 at height 0.7, proxy = sphere) under a uniform light.
scene::Scene one_proxy_scene(int w, int h) {
  scene::Scene sc = softgi::testing::with_proxies(softgi::testing::make_plane_sphere_scene(w, h));
  sc.proxies[0].albedo = kProxyAlbedo;
  make_uniform(sc, kL0);
  return sc;
}

struct PixelModel {
  double alpha = 0.0, t = 0.0, F = 0.0;
};
PixelModel pixel_model(const glm::vec3& p, const glm::vec3& N, const glm::vec3& c, double r) {
  const glm::dvec3 dv = glm::dvec3(c) - glm::dvec3(p);
  const double d = glm::length(dv);
  PixelModel m;
  m.alpha = std::min(1.0, r / d);
  m.t = glm::dot(dv / d, glm::dvec3(N));
  m.F = model_F(m.alpha, m.t);
  return m;
}

}  // namespace

// The technique's indirect image on the plane against rho a L0 F per pixel, for every operator, at
// full receiver resolution, without a sphere of influence and without eq. 12 (one proxy: xi = 1).
// The technique's own approximations: 256-row linear tables in theta (about 1e-4 relative at the
// sizes seen here), the paper's polynomial D_0 = 0.28209 against 1/(2 sqrt(pi)) (2e-5 relative), the
// SH projection of the uniform sky by quadrature (higher bands of a constant vanish to float
// rounding) and float sums: measured below 2e-4 of the largest value; kClosedFormRel = 2e-3 leaves
// room for other ISAs without hiding a wrong factor (a missing 1/pi is 3x, a missing band or cosine
// O(10 %)).
TEST(ImageSplatIndirectModel, OneProxyOverAPlaneMatchesTheClosedForm) {
  constexpr double kClosedFormRel = 2e-3;
  const int W = 48, H = 36;
  const scene::Scene sc = one_proxy_scene(W, H);
  const render::GBuffer gb = gbuffer_of(sc, W, H);
  const glm::vec3 c = softgi::testing::PlaneSphere::center();
  const double r = softgi::testing::PlaneSphere::kRadius;
  for (const char* op : {"averaged_poly", "averaged", "point", "exact"}) {
    const render::FrameResult fr = render_splat(
        sc, {"receiver_scale=1", "coverage=off", "normalize_indirect=false", "fallback=none", std::string("indirect_operator=") + op}, W,
        H);
    ASSERT_EQ(fr.indirect.rgb.size(), gb.object.size());
    double worst = 0.0, peak = 0.0;
    int pixels = 0;
    for (std::size_t i = 0; i < gb.object.size(); ++i) {
      if (gb.object[i] != 0) continue;  // the plane only (the sphere's own proxy is culled on it)
      const PixelModel m = pixel_model(gb.position[i], gb.normal[i], c, r);
      for (int ch = 0; ch < 3; ++ch) {
        const double want = gb.albedo[i][ch] * kProxyAlbedo[ch] * kL0[ch] * m.F;
        peak = std::max(peak, want);
        worst = std::max(worst, std::abs(fr.indirect.rgb[i][ch] - want));
      }
      ++pixels;
    }
    ASSERT_GT(pixels, W * H / 4) << op;
    ASSERT_GT(peak, 0.05) << op << ": the proxy must light the plane";
    EXPECT_LE(worst, kClosedFormRel * peak) << op << ": largest |technique - closed form| over the plane, peak " << peak;
  }
}

// The default pipeline (receiver buffer at 1/2, bilateral upsampling, derived sphere of influence with
// smooth clamping, eq. 12 with the HYB exponential) on the same plane: each of these may only cost
// what it is documented to cost. Pixels whose proxy half-angle sine is within twice the clamp's
// support (alpha < 2 / eta_indirect, the smooth ramp) are left out, and pixels next to the sphere's
// silhouette (see kFootprint) too. xi from the order-4 HYB exponential of one cap differs from 1 by
// the exponential's DC error (xi_raw measured in [0.995, 1.0] here).
TEST(ImageSplatIndirectModel, DefaultPipelineKeepsTheClosedFormOnAPlane) {
  // Sum over the pixels: xi and the clamp (measured 0.2 % at receiver_scale 1) and interpolation
  // errors that average out (measured 0.03 %).
  constexpr double kMeanRel = 0.01;
  // Per pixel: eq. 11's depth weight 1 / (eps + |z_p - z_i|) favours the taps at the target's own
  // depth on a plane seen at an angle, which shifts the interpolation across the steep peak under the
  // sphere: measured 5.1 % of the peak (0.5 % at receiver_scale 1, where there is no interpolation).
  constexpr double kPixelRel = 0.08;
  // Display pixels whose bilinear footprint at receiver_scale 2 (+-2 pixels, plus one) is all plane:
  // next to the sphere's silhouette the bilateral weights drop the sphere's taps (measured 5.5 %).
  constexpr int kFootprint = 3;
  const int W = 64, H = 48;
  const scene::Scene sc = one_proxy_scene(W, H);
  const render::GBuffer gb = gbuffer_of(sc, W, H);
  const glm::vec3 c = softgi::testing::PlaneSphere::center();
  const double r = softgi::testing::PlaneSphere::kRadius;
  const render::FrameResult fr = render_splat(sc, {}, W, H);
  double eta = 0.0;
  for (const auto& p : fr.passes)
    if (p.name == "tables") eta = p.counters.at("eta_indirect");
  ASSERT_GT(eta, 1.0);
  double worst = 0.0, peak = 0.0, sum_t = 0.0, sum_m = 0.0;
  int pixels = 0;
  for (int y = kFootprint; y + kFootprint < H; ++y)
    for (int x = kFootprint; x + kFootprint < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      bool interior = true;
      for (int dy = -kFootprint; dy <= kFootprint; ++dy)
        for (int dx = -kFootprint; dx <= kFootprint; ++dx)
          interior = interior && gb.object[static_cast<std::size_t>(y + dy) * W + x + dx] == 0;
      if (!interior) continue;
      const PixelModel m = pixel_model(gb.position[i], gb.normal[i], c, r);
      if (m.alpha < 2.0 / eta) continue;
      for (int ch = 0; ch < 3; ++ch) {
        const double want = gb.albedo[i][ch] * kProxyAlbedo[ch] * kL0[ch] * m.F;
        peak = std::max(peak, want);
        worst = std::max(worst, std::abs(fr.indirect.rgb[i][ch] - want));
        sum_t += fr.indirect.rgb[i][ch];
        sum_m += want;
      }
      ++pixels;
    }
  ASSERT_GT(pixels, W * H / 4);
  std::cout << "default pipeline / closed form over " << pixels << " plane pixels: " << sum_t / sum_m << ", largest difference "
            << worst / peak << " of the peak\n";
  EXPECT_LE(worst, kPixelRel * peak);
  EXPECT_NEAR(sum_t / sum_m, 1.0, kMeanRel);
}

// --- the Embree reference where the model is exact but for its SH truncation -----------------------

namespace {

// A small receiver patch (|x|, |z| <= kPatch) under the sphere raised to height kHeight: the patch
// hardly shadows the sphere, so the reference's one-bounce light off the real sphere is that of an
// unshadowed diffuse sphere of radiance a L0, which is the paper's model (section 5: "directly
// illuminated by the environment L without shadows") with exact visibility and no SH truncation.
constexpr float kPatch = 0.1f, kHeight = 1.5f;
scene::Scene patch_scene(int w, int h) {
  scene::Scene sc = one_proxy_scene(w, h);
  for (auto& p : sc.meshes[0].positions) p = glm::vec3(p.x > 0.0f ? kPatch : -kPatch, 0.0f, p.z > 0.0f ? kPatch : -kPatch);
  sc.materials[1].albedo = kProxyAlbedo;  // the real sphere re-radiates as its proxy does
  sc.nodes[1].translation = glm::vec3(0.0f, kHeight, 0.0f);
  sc.camera.position = {0.0f, 0.9f, 1.6f};  // below the sphere, looking down at the patch
  sc.camera.target = {0.0f, 0.0f, 0.0f};
  sc.camera.fov_y_deg = 9.0f;
  return sc;
}

}  // namespace

// Over the patch: reference / (rho a L0 alpha^2 t) is 1 up to the patch's own shadow on the sphere
// (its form factor seen from the sphere's lowest point, A / (pi h^2) = 0.04 / (pi 1^2) = 1.3 %, less
// elsewhere on the sphere) and Monte Carlo noise; technique / (rho a L0 F) is 1 as above; and so
// technique / reference is F / (alpha^2 t), the order-3 truncation alone (about 1.056 at alpha = 1/3).
// kReferenceRel: 2048 samples per pixel of which about alpha^2 = 11 % hit the sphere, over ~600
// pixels, give a relative standard error of the summed indirect light under 0.3 %; plus the
// shadow: 3 %.
TEST(ImageSplatIndirectModel, ReferenceWithAnUnshadowedSphereDiffersByTheTruncationAlone) {
  constexpr double kReferenceRel = 0.03;
  const int W = 40, H = 40;
  const scene::Scene sc = patch_scene(W, H);
  const render::GBuffer gb = gbuffer_of(sc, W, H);
  reference::ReferenceOptions ro;
  ro.spp = 2048;
  ro.width = W;
  ro.height = H;
  ro.jitter = false;  // every sample through the pixel centre, as the G-buffer sees it
  const reference::ReferenceResult ref = reference::render_reference(sc, ro);
  const render::FrameResult fr =
      render_splat(sc, {"receiver_scale=1", "coverage=off", "normalize_indirect=false", "fallback=none"}, W, H);
  const glm::vec3 c = sc.nodes[1].translation;
  const double r = softgi::testing::PlaneSphere::kRadius;
  double s_ref = 0.0, s_tech = 0.0, s_phys = 0.0, s_model = 0.0;
  int pixels = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    if (gb.object[i] != 0) continue;
    const PixelModel m = pixel_model(gb.position[i], gb.normal[i], c, r);
    for (int ch = 0; ch < 3; ++ch) {
      const double k = gb.albedo[i][ch] * kProxyAlbedo[ch] * kL0[ch];
      s_ref += ref.indirect.rgb[i][ch];
      s_tech += fr.indirect.rgb[i][ch];
      s_phys += k * m.alpha * m.alpha * m.t;
      s_model += k * m.F;
    }
    ++pixels;
  }
  ASSERT_GT(pixels, 300);
  std::cout << pixels << " patch pixels: reference / unshadowed form factor " << s_ref / s_phys << ", technique / closed form "
            << s_tech / s_model << ", closed form / form factor " << s_model / s_phys << ", technique / reference "
            << s_tech / s_ref << "\n";
  EXPECT_NEAR(s_ref / s_phys, 1.0 - 0.5 * kReferenceRel, 0.5 * kReferenceRel) << "the reference sees the unshadowed sphere";
  EXPECT_NEAR(s_tech / s_model, 1.0, 2e-3);
  EXPECT_NEAR((s_tech / s_ref) / (s_model / s_phys), 1.0, kReferenceRel);
}

// --- measurement on `spheres` (not run by ctest: a 256x256, 256-spp reference takes minutes) -------
//
//   build/tests/softgi_tests_image_splat --gtest_also_run_disabled_tests --gtest_filter='ImageSplatIndirectMeasure.*'
//
// prints, over the 5 % of surface pixels where the default technique's indirect luminance is
// largest, the mean indirect RGB of the technique's variants that remove one approximation at a time
// and of the reference (full environment, then its order-4 SH projection), and the relMSE of the
// final image against the full reference with and without the indirect light. docs/techniques/
// image_splat.md quotes this output. It asserts only what the decomposition relies on: that the
// model stays above the reference there (if it did not, the remaining factor would not be the
// unshadowed proxies).
TEST(ImageSplatIndirectMeasure, DISABLED_SpheresBrightestIndirect) {
  const int W = 256, H = 256;
  const scene::Scene sc = scene::make_builtin("spheres");
  const render::GBuffer gb = gbuffer_of(sc, W, H);
  reference::ReferenceOptions ro;
  ro.spp = 256;
  ro.width = W;
  ro.height = H;
  ro.jitter = false;  // as softgi compare renders it
  const reference::ReferenceResult ref = reference::render_reference(sc, ro);
  ro.light_sh_order = 4;
  const reference::ReferenceResult ref4 = reference::render_reference(sc, ro);
  const std::vector<std::pair<std::string, std::vector<std::string>>> variants = {
      {"default", {}},
      {"+ receiver_scale=1", {"receiver_scale=1"}},
      {"+ coverage=off", {"receiver_scale=1", "coverage=off"}},
      {"+ normalize_indirect=false", {"receiver_scale=1", "coverage=off", "normalize_indirect=false"}},
      {"+ indirect_operator=exact", {"receiver_scale=1", "coverage=off", "normalize_indirect=false", "indirect_operator=exact"}},
      {"+ averaged, indirect_order=6",
       {"receiver_scale=1", "coverage=off", "normalize_indirect=false", "indirect_operator=averaged", "indirect_order=6"}},
  };
  std::vector<render::FrameResult> runs;
  for (const auto& v : variants) runs.push_back(render_splat(sc, v.second, W, H));
  const render::FrameResult no_ind = render_splat(sc, {"indirect=false"}, W, H);
  auto lum = [](const glm::vec3& v) { return 0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z; };
  std::vector<std::size_t> surf;
  Mask mask;
  mask.width = W;
  mask.height = H;
  mask.on.assign(gb.object.size(), 0);
  for (std::size_t i = 0; i < gb.object.size(); ++i)
    if (gb.hit(i)) {
      surf.push_back(i);
      mask.on[i] = 1;
    }
  ASSERT_GT(surf.size(), 1000u);
  std::sort(surf.begin(), surf.end(),
            [&](std::size_t a, std::size_t b) { return lum(runs[0].indirect.rgb[a]) > lum(runs[0].indirect.rgb[b]); });
  surf.resize(surf.size() / 20);
  auto mean = [&](const Image& img) {
    glm::dvec3 s(0.0);
    for (std::size_t i : surf) s += glm::dvec3(img.rgb[i]);
    return s / static_cast<double>(surf.size());
  };
  auto print = [](const std::string& label, const glm::dvec3& m, const glm::dvec3& base) {
    std::cout << "  " << label << ": " << m.x << " " << m.y << " " << m.z << "  (x " << (m.x + m.y + m.z) / (base.x + base.y + base.z)
              << " of the reference)\n";
  };
  const glm::dvec3 mref = mean(ref.indirect);
  std::cout << "spheres 256x256, t = 0, " << surf.size() << " pixels (5 % of the surface, brightest technique indirect luminance), "
            << "mean indirect RGB:\n";
  for (std::size_t k = 0; k < runs.size(); ++k) print(variants[k].first, mean(runs[k].indirect), mref);
  print("reference, order-4 SH light", mean(ref4.indirect), mref);
  print("reference, full environment", mref, mref);
  const metrics::Metrics with = metrics::compare(runs[0].final_image, ref.final_image, mask);
  const metrics::Metrics without = metrics::compare(no_ind.final_image, ref.final_image, mask);
  std::cout << "final image relMSE against the full reference: with indirect " << with.relmse << ", without " << without.relmse
            << "\n";
  const glm::dvec3 last = mean(runs.back().indirect);
  EXPECT_GT(last.x + last.y + last.z, mref.x + mref.y + mref.z);
}
