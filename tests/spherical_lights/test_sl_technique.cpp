// Spherical lights as a technique: the receiver kernel's visibility (eq. 23) against the product of
// the blocker visibilities, per-object against per-sphere blocking, and whole frames: a white
// sphere under a constant sky against the closed form of its reflected light on the plane.
#include <gtest/gtest.h>

#include <algorithm>
#include <any>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "../../techniques/spherical_lights/sl_passes.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/sh/product.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/techniques/registry.hpp"

using namespace softgi;
using namespace softgi::techniques::spherical_lights;

namespace {

constexpr double kPi = 3.14159265358979323846;

Settings default_settings() {
  Settings s;
  s.isa = best_kernel_isa();
  return s;
}

// A pose of SLs given directly: identity rotations, one object per entry of `object`.
SlPose make_pose(const std::vector<scene::Sphere>& spheres, const std::vector<int>& object) {
  SlPose p;
  p.order = 4;
  int objects = 0;
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    p.centre.push_back(spheres[i].center);
    p.radius.push_back(spheres[i].radius);
    p.rotation.push_back(glm::mat3(1.0f));
    p.object.push_back(object[i]);
    objects = std::max(objects, object[i] + 1);
  }
  p.object_centre.assign(objects, glm::vec3(0.0f));
  std::vector<int> count(objects, 0);
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    p.object_centre[object[i]] += spheres[i].center;
    ++count[object[i]];
  }
  for (int o = 0; o < objects; ++o) p.object_centre[o] /= static_cast<float>(count[o]);
  p.intersecting.resize(spheres.size());
  for (std::size_t i = 0; i < spheres.size(); ++i)
    for (std::size_t j = 0; j < spheres.size(); ++j)
      if (i != j && object[i] == object[j] &&
          glm::length(spheres[i].center - spheres[j].center) < spheres[i].radius + spheres[j].radius)
        p.intersecting[i].push_back(static_cast<int>(j));
  p.leaves = spheres.size();
  for (std::size_t i = 0; i < spheres.size(); ++i) p.leaves_below.push_back({static_cast<int>(i)});
  p.trees.resize(objects);
  p.node_sl.resize(objects);
  return p;
}

Intensity random_intensity(std::size_t sls, int order, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.2f, 0.2f);
  Intensity lc;
  lc.order = order;
  const int n2 = order * order;
  lc.v.resize(sls * 3 * n2);
  for (std::size_t i = 0; i < sls; ++i)
    for (int c = 0; c < 3; ++c)
      for (int q = 0; q < n2; ++q) lc.v[(i * 3 + c) * n2 + q] = q == 0 ? 2.0f + u(rng) : u(rng);
  return lc;
}

// rho_N . f for the clamped cosine / pi (eq. 24).
double brdf_dot(int order, const glm::vec3& n, const std::vector<double>& f) {
  std::vector<double> y(order * order);
  sh::eval_basis(order, sh::Vec3<double>{n.x, n.y, n.z}, y.data());
  const std::vector<double> cc = sh::clamped_cosine_zh(order);
  double v = 0.0;
  for (int l = 0; l < order; ++l)
    for (int m = -l; m <= l; ++m) v += f[sh::index(l, m)] * sh::zh_rotation_factor(l) * cc[l] / kPi * y[sh::index(l, m)];
  return v;
}

}  // namespace

// Eq. 23 for SLs that do not intersect: exp(S) - exp(S + G_i) equals (prod_{j<i} B_j) * (1 - B_i),
// the visibility of S_i behind the closer SLs by SH products of their visibility vectors (eqs. 4,
// 20), up to the log-space approximation (HYB exponential, eigenvalue clip of the log). Three SLs
// in a row above a receiver, each partly behind the one before.
TEST(SlVisibility, TwoExponentialsMatchTheProductOfBlockerVisibilities) {
  const int n = 4, n2 = n * n;
  const auto tables = make_tables(n, 256, 0.02);
  const ZhTable vis = make_zh_table(tables->sh->cap_visibility(), n, false);
  const std::vector<scene::Sphere> sl = {
      {{0.1f, 1.0f, 0.0f}, 0.3f}, {{0.35f, 2.0f, 0.1f}, 0.45f}, {{-0.2f, 3.2f, -0.3f}, 0.6f}};
  const SlPose pose = make_pose(sl, {0, 1, 2});
  const Intensity lc = random_intensity(sl.size(), n, 1);
  Settings s = default_settings();
  s.rule = ReplacementRule::Off;
  const glm::vec3 p(0.0f), N(0.0f, 1.0f, 0.0f);
  std::vector<float> vbar;
  std::vector<glm::vec3> lbar;
  indirect_terms(s, *tables, pose, lc, p, N, vbar, lbar);
  ASSERT_EQ(vbar.size(), sl.size());
  std::vector<double> prod(n2, 0.0);
  prod[0] = std::sqrt(4.0 * kPi);  // the constant 1
  double total = 0.0;
  for (std::size_t i = 0; i < sl.size(); ++i) {
    std::vector<float> b(n2);
    sphere_zh_vector(vis, p, sl[i].center, sl[i].radius, nullptr, b.data());
    std::vector<double> cap(n2), bd(n2);
    for (int q = 0; q < n2; ++q) {
      bd[q] = b[q];
      cap[q] = (q == 0 ? std::sqrt(4.0 * kPi) : 0.0) - b[q];
    }
    const std::vector<double> vi = sh::product<double>(n, prod, cap);
    const double expect = brdf_dot(n, N, vi);
    total += expect;
    // 0.004: about 2 % of the largest visibility here (0.2); the HYB exponential and the clipped log
    // differ from exact products by about that much for caps of 15-20 degrees (docs/sh.md).
    EXPECT_NEAR(vbar[i], expect, 0.004) << "SL " << i;
    prod = sh::product<double>(n, prod, bd);
  }
  EXPECT_GT(total, 0.1);
  // The occluded SLs are darker than their unoccluded caps: without the closer blockers, the third
  // SL's visibility would be its whole cap.
  std::vector<float> b(n2);
  sphere_zh_vector(vis, p, sl[2].center, sl[2].radius, nullptr, b.data());
  std::vector<double> cap(n2);
  for (int q = 0; q < n2; ++q) cap[q] = (q == 0 ? std::sqrt(4.0 * kPi) : 0.0) - b[q];
  EXPECT_LT(vbar[2], brdf_dot(n, N, cap) - 0.01);
}

// Section 7.2: when the SLs of each object come before those of the next in distance order, the
// object order and the sphere order agree and the two strategies give the same visibilities; when
// objects interleave they differ.
TEST(SlVisibility, PerObjectEqualsPerSphereWhenObjectsDoNotInterleave) {
  const int n = 4;
  const auto tables = make_tables(n, 256, 0.02);
  // Object 0 (two intersecting SLs) near the receiver, object 1 farther up.
  const std::vector<scene::Sphere> sl = {
      {{0.0f, 1.0f, 0.0f}, 0.3f}, {{0.3f, 1.1f, 0.0f}, 0.25f}, {{0.1f, 2.5f, 0.2f}, 0.4f}, {{-0.4f, 2.7f, 0.0f}, 0.35f}};
  const SlPose pose = make_pose(sl, {0, 0, 1, 1});
  ASSERT_FALSE(pose.intersecting[0].empty());
  const Intensity lc = random_intensity(sl.size(), n, 2);
  Settings a = default_settings(), b = a;
  b.blocking = Blocking::PerObject;
  const glm::vec3 p(0.05f, 0.0f, 0.0f), N(0.0f, 1.0f, 0.0f);
  std::vector<float> va, vb;
  std::vector<glm::vec3> la, lb;
  indirect_terms(a, *tables, pose, lc, p, N, va, la);
  indirect_terms(b, *tables, pose, lc, p, N, vb, lb);
  for (std::size_t i = 0; i < sl.size(); ++i) {
    EXPECT_FLOAT_EQ(va[i], vb[i]) << "SL " << i;
    EXPECT_EQ(la[i], lb[i]);
  }
  // Interleaved: object 1's first SL is closer than object 0's second, but object 0's centre is
  // closer. Per-object blocking then lets object 0's far SL darken object 1's near one.
  const std::vector<scene::Sphere> mix = {
      {{0.0f, 0.8f, 0.0f}, 0.3f}, {{0.0f, 3.0f, 0.0f}, 0.5f}, {{0.1f, 1.6f, 0.0f}, 0.3f}, {{0.3f, 6.0f, 0.0f}, 0.5f}};
  const SlPose pm = make_pose(mix, {0, 0, 1, 1});
  indirect_terms(a, *tables, pm, lc, p, N, va, la);
  indirect_terms(b, *tables, pm, lc, p, N, vb, lb);
  double diff = 0.0;
  for (std::size_t i = 0; i < mix.size(); ++i) diff += std::abs(va[i] - vb[i]);
  EXPECT_GT(diff, 1e-3);
}

// Intersecting SLs of one object do not block each other at run time (eq. 21: their occlusion is in
// the emission); an SL of another object at the same place does.
TEST(SlVisibility, IntersectingSlsOfTheSameObjectAreIgnored) {
  const int n = 4;
  const auto tables = make_tables(n, 256, 0.02);
  const std::vector<scene::Sphere> sl = {{{0.0f, 1.0f, 0.0f}, 0.3f}, {{0.0f, 1.4f, 0.0f}, 0.35f}};
  const Intensity lc = random_intensity(sl.size(), n, 3);
  const Settings s = default_settings();
  const glm::vec3 p(0.0f), N(0.0f, 1.0f, 0.0f);
  std::vector<float> same, other, alone;
  std::vector<glm::vec3> l;
  indirect_terms(s, *tables, make_pose(sl, {0, 0}), lc, p, N, same, l);
  indirect_terms(s, *tables, make_pose(sl, {0, 1}), lc, p, N, other, l);
  indirect_terms(s, *tables, make_pose({sl[1]}, {0}), lc, p, N, alone, l);
  EXPECT_NEAR(same[1], alone[0], 1e-5);
  // The nearer sphere covers the farther one; at order 4 the SH products of two 15-17 degree caps
  // resolve that only in part (about a quarter of the cap's visibility here), so the margin is 0.01.
  EXPECT_LT(other[1], same[1] - 0.01);
}

// --- The ray-cast reference of the receiver pass -----------------------------------------------------

namespace {

// Intensity L (radiance) in every direction: DC L sqrt(4 pi), the rest zero.
Intensity constant_intensity(std::size_t sls, int order, float L) {
  Intensity lc;
  lc.order = order;
  const int n2 = order * order;
  lc.v.assign(sls * 3 * n2, 0.0f);
  for (std::size_t i = 0; i < sls; ++i)
    for (int c = 0; c < 3; ++c) lc.v[(i * 3 + c) * n2] = L * static_cast<float>(std::sqrt(4.0 * kPi));
  return lc;
}

Intensity subset(const Intensity& lc, const std::vector<int>& sls) {
  Intensity o;
  o.order = lc.order;
  const std::size_t row = 3 * lc.order * lc.order;
  for (int i : sls) o.v.insert(o.v.end(), lc.v.begin() + i * row, lc.v.begin() + (i + 1) * row);
  return o;
}

glm::vec3 ray_cast_at(const Settings& s, const SlPose& pose, const Intensity& lc, const glm::vec3& p, const glm::vec3& n,
                      std::size_t receiver = 0) {
  ReceiverSoA rec;
  rec.resize(receiver + 1);
  rec.set(receiver, p, n);
  IndirectStats st;
  glm::vec3 out(0.0f);
  accumulate_indirect_ray_cast(s, pose, lc, rec, receiver, receiver + 1, &out, st);
  EXPECT_EQ(st.rays, static_cast<long long>(s.ray_strata) * s.ray_strata);
  return out;
}

}  // namespace

// A sphere of constant radiance L entirely above the receiver's horizon gives E/pi = L sin^2(theta)
// cos(phi) (sin theta = r / D, phi between N and the centre's direction), with no SH anywhere in the
// ray-cast pass: what is left is the stratified estimate of the cap's cosine-weighted area, whose
// error comes from the strata the cap's rim crosses (bound below); k = 64 must be closer on average.
TEST(SlRayCast, UniformSphereMatchesTheFormFactor) {
  const float L = 1.5f;
  const std::vector<scene::Sphere> sl = {{{0.3f, 1.2f, -0.2f}, 0.5f}};
  const SlPose pose = make_pose(sl, {0});
  const Intensity lc = constant_intensity(1, 4, L);
  Settings s = default_settings();
  s.rule = ReplacementRule::Off;
  s.visibility = IndirectVisibility::RayCast;
  double err32 = 0.0, err64 = 0.0;
  int checked = 0;
  for (int k = 0; k < 40; ++k) {
    const glm::vec3 p(-1.0f + 0.05f * k, 0.0f, 0.02f * k - 0.4f), N(0.0f, 1.0f, 0.0f);
    const glm::vec3 d = sl[0].center - p;
    const float D = glm::length(d);
    if (d.y / D < sl[0].radius / D + 0.02f) continue;  // the cap must be above the horizon
    const double expect = L * (sl[0].radius / D) * (sl[0].radius / D) * d.y / D;
    s.ray_strata = 32;
    const glm::vec3 g32 = ray_cast_at(s, pose, lc, p, N, k);
    s.ray_strata = 64;
    const glm::vec3 g64 = ray_cast_at(s, pose, lc, p, N, k);
    // Four standard deviations of the stratified count: the h strata inside the cap have a rim of
    // about 2 sqrt(pi h) strata, each a Bernoulli draw of variance at most 1/4.
    const double h32 = expect / L * 1024.0;
    const double sigma = std::sqrt(2.0 * std::sqrt(kPi * h32) / 4.0) / 1024.0 * L;
    EXPECT_NEAR(g32.x, expect, 4.0 * sigma) << "receiver " << k;
    EXPECT_EQ(g32.x, g32.z);  // grey intensity, grey light
    err32 += std::abs(g32.x - expect) / expect;
    err64 += std::abs(g64.x - expect) / expect;
    ++checked;
  }
  ASSERT_GT(checked, 20);
  std::printf("ray-cast form factor: mean relative error %.5f at 32^2 rays, %.5f at 64^2\n", err32 / checked, err64 / checked);
  EXPECT_LT(err64, err32);
}

// With the paper's precomputed occlusion an SL ignores its own object's intersecting SLs, so two
// intersecting SLs light a receiver as the two alone would, added (the same rays, so to float
// rounding of the sum); resolved at run time, the nearer hides the farther where they overlap and
// the light is less. SLs of two objects are resolved per ray either way.
TEST(SlRayCast, IntersectingSlsIgnoredAddUpAndRunTimeOcclusionHidesTheOverlap) {
  const std::vector<scene::Sphere> sl = {{{0.0f, 1.0f, 0.0f}, 0.4f}, {{0.25f, 1.5f, 0.1f}, 0.45f}};
  const Intensity lc = random_intensity(sl.size(), 4, 5);
  Settings pre = default_settings();
  pre.rule = ReplacementRule::Off;
  pre.visibility = IndirectVisibility::RayCast;
  Settings rt = pre;
  rt.pre.intersecting = IntersectingOcclusion::RunTime;
  const glm::vec3 p(0.1f, 0.0f, -0.1f), N(0.0f, 1.0f, 0.0f);
  const SlPose same = make_pose(sl, {0, 0}), two = make_pose(sl, {0, 1});
  ASSERT_EQ(same.intersecting[1], std::vector<int>{0});
  const glm::vec3 both = ray_cast_at(pre, same, lc, p, N);
  const glm::vec3 a = ray_cast_at(pre, make_pose({sl[0]}, {0}), subset(lc, {0}), p, N);
  const glm::vec3 b = ray_cast_at(pre, make_pose({sl[1]}, {0}), subset(lc, {1}), p, N);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(both[c], a[c] + b[c], 1e-5f * (a[c] + b[c])) << "channel " << c;
  const glm::vec3 resolved = ray_cast_at(rt, same, lc, p, N);
  // The nearer SL covers about a third of the farther one's cap from p: a tenth of the sum at least.
  for (int c = 0; c < 3; ++c) EXPECT_LT(resolved[c], 0.9f * both[c]) << "channel " << c;
  EXPECT_EQ(ray_cast_at(pre, two, lc, p, N), ray_cast_at(rt, two, lc, p, N));
  EXPECT_EQ(ray_cast_at(rt, two, lc, p, N), resolved);
}

// The paper's receiver pass (average radiance x two-exponential visibility) against its ray-cast
// reference, three SLs in a row, each partly behind the one before (no intersections). Alone, each
// SL's light agrees within the order-4 truncation of its cap and of the w_theta average (the
// white-sphere frame test's worst case is 6.3 %; 8 % bounds it). Together, the reference hides what
// the nearer SLs cover; the SH pass resolves that blocking only in part at order 4 (products of
// 10-17 degree caps: a quarter of the occlusion, as IntersectingSlsOfTheSameObjectAreIgnored notes),
// so its sum lies between the reference's and the unblocked sum.
TEST(SlRayCast, ShPassAgreesWithTheRayCastReference) {
  const std::vector<scene::Sphere> sl = {
      {{0.1f, 1.0f, 0.0f}, 0.3f}, {{0.35f, 2.0f, 0.1f}, 0.45f}, {{-0.2f, 3.2f, -0.3f}, 0.6f}};
  const SlPose pose = make_pose(sl, {0, 1, 2});
  const Intensity lc = random_intensity(sl.size(), 4, 1);
  const auto tables = make_tables(4, 256, 0.02);
  Settings s = default_settings();
  s.rule = ReplacementRule::Off;
  Settings r = s;
  r.visibility = IndirectVisibility::RayCast;
  r.ray_strata = 128;
  const glm::vec3 p(0.0f), N(0.0f, 1.0f, 0.0f);
  std::vector<float> vbar;
  std::vector<glm::vec3> lbar;
  indirect_terms(s, *tables, pose, lc, p, N, vbar, lbar);
  glm::vec3 shv(0.0f), unblocked(0.0f), unblocked_ref(0.0f);
  for (std::size_t i = 0; i < vbar.size(); ++i) shv += lbar[i] * vbar[i];
  for (std::size_t i = 0; i < sl.size(); ++i) {
    const SlPose one = make_pose({sl[i]}, {0});
    const Intensity li = subset(lc, {static_cast<int>(i)});
    std::vector<float> v1;
    std::vector<glm::vec3> l1;
    indirect_terms(s, *tables, one, li, p, N, v1, l1);
    const glm::vec3 alone = l1[0] * v1[0], alone_ref = ray_cast_at(r, one, li, p, N);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(alone[c], alone_ref[c], 0.08f * alone_ref[c]) << "SL " << i << " channel " << c;
    unblocked += alone;
    unblocked_ref += alone_ref;
  }
  const glm::vec3 ref = ray_cast_at(r, pose, lc, p, N);
  std::printf("three SLs: sh %.5f, ray cast %.5f; unblocked: sh %.5f, ray cast %.5f\n", shv.x, ref.x, unblocked.x, unblocked_ref.x);
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(ref[c], 0.7f * unblocked_ref[c]) << "channel " << c;  // the blocking is substantial here
    EXPECT_GT(shv[c], ref[c]) << "channel " << c;
    EXPECT_LT(shv[c], unblocked[c]) << "channel " << c;
  }
}

// --- Whole frames ----------------------------------------------------------------------------------

namespace {

scene::Mesh uv_sphere(float radius, int segments, int rings) {
  scene::Mesh m;
  m.name = "sphere";
  for (int j = 0; j <= rings; ++j)
    for (int i = 0; i <= segments; ++i) {
      const float th = static_cast<float>(kPi) * j / rings, ph = 2.0f * static_cast<float>(kPi) * i / segments;
      const glm::vec3 d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
      m.positions.push_back(radius * d);
      m.normals.push_back(d);
    }
  for (int j = 0; j < rings; ++j)
    for (int i = 0; i < segments; ++i) {
      const unsigned a = j * (segments + 1) + i, b = a + 1, c = a + segments + 1, d = c + 1;
      if (j != 0) m.triangles.push_back({a, b, c});
      if (j != rings - 1) m.triangles.push_back({b, d, c});
    }
  return m;
}

scene::Mesh grid(int n, float size) {
  scene::Mesh m;
  m.name = "ground";
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      m.positions.emplace_back(size * (i / float(n - 1) - 0.5f), 0.0f, size * (j / float(n - 1) - 0.5f));
      m.normals.emplace_back(0.0f, 1.0f, 0.0f);
    }
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const unsigned a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      m.triangles.push_back({a, c, b});
      m.triangles.push_back({b, c, d});
    }
  return m;
}

// A white sphere of radius r at height h above a grey plane, under a sky of constant radiance L.
scene::Scene white_sphere_scene(float r, float h, float L) {
  scene::Scene s;
  s.name = "white-sphere";
  s.source = "test";
  scene::Material ground;
  ground.albedo = glm::vec3(0.5f);
  scene::Material white;
  white.albedo = glm::vec3(1.0f);
  s.materials = {ground, white};
  s.meshes.push_back(grid(41, 6.0f));
  s.meshes.push_back(uv_sphere(r, 48, 24));
  s.meshes[1].material = 1;
  scene::Node g;
  g.name = "ground";
  g.mesh = 0;
  scene::Node b;
  b.name = "ball";
  b.mesh = 1;
  b.translation = {0.0f, h, 0.0f};
  s.nodes = {g, b};
  scene::ProxySet ps;
  ps.name = "ball";
  ps.node = 1;
  ps.spheres.push_back({glm::vec3(0.0f), r});
  ps.albedo = glm::vec3(1.0f);
  s.proxies.push_back(ps);
  s.environment.zenith = s.environment.horizon = s.environment.ground = glm::vec3(L);
  s.environment.sun_radiance = glm::vec3(L);
  s.camera.width = s.camera.height = 16;
  return s;
}

render::FrameResult render_sl(const scene::Scene& s, const std::vector<std::string>& assignments, const render::RenderRequest& req) {
  techniques::register_all();
  backends::CpuBackend cpu;
  auto t = render::create_technique("spherical_lights");
  render::ParamSet p = render::default_params(*t);
  for (const auto& a : assignments) p.set_assignment(a);
  return cpu.render(*t, s, p, req);
}

}  // namespace

// A sphere emitting radiance L (white, lit by the constant sky it sees unoccluded: the plane has no
// proxies and blocks nothing) gives a plane point at distance D from its centre, at angle phi from the
// normal, E/pi = L sin^2(theta) cos(phi), sin theta = r / D (the form factor of a sphere above the
// horizon). The technique's L^c is exact here (a constant), so what remains is the order-n SH of the
// SL's cap and the log/exp approximation of its visibility: the error must shrink with the order.
struct ClosedFormError {
  double worst = 0.0, mean = 0.0, bias = 0.0;
};
ClosedFormError white_sphere_error(int order) {
  const float r = 0.5f, h = 0.9f, L = 1.0f;
  const scene::Scene s = white_sphere_scene(r, h, L);
  render::RenderRequest req;
  req.outputs = {"final", kIndirectShading, kReceivers, kIntensity};
  const render::FrameResult f = render_sl(s, {"order=" + std::to_string(order)}, req);
  const auto& ind = *std::any_cast<const std::shared_ptr<const Shading>&>(f.resources.at(kIndirectShading));
  const auto& rec = *std::any_cast<const std::shared_ptr<const Receivers>&>(f.resources.at(kReceivers));
  const auto& lc = *std::any_cast<const std::shared_ptr<const Intensity>&>(f.resources.at(kIntensity));
  // The intensity is the constant L: DC L sqrt(4 pi) (every direction of a sphere's SL is kept, so
  // the Voronoi sums add up to the exact DC), the rest the stratified projection's noise.
  const int n2 = lc.order * lc.order;
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(lc.v[c * n2] / std::sqrt(4.0 * kPi), L, 0.02 * L) << "channel " << c;
    for (int q = 1; q < n2; ++q) EXPECT_NEAR(lc.v[c * n2 + q], 0.0, 0.05 * L) << "channel " << c << " coefficient " << q;
  }
  ClosedFormError e;
  double sum_e = 0.0, sum_t = 0.0, sum_s = 0.0;
  int checked = 0;
  for (std::size_t v = 0; v < s.meshes[0].positions.size(); ++v) {
    const glm::vec3 p = s.meshes[0].positions[v];
    const glm::vec3 d = glm::vec3(0.0f, h, 0.0f) - p;
    const float D = glm::length(d);
    const double expect = L * (r / D) * (r / D) * d.y / D;
    const double got = ind.value[rec.index[0][v]].y;
    if (expect < 0.02) continue;  // far away: below the tolerance's scale
    e.worst = std::max(e.worst, std::abs(got - expect) / expect);
    sum_e += std::abs(got - expect);
    sum_s += got - expect;
    sum_t += expect;
    ++checked;
  }
  EXPECT_GT(checked, 20);
  e.mean = sum_e / sum_t;
  e.bias = sum_s / sum_t;
  std::printf("white sphere, order %d: %d plane vertices, worst relative error %.4f, mean %.4f, bias %.4f\n", order, checked, e.worst,
              e.mean, e.bias);
  return e;
}

TEST(SlFrame, WhiteSphereUnderConstantSkyMatchesTheClosedForm) {
  // Measured: order 4 worst 6.3 %, mean 3.2 % (too dark by 2.3 %); order 6 worst 3.4 %, mean 0.9 %.
  // The bounds leave about 25 % of headroom over those; order 6 must be at least twice as close.
  const ClosedFormError e4 = white_sphere_error(4), e6 = white_sphere_error(6);
  EXPECT_LT(e4.worst, 0.08);
  EXPECT_LT(e4.mean, 0.04);
  EXPECT_LT(e6.worst, 0.045);
  EXPECT_LT(e6.mean, 0.015);
  EXPECT_LT(e6.mean, 0.5 * e4.mean);
}

// A whole frame with the ray-cast receiver pass: it leaves the SL cut out, every SL-receiver pair
// is cast (rays counted), and on the white sphere it is closer to the closed form than the SH pass
// (no SH truncation of the caps: the measured mean error of the SH pass at order 4 is 3.2 %).
// Resolving intersecting SLs at run time needs it, and says so otherwise.
TEST(SlFrame, RayCastReceiverPassIsTheReference) {
  const float r = 0.5f, h = 0.9f, L = 1.0f;
  const scene::Scene s = white_sphere_scene(r, h, L);
  render::RenderRequest req;
  req.outputs = {"final", kIndirectShading, kReceivers};
  const render::FrameResult f = render_sl(s, {"indirect_visibility=ray_cast", "ray_strata=48"}, req);
  bool cut = false;
  for (const auto& p : f.passes) {
    cut |= p.name == "sl_cut";
    if (p.name == "accumulate_indirect") {
      EXPECT_GT(p.counters.at("rays"), 0.0);
    }
  }
  EXPECT_FALSE(cut);
  const auto& ind = *std::any_cast<const std::shared_ptr<const Shading>&>(f.resources.at(kIndirectShading));
  const auto& rec = *std::any_cast<const std::shared_ptr<const Receivers>&>(f.resources.at(kReceivers));
  double sum_e = 0.0, sum_t = 0.0;
  for (std::size_t v = 0; v < s.meshes[0].positions.size(); ++v) {
    const glm::vec3 d = glm::vec3(0.0f, h, 0.0f) - s.meshes[0].positions[v];
    const float D = glm::length(d);
    const double expect = L * (r / D) * (r / D) * d.y / D;
    if (expect < 0.02) continue;
    sum_e += std::abs(ind.value[rec.index[0][v]].y - expect);
    sum_t += expect;
  }
  std::printf("white sphere, ray-cast receivers: mean relative error %.4f\n", sum_e / sum_t);
  // The intensity's own projection noise (2 % on its DC, checked in white_sphere_error) remains.
  EXPECT_LT(sum_e / sum_t, 0.025);
  techniques::register_all();
  auto t = render::create_technique("spherical_lights");
  render::ParamSet p = render::default_params(*t);
  p.set_assignment("intersecting=run_time");
  try {
    (void)read_settings(p);
    ADD_FAILURE() << "intersecting=run_time with the SH receiver pass was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("indirect_visibility=ray_cast"), std::string::npos) << e.what();
  }
}

// Shadows only leaves the indirect passes out; the indirect light brightens the plane under the ball.
TEST(SlFrame, IndirectOffPrunesTheIndirectPasses) {
  const scene::Scene s = white_sphere_scene(0.5f, 0.9f, 1.0f);
  render::RenderRequest req;
  const render::FrameResult on = render_sl(s, {}, req);
  const render::FrameResult off = render_sl(s, {"indirect=false"}, req);
  auto ran = [](const render::FrameResult& f, const std::string& pass) {
    return std::any_of(f.passes.begin(), f.passes.end(), [&](const render::PassRecord& p) { return p.name == pass; });
  };
  for (const char* p : {"sample_shading", "intensity_update", "accumulate_indirect", "indirect_image"}) {
    EXPECT_TRUE(ran(on, p)) << p;
    EXPECT_FALSE(ran(off, p)) << p;
  }
  double a = 0.0, b = 0.0;
  for (std::size_t i = 0; i < on.final_image.rgb.size(); ++i) {
    a += on.final_image.rgb[i].y;
    b += off.final_image.rgb[i].y;
  }
  EXPECT_GT(a, b * 1.01);
}

// Every built-in scene renders, with finite, non-negative indirect light where it has proxies.
TEST(SlFrame, EveryBuiltinSceneRenders) {
  for (const auto& info : scene::builtin_scenes()) {
    SCOPED_TRACE(info.name);
    scene::Scene s = scene::make_builtin(info.name);
    s.camera.width = s.camera.height = 24;
    render::RenderRequest req;
    req.time = 0.5;
    const render::FrameResult f = render_sl(s, {}, req);
    bool proxies = false;
    for (const auto& p : s.proxies) proxies = proxies || !p.spheres.empty();
    if (!proxies) {  // no SL to re-radiate: the indirect passes are left out
      EXPECT_TRUE(f.indirect.empty());
      continue;
    }
    ASSERT_EQ(f.indirect.rgb.size(), 24u * 24u);
    for (const auto& c : f.indirect.rgb) {
      ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z));
      ASSERT_GE(std::min({c.x, c.y, c.z}), 0.0f);
    }
  }
}

// Section 7.3: the hierarchy cut with reflection ratios stays close to every leaf (the ratios match
// the parents to their leaves at each cluster's central receiver), closer than without the ratios,
// and the cut does replace leaves by parents.
TEST(SlFrame, HierarchyCutWithRatiosIsCloseToEveryLeaf) {
  scene::Scene s = scene::make_builtin("character");
  s.camera.width = s.camera.height = 16;
  render::RenderRequest req;
  req.time = 0.5;
  req.outputs = {"final", kIndirectShading};
  auto indirect = [&](const std::vector<std::string>& a, double* parents) {
    const render::FrameResult f = render_sl(s, a, req);
    if (parents)
      for (const auto& p : f.passes)
        if (p.name == "sl_cut") *parents = p.counters.at("parents_in_cuts");
    return std::any_cast<const std::shared_ptr<const Shading>&>(f.resources.at(kIndirectShading))->value;
  };
  double parents = 0.0;
  const auto flat = indirect({"hierarchy=false"}, nullptr);
  const auto cut = indirect({}, &parents);
  const auto plain = indirect({"reflection_ratios=false"}, nullptr);
  EXPECT_GT(parents, 0.0);
  auto rel = [&](const std::vector<glm::vec3>& a) {
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const glm::vec3 d = a[i] - flat[i];
      num += glm::dot(d, d);
      den += glm::dot(flat[i], flat[i]);
    }
    return std::sqrt(num / den);
  };
  const double e_cut = rel(cut), e_plain = rel(plain);
  std::printf("hierarchy: relative RMS difference to every leaf %.4f with ratios, %.4f without\n", e_cut, e_plain);
  // Measured: 5.2 % with the ratios, 12.5 % without, over every vertex (the ratios are exact only at
  // each cluster's p*). 8 % leaves room for the float summation order; the ratios must at least
  // take 40 % of the difference away.
  EXPECT_LT(e_cut, 0.08);
  EXPECT_LT(e_cut, 0.6 * e_plain);
}

// Section 7.3: the shadows from cuts of the SL hierarchies with paper 004's ratio vectors
// (shadow_hierarchy), at the vertices per Lloyd cluster and at the SLs' sample points per object,
// against every leaf SL: far fewer pairs in both stages, and shading within what paper 004's cut
// allows against its flat list (ShexpHierarchy: 1 % mean, 8 % worst, relative to the shading); the
// option needs the hierarchies.
TEST(SlFrame, ShadowHierarchyCutsThePairsAndKeepsTheShadows) {
  const scene::Scene s = scene::make_builtin("crowd");
  render::RenderRequest req;
  req.width = req.height = 16;
  req.outputs = {"final", kDirectShading, kSampleRadiance};
  struct Run {
    std::vector<glm::vec3> direct, samples;
    double pairs = 0.0, sample_pairs = 0.0;
  };
  auto run = [&](const std::vector<std::string>& a) {
    const render::FrameResult f = render_sl(s, a, req);
    Run r;
    for (const auto& p : f.passes) {
      if (p.name == "accumulate_log") r.pairs = p.counters.at("pairs");
      if (p.name == "accumulate_log_samples") r.sample_pairs = p.counters.at("pairs");
    }
    r.direct = std::any_cast<const std::shared_ptr<const Shading>&>(f.resources.at(kDirectShading))->value;
    r.samples = std::any_cast<const std::shared_ptr<const Shading>&>(f.resources.at(kSampleRadiance))->value;
    return r;
  };
  const Run flat = run({});
  const Run cut = run({"shadow_hierarchy=true"});
  // Mean difference relative to the mean, and the worst relative to the brightest.
  auto compare = [](const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b, double& mean, double& worst) {
    ASSERT_EQ(a.size(), b.size());
    double sum_e = 0.0, sum_v = 0.0, peak = 0.0;
    worst = 0.0;
    for (const auto& v : a) peak = std::max(peak, static_cast<double>(v.y));
    for (std::size_t i = 0; i < a.size(); ++i) {
      const double e = std::abs(static_cast<double>(b[i].y) - a[i].y);
      sum_e += e;
      sum_v += std::abs(a[i].y);
      worst = std::max(worst, e / peak);
    }
    mean = sum_e / sum_v;
  };
  double mean = 0.0, worst = 0.0, smean = 0.0, sworst = 0.0;
  compare(flat.direct, cut.direct, mean, worst);
  compare(flat.samples, cut.samples, smean, sworst);
  std::printf("shadow hierarchy: vertices %.0f of %.0f pairs, direct light mean difference %.2e, worst %.2e of the brightest; "
              "sample points %.0f of %.0f pairs, %.2e, %.2e\n",
              cut.pairs, flat.pairs, mean, worst, cut.sample_pairs, flat.sample_pairs, smean, sworst);
  EXPECT_LT(cut.pairs, 0.25 * flat.pairs);
  EXPECT_LT(cut.sample_pairs, 0.25 * flat.sample_pairs);
  EXPECT_GT(mean, 0.0) << "the cut must take inner nodes somewhere";
  EXPECT_GT(smean, 0.0);
  EXPECT_LT(mean, 0.01);
  EXPECT_LT(worst, 0.08);
  EXPECT_LT(smean, 0.01);
  EXPECT_LT(sworst, 0.08);
  EXPECT_THROW(render_sl(s, {"hierarchy=false", "shadow_hierarchy=true"}, req), std::invalid_argument);
}

// Section 7.3's local lights over a block of receivers (add_local_lights, the exponentials of the
// whole block in one batch, log vectors only for the spheres before the farthest light) against
// the definition written out per receiver: every leaf and light rule-adjusted, sorted by distance,
// prefix sums over all of them, two exponentials per light, the terms summed from zero. Bit for
// bit: the batch changes no arithmetic. Receivers with a zero normal, inside a light, and with
// every light eliminated are among them; the block adds to what out held.
TEST(SlLocalLights, ABlockOfReceiversIsTheDefinitionPerReceiverToTheBit) {
  const int n = 4, n2 = n * n;
  const auto tables = make_tables(n, 256, 0.02);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<scene::Sphere> leaves;
  for (int i = 0; i < 14; ++i) leaves.push_back({{2.0f * u(rng), 1.0f + u(rng), 2.0f * u(rng)}, 0.15f + 0.2f * (u(rng) + 1.0f)});
  SlPose pose = make_pose(leaves, std::vector<int>(leaves.size(), 0));
  pose.leaves = leaves.size();
  std::vector<scene::SphericalLight> lights(3);
  for (std::size_t k = 0; k < lights.size(); ++k) {
    lights[k].position = glm::vec3(1.5f * u(rng), 2.2f + 0.3f * u(rng), 1.5f * u(rng));
    lights[k].radius = 0.2f + 0.1f * static_cast<float>(k);
    lights[k].radiance = glm::vec3(3.0f + k, 2.0f, 1.0f + 0.5f * k);
  }
  ReceiverSoA rec;
  const std::size_t count = 150;
  rec.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    glm::vec3 p(2.5f * u(rng), 0.6f * (u(rng) + 1.0f), 2.5f * u(rng)), nn(u(rng), u(rng) + 1.2f, u(rng));
    if (i == 3) nn = glm::vec3(0.0f);                   // no normal: no term
    if (i == 5) p = lights[0].position;                 // at a light's centre: that light is eliminated
    if (i == 7) nn = glm::vec3(0.0f, -1.0f, 0.0f);      // facing away from every light
    rec.set(i, p, glm::normalize(glm::dot(nn, nn) > 0.0f ? nn : glm::vec3(1.0f)) * (glm::dot(nn, nn) > 0.0f ? 1.0f : 0.0f));
  }
  for (const ReplacementRule rule : {ReplacementRule::Continuous, ReplacementRule::Off}) {
    SCOPED_TRACE(static_cast<int>(rule));
    Settings s = default_settings();
    s.order = n;
    s.rule = rule;
    BatchExp be;
    be.order = n;
    be.method = s.exp;
    be.tables = tables->sh.get();
    be.plan = &ProductPlan::get(n);
    std::vector<glm::vec3> out(count), expect(count);
    for (std::size_t i = 0; i < count; ++i) out[i] = expect[i] = glm::vec3(0.25f * static_cast<float>(i % 5));
    // Two blocks, the second starting inside the receivers, as the pass splits them.
    add_local_lights(s, *tables, &pose, lights, rec, 0, 61, out.data());
    add_local_lights(s, *tables, &pose, lights, rec, 61, count, out.data() + 61);
    std::size_t lit = 0;
    for (std::size_t i = 0; i < count; ++i) {
      const glm::vec3 p(rec.px[i], rec.py[i], rec.pz[i]), nn(rec.nx[i], rec.ny[i], rec.nz[i]);
      if (!(glm::dot(nn, nn) > 0.0f)) continue;
      struct Entry {
        float key;
        int light;
        std::vector<float> G;
      };
      std::vector<Entry> e;
      auto add = [&](const glm::vec3& c, float r, int light) {
        const AdjustedSphere adj = apply_replacement_rule(s.rule, p, nn, c, r);
        const float dist = glm::length(adj.center - p);
        if (!(adj.radius > 0.0f) || !(dist > adj.radius)) return;
        Entry x{dist - adj.radius, light, std::vector<float>(n2)};
        sphere_zh_vector(tables->log, p, adj.center, adj.radius, nullptr, x.G.data());
        e.push_back(std::move(x));
      };
      for (const auto& l : leaves) add(l.center, l.radius, -1);
      for (std::size_t k = 0; k < lights.size(); ++k) add(lights[k].position, lights[k].radius, static_cast<int>(k));
      std::stable_sort(e.begin(), e.end(), [](const Entry& a, const Entry& b) { return a.key < b.key; });
      std::vector<float> prefix(n2, 0.0f);
      glm::vec3 term(0.0f);
      std::array<float, sh::kMaxCoeffs> hn{};
      sh::eval_basis(n, sh::Vec3<float>{nn.x, nn.y, nn.z}, hn.data());
      const std::vector<double> cc = sh::clamped_cosine_zh(n);
      for (int l = 0; l < n; ++l)
        for (int m = -l; m <= l; ++m) hn[sh::index(l, m)] *= static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / kPi);
      for (const Entry& x : e) {
        if (x.light >= 0) {
          std::vector<float> f(2 * n2), g(2 * n2);
          for (int q = 0; q < n2; ++q) {
            f[q] = prefix[q];
            f[n2 + q] = prefix[q] + x.G[q];
          }
          sh::ExpStats es;
          exp_batch(s.isa, be, f.data(), g.data(), 2, 0, es);
          float v = 0.0f;
          for (int q = 0; q < n2; ++q) v += (g[q] - g[n2 + q]) * hn[q];
          term += std::max(v, 0.0f) * lights[x.light].radiance;
        }
        for (int q = 0; q < n2; ++q) prefix[q] += x.G[q];
      }
      lit += term != glm::vec3(0.0f);
      expect[i] += term;
    }
    EXPECT_GT(lit, count / 2) << "receivers that a light reaches";
    std::size_t differ = 0;
    for (std::size_t i = 0; i < count; ++i) differ += out[i] != expect[i];
    EXPECT_EQ(differ, 0u) << "receivers whose local-light term is not the definition's";
    EXPECT_EQ(out[3], expect[3]);
  }
}

// Section 7.3: a local light as an SL of constant intensity. Alone above the plane under a black
// sky, it gives E/pi = R sin^2(theta) cos(phi) (the form factor of a sphere above the horizon), up to
// the order-4 SH of its cap as for the white sphere above; a proxy sphere between the light and the
// plane darkens the plane under it, through the two-exponential visibility.
TEST(SlFrame, LocalLightAsAnSlMatchesTheSphereFormFactor) {
  scene::Scene s = white_sphere_scene(0.5f, 0.9f, 0.0f);
  s.environment.sun_radiance = glm::vec3(0.0f);
  const glm::vec3 lp(0.0f, 1.6f, 0.0f);
  const float lr = 0.4f, R = 2.0f;
  scene::SphericalLight light;
  light.position = lp;
  light.radius = lr;
  light.radiance = glm::vec3(R);
  s.lights.push_back(light);
  // The ball far to the side: it blocks nothing between the light and the centre of the plane.
  s.nodes[1].translation = {2.4f, 0.5f, 2.4f};
  s.proxies[0].spheres[0].radius = 0.5f;
  render::RenderRequest req;
  req.outputs = {"final", kDirectShading, kReceivers};
  auto direct = [&](const scene::Scene& sc, const std::vector<std::string>& a) {
    const render::FrameResult f = render_sl(sc, a, req);
    const auto& d = *std::any_cast<const std::shared_ptr<const Shading>&>(f.resources.at(kDirectShading));
    const auto& r = *std::any_cast<const std::shared_ptr<const Receivers>&>(f.resources.at(kReceivers));
    std::vector<float> v(sc.meshes[0].positions.size());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = d.value[r.index[0][i]].y;
    return v;
  };
  auto error = [&](int order, double& worst, double& mean) {
    const std::vector<float> v4 = direct(s, {"order=" + std::to_string(order)});
    double sum_e = 0.0, sum_t = 0.0;
    worst = 0.0;
    for (std::size_t v = 0; v < v4.size(); ++v) {
      const glm::vec3 q = s.meshes[0].positions[v];
      const glm::vec3 d = lp - q;
      const float D = glm::length(d);
      const double expect = R * (lr / D) * (lr / D) * d.y / D;
      if (expect < 0.05 * R * (lr / lp.y) * (lr / lp.y)) continue;
      if (glm::length(glm::vec2(q.x - 2.4f, q.z - 2.4f)) < 1.5f) continue;  // under and beside the ball
      worst = std::max(worst, std::abs(v4[v] - expect) / expect);
      sum_e += std::abs(v4[v] - expect);
      sum_t += expect;
    }
    mean = sum_e / sum_t;
    std::printf("local light as an SL, order %d: worst relative error %.4f, mean %.4f\n", order, worst, mean);
  };
  double w4 = 0.0, m4 = 0.0, w6 = 0.0, m6 = 0.0;
  error(4, w4, m4);
  error(6, w6, m6);
  // Measured: order 4 worst 9.0 %, mean 4.3 %; order 6 mean 2.3 %. The bounds leave about 25 % of
  // headroom; the SH truncation of the cap must fall with the order (order 6: 40 % closer at least).
  EXPECT_LT(w4, 0.11);
  EXPECT_LT(m4, 0.055);
  EXPECT_LT(m6, 0.6 * m4);
  const std::vector<float> sl = direct(s, {});
  // The ball moved right under the light: the plane's centre loses most of the light's cap.
  scene::Scene blocked = s;
  blocked.nodes[1].translation = {0.0f, 0.8f, 0.0f};
  blocked.proxies[0].spheres[0].radius = 0.5f;
  const std::vector<float> sb = direct(blocked, {});
  const std::size_t centre = (41 / 2) * 41 + 41 / 2;
  EXPECT_LT(sb[centre], 0.3f * sl[centre]);
}
