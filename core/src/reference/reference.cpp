// Monte Carlo ground truth with Embree 3 (docs/reference.md). One of the two translation units that
// include Embree (with the CPU G-buffer pass; the set-up they share is core/src/embree/embree_setup.hpp).
//
// Estimator per pixel sample (all directions world space, pointing away from the receiver):
//   primary ray -> first hit x (two-sided: the normal faces the camera)
//   direct(x)   = env term (one BSDF sample + one light sample, balance-heuristic MIS; Veach 1997
//                 eq. 9.13) + one solid-angle cone sample per spherical light
//   indirect(x) = one BSDF sample w -> secondary hit y on the real geometry ->
//                 f(x) cos / pdf * direct(y towards x), direct(y) estimated with one environment
//                 sample (one-sample MIS) and one sample of one spherical light chosen uniformly.
// Every random number of sample k at pixel p comes from a counter-based generator keyed on
// (seed, p, k), so images do not depend on thread scheduling or on the pass structure.
#include "softgi/reference/reference.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "../embree/embree_setup.hpp"
#include "softgi/proxies/self_shadow.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/vertex_image.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::reference {

namespace {

using glm::vec3;
constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 1.0f / kPi;
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kTile = 16;                // tile edge in pixels: the unit of parallel work
constexpr int kMaxSpp = 1 << 20;
constexpr int kMaxDimension = 16384;     // per image side (render::make_pinhole_camera's limit)
constexpr long long kMaxPixels = 1LL << 26;

// ---------------------------------------------------------------------------------------------
// Counter-based random numbers: splitmix64 (Steele, Lea, Flood 2014) keyed on (seed, pixel, sample).
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
class Rng {
 public:
  Rng(unsigned seed, std::uint64_t pixel, std::uint64_t sample)
      : state_(splitmix64(splitmix64(splitmix64(seed) ^ pixel) ^ sample)) {}
  float next() {  // uniform in [0, 1)
    state_ += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<float>(z >> 40) * 0x1p-24f;
  }

 private:
  std::uint64_t state_;
};

inline float luminance(const vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
inline bool finite3(const vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Orthonormal basis around a unit vector (Duff et al. 2017, "Building an orthonormal basis, revisited").
struct Frame {
  vec3 t, b, n;
  explicit Frame(const vec3& nn) : n(nn) {
    float s = std::copysign(1.0f, n.z);
    float a = -1.0f / (s + n.z);
    float bb = n.x * n.y * a;
    t = vec3(1.0f + s * n.x * n.x * a, s * bb, -s * n.x);
    b = vec3(bb, s + n.y * n.y * a, -n.y);
  }
  vec3 to_world(const vec3& v) const { return v.x * t + v.y * b + v.z * n; }
};

// Uniform direction in the cone of half-angle acos(cos_max) about `axis`; pdf 1 / (2 pi (1 - cos_max)).
inline vec3 sample_cone(const vec3& axis, float one_minus_cos_max, float u1, float u2) {
  float cos_t = 1.0f - u1 * one_minus_cos_max;
  float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
  float phi = 2.0f * kPi * u2;
  return Frame(axis).to_world(vec3(sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t));
}

// Ray origins pushed off the surface by a few float ulps along the geometric normal (Waechter and
// Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6):
// scale-independent, unlike a fixed epsilon.
inline float offset_component(float p, float n) {
  constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
  if (std::fabs(p) < kOrigin) return p + kFloatScale * n;
  std::int32_t of = static_cast<std::int32_t>(kIntScale * n);
  std::int32_t bits;
  std::memcpy(&bits, &p, sizeof bits);
  bits += (p < 0.0f) ? -of : of;
  float r;
  std::memcpy(&r, &bits, sizeof r);
  return r;
}
inline vec3 offset_origin(const vec3& p, const vec3& ng) {
  return vec3(offset_component(p.x, ng.x), offset_component(p.y, ng.y), offset_component(p.z, ng.z));
}

// ---------------------------------------------------------------------------------------------
// BRDF: (1 - g) * albedo / pi + g * albedo * (ns + 2) / (2 pi) * max(0, R.wi)^ns, R the mirror of wo
// about N. The glossy lobe is the normalised Phong lobe (Lafortune and Willems 1994, the "modified
// Phong" normalisation), the local Phong model of paper 002 section 3.3 (eq. 6); its reflectance at normal
// incidence is exactly 1, so albedo bounds the material's reflectance. Both lobes are tinted by the
// albedo (the scene model has a single colour per material).
struct Brdf {
  vec3 albedo{0.0f};
  float glossy = 0.0f;   // weight of the Phong lobe, 0 when ns <= 0
  float ns = 0.0f;
  vec3 reflect_dir{0.0f};  // mirror direction of wo

  vec3 eval(const vec3& n, const vec3& wi) const {
    float c = glm::dot(n, wi);
    if (c <= 0.0f) return vec3(0.0f);
    float v = (1.0f - glossy) * kInvPi;
    if (glossy > 0.0f) {
      float ca = glm::dot(reflect_dir, wi);
      if (ca > 0.0f) v += glossy * (ns + 2.0f) * (0.5f * kInvPi) * std::pow(ca, ns);
    }
    return albedo * v;
  }
  // Mixture sampling: cosine hemisphere with probability 1 - g, the Phong lobe cos^ns about R
  // (pdf (ns + 1) / (2 pi) cos^ns) with probability g.
  float pdf(const vec3& n, const vec3& wi) const {
    float c = glm::dot(n, wi);
    float p = c > 0.0f ? (1.0f - glossy) * c * kInvPi : 0.0f;
    if (glossy > 0.0f) {
      float ca = glm::dot(reflect_dir, wi);
      if (ca > 0.0f) p += glossy * (ns + 1.0f) * (0.5f * kInvPi) * std::pow(ca, ns);
    }
    return p;
  }
  vec3 sample(const Frame& f, float u0, float u1, float u2) const {
    if (glossy > 0.0f && u0 < glossy) {
      float cos_a = std::pow(u1, 1.0f / (ns + 1.0f));
      float sin_a = std::sqrt(std::max(0.0f, 1.0f - cos_a * cos_a));
      float phi = 2.0f * kPi * u2;
      return Frame(reflect_dir).to_world(vec3(sin_a * std::cos(phi), sin_a * std::sin(phi), cos_a));
    }
    float r = std::sqrt(u1), phi = 2.0f * kPi * u2;
    return f.to_world(vec3(r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u1))));
  }
};

// ---------------------------------------------------------------------------------------------
// Distant light: the scene environment, or its order-n SH projection (paper 004 Figure 7: lighting
// error separated from visibility error). SH radiance may be negative; it is kept as is.
class EnvLight {
 public:
  EnvLight(const scene::Environment& env, int sh_order) : env_(env), sh_order_(sh_order) {
    if (sh_order_ > 0) {
      sh_ = scene::environment_sh(env_, sh_order_);
      if (static_cast<int>(sh_.size()) < sh_order_ * sh_order_)
        throw std::runtime_error("reference: environment_sh returned " + std::to_string(sh_.size()) +
                                 " coefficients for order " + std::to_string(sh_order_));
      return;  // SH light: directions from BSDF sampling only (not by importance of the map)
    }
    if (env_.kind == scene::Environment::Kind::Sky) setup_sun();
    else setup_table();
  }

  vec3 radiance(const vec3& d) const {
    if (sh_order_ == 0) return env_.radiance(d);
    std::array<float, sh::kMaxCoeffs> y{};
    sh::eval_basis(sh_order_, sh::Vec3<float>{d.x, d.y, d.z}, y.data());
    vec3 r(0.0f);
    for (int i = 0; i < sh_order_ * sh_order_; ++i) r += sh_[i] * y[i];
    return r;
  }
  bool has_sampler() const { return mode_ != Mode::None; }
  vec3 sample(Rng& rng) const {
    float u1 = rng.next(), u2 = rng.next();
    if (mode_ == Mode::SunCone) return sample_cone(sun_dir_, sun_one_minus_cos_, u1, u2);
    // Table: row by the marginal CDF, column by the row's conditional CDF, then uniform in solid
    // angle inside the cell.
    int j = pick(marginal_.data(), th_, u1);
    int i = pick(conditional_.data() + static_cast<std::size_t>(j) * (tw_ + 1), tw_, u2);
    float c0 = cos_edge_[j], c1 = cos_edge_[j + 1];
    float ct = c0 - rng.next() * (c0 - c1);
    float st = std::sqrt(std::max(0.0f, 1.0f - ct * ct));
    float phi = 2.0f * kPi * (static_cast<float>(i) + rng.next()) / static_cast<float>(tw_);
    return vec3(st * std::cos(phi), ct, -st * std::sin(phi));
  }
  float pdf(const vec3& d) const {
    if (mode_ == Mode::SunCone) return glm::dot(d, sun_dir_) >= sun_cos_ ? sun_pdf_ : 0.0f;
    if (mode_ == Mode::Table) {
      float ct = std::clamp(d.y, -1.0f, 1.0f);
      int j = std::clamp(static_cast<int>(std::acos(ct) / kPi * static_cast<float>(th_)), 0, th_ - 1);
      float phi = std::atan2(-d.z, d.x);
      if (phi < 0.0f) phi += 2.0f * kPi;
      int i = std::clamp(static_cast<int>(phi / (2.0f * kPi) * static_cast<float>(tw_)), 0, tw_ - 1);
      return cell_pdf_[static_cast<std::size_t>(j) * tw_ + i];
    }
    return 0.0f;
  }

 private:
  enum class Mode { None, SunCone, Table };

  // The sun disk of the sky: explicit sampling of its cone (paper 004 uses the same sky model for
  // soft sun shadows). The world direction is sun_direction turned by rotation_y about +y; which way
  // the environment turns is settled by asking radiance() which candidate is the brighter.
  void setup_sun() {
    if (!(env_.sun_radius > 0.0f) || !(luminance(env_.sun_radiance) > 0.0f)) return;
    vec3 d = glm::normalize(env_.sun_direction);
    float c = std::cos(env_.rotation_y), s = std::sin(env_.rotation_y);
    vec3 a(c * d.x + s * d.z, d.y, -s * d.x + c * d.z), b(c * d.x - s * d.z, d.y, s * d.x + c * d.z);
    sun_dir_ = luminance(env_.radiance(a)) >= luminance(env_.radiance(b)) ? a : b;
    float r = std::min(env_.sun_radius, kPi);
    sun_cos_ = std::cos(r);
    sun_one_minus_cos_ = 2.0f * std::sin(0.5f * r) * std::sin(0.5f * r);  // 1 - cos r without cancellation
    sun_pdf_ = 1.0f / (2.0f * kPi * sun_one_minus_cos_);
    mode_ = Mode::SunCone;
  }

  // Maps: a piecewise-constant distribution over a world lat-long grid, built from radiance()
  // itself (so rotation and intensity are whatever the environment does), weight = mean luminance
  // of 2x2 sub-samples times the cell's solid angle. MIS with BSDF sampling keeps the estimate
  // unbiased wherever the table underestimates.
  void setup_table() {
    tw_ = std::clamp(env_.map_width, 64, 1024);
    th_ = tw_ / 2;
    cos_edge_.resize(th_ + 1);
    for (int j = 0; j <= th_; ++j) cos_edge_[j] = std::cos(kPi * static_cast<float>(j) / static_cast<float>(th_));
    std::vector<double> w(static_cast<std::size_t>(tw_) * th_);
    tbb::parallel_for(0, th_, [&](int j) {
      for (int i = 0; i < tw_; ++i) {
        double sum = 0.0;
        for (int sj = 0; sj < 2; ++sj)
          for (int si = 0; si < 2; ++si) {
            float theta = kPi * (static_cast<float>(j) + 0.25f + 0.5f * static_cast<float>(sj)) / static_cast<float>(th_);
            float phi = 2.0f * kPi * (static_cast<float>(i) + 0.25f + 0.5f * static_cast<float>(si)) / static_cast<float>(tw_);
            vec3 d(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
            float l = luminance(env_.radiance(d));
            sum += std::isfinite(l) ? std::max(0.0f, l) : 0.0f;
          }
        double omega = (cos_edge_[j] - cos_edge_[j + 1]) * 2.0 * sh::kPi / tw_;
        w[static_cast<std::size_t>(j) * tw_ + i] = 0.25 * sum * omega;
      }
    });
    double total = 0.0;
    for (double x : w) total += x;
    if (!(total > 0.0) || !std::isfinite(total)) return;  // black map: BSDF sampling only
    marginal_.assign(th_ + 1, 0.0f);
    conditional_.assign(static_cast<std::size_t>(th_) * (tw_ + 1), 0.0f);
    cell_pdf_.assign(static_cast<std::size_t>(tw_) * th_, 0.0f);
    double acc_rows = 0.0;
    for (int j = 0; j < th_; ++j) {
      double row = 0.0;
      float* cdf = conditional_.data() + static_cast<std::size_t>(j) * (tw_ + 1);
      for (int i = 0; i < tw_; ++i) {
        row += w[static_cast<std::size_t>(j) * tw_ + i];
        cdf[i + 1] = static_cast<float>(row);
      }
      for (int i = 1; i <= tw_; ++i) cdf[i] = row > 0.0 ? static_cast<float>(cdf[i] / row) : static_cast<float>(i) / tw_;
      acc_rows += row;
      marginal_[j + 1] = static_cast<float>(acc_rows / total);
      double omega = (cos_edge_[j] - cos_edge_[j + 1]) * 2.0 * sh::kPi / tw_;
      for (int i = 0; i < tw_; ++i)
        cell_pdf_[static_cast<std::size_t>(j) * tw_ + i] = static_cast<float>(w[static_cast<std::size_t>(j) * tw_ + i] / total / omega);
    }
    marginal_[th_] = 1.0f;
    mode_ = Mode::Table;
  }
  // Index k with cdf[k] <= u < cdf[k + 1], skipping zero-probability entries.
  static int pick(const float* cdf, int n, float u) {
    int k = static_cast<int>(std::upper_bound(cdf + 1, cdf + n + 1, u) - (cdf + 1));
    k = std::clamp(k, 0, n - 1);
    while (k < n - 1 && cdf[k + 1] <= cdf[k]) ++k;
    return k;
  }

  const scene::Environment& env_;
  int sh_order_ = 0;
  std::vector<vec3> sh_;
  Mode mode_ = Mode::None;
  vec3 sun_dir_{0.0f, 1.0f, 0.0f};
  float sun_cos_ = 1.0f, sun_one_minus_cos_ = 0.0f, sun_pdf_ = 0.0f;
  int tw_ = 0, th_ = 0;
  std::vector<float> cos_edge_, marginal_, conditional_, cell_pdf_;
};

// ---------------------------------------------------------------------------------------------
// Sphere blockers with the self-shadowing rules of paper 004 section 6.2 (Figure 5), applied per
// receiver p with outward normal N inside the occlusion callback: the core's definition
// (softgi/proxies/self_shadow.hpp), the one the accumulation techniques apply, under
// ReferenceOptions::replacement_rule. Under every rule the reference accepts, the adjusted sphere
// lies inside S (a sphere tangent to T_p at q1 of radius at most (h + r)/2, or S shrunk about its
// centre), so S's box bounds it for the BVH.
struct ProxyReceiver {
  RTCIntersectContext ctx;  // first member: Embree hands this pointer back to the callbacks
  vec3 p{0.0f}, n{0.0f, 1.0f, 0.0f};
  proxies::ReplacementRule rule = proxies::kDefaultReplacementRule;
};

struct ProxyGeometry {
  std::vector<scene::Sphere> spheres;
};

// Segment [tnear, tfar] of the ray against a sphere.
inline bool sphere_blocks(const scene::Sphere& s, const vec3& o, const vec3& d, float tnear, float tfar) {
  vec3 oc = o - s.center;
  float a = glm::dot(d, d), b = glm::dot(oc, d), c = glm::dot(oc, oc) - s.radius * s.radius;
  float disc = b * b - a * c;
  if (disc < 0.0f) return false;
  float sq = std::sqrt(disc);
  float t0 = (-b - sq) / a, t1 = (-b + sq) / a;
  return (t0 >= tnear && t0 <= tfar) || (t1 >= tnear && t1 <= tfar);
}

void proxy_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* g = static_cast<const ProxyGeometry*>(args->geometryUserPtr);
  const scene::Sphere& s = g->spheres[args->primID];
  args->bounds_o->lower_x = s.center.x - s.radius;
  args->bounds_o->lower_y = s.center.y - s.radius;
  args->bounds_o->lower_z = s.center.z - s.radius;
  args->bounds_o->upper_x = s.center.x + s.radius;
  args->bounds_o->upper_y = s.center.y + s.radius;
  args->bounds_o->upper_z = s.center.z + s.radius;
}

void proxy_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* g = static_cast<const ProxyGeometry*>(args->geometryUserPtr);
  const auto* rec = reinterpret_cast<const ProxyReceiver*>(args->context);
  const scene::Sphere& b = g->spheres[args->primID];
  const proxies::AdjustedSphere a = proxies::apply_replacement_rule(rec->rule, rec->p, rec->n, b.center, b.radius);
  if (!(a.radius > 0.0f)) return;
  const scene::Sphere s{a.center, a.radius};
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    RTCRayN* ray = args->ray;
    vec3 o(RTCRayN_org_x(ray, args->N, i), RTCRayN_org_y(ray, args->N, i), RTCRayN_org_z(ray, args->N, i));
    vec3 d(RTCRayN_dir_x(ray, args->N, i), RTCRayN_dir_y(ray, args->N, i), RTCRayN_dir_z(ray, args->N, i));
    float& tfar = RTCRayN_tfar(ray, args->N, i);
    if (sphere_blocks(s, o, d, RTCRayN_tnear(ray, args->N, i), tfar)) tfar = -kInf;
  }
}

// Proxies are only ever shadow blockers; rtcIntersect is never called on their scene.
void proxy_intersect(const RTCIntersectFunctionNArguments*) {}

// ---------------------------------------------------------------------------------------------
struct Hit {
  vec3 p, ng, ns;  // position, geometric and shading normal, both facing the incoming ray
  Brdf brdf;
};

class Renderer {
 public:
  Renderer(const scene::Scene& sc, const ReferenceOptions& opt)
      : scene_(sc), opt_(opt), posed_(scene::evaluate(sc, opt.time)), env_(sc.environment, opt.light_sh_order) {
    setup_camera();
    device_ = embree::new_device(state_, "reference", false);
    build_geometry();
    if (opt_.blockers != ReferenceOptions::Blockers::Geometry) build_proxies();
    check_embree("building the scene");
  }
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  int width() const { return camera_.width; }
  int height() const { return camera_.height; }
  void check_embree(const char* what) { state_.check("reference", what); }

  // One pixel sample: direct and indirect outgoing radiance towards the camera.
  void sample(int x, int y, int k, vec3& direct, vec3& indirect, long long& rays) const {
    Rng rng(opt_.seed, static_cast<std::uint64_t>(y) * camera_.width + x, static_cast<std::uint64_t>(k));
    float jx = 0.5f, jy = 0.5f;
    if (opt_.jitter) {
      jx = rng.next();
      jy = rng.next();
    }
    // The camera model shared with the G-buffer pass (softgi/render/camera.hpp).
    const vec3 dir = camera_.direction(static_cast<float>(x) + jx, static_cast<float>(y) + jy);
    direct = indirect = vec3(0.0f);
    Hit h;
    ++rays;
    if (!intersect(camera_.position, dir, h, geom_scene_.get(), geom_object_)) {
      // The background every technique draws too (render/vertex_image.hpp): the environment as
      // seen, whatever light model shades the surfaces.
      direct = render::background_radiance(scene_.environment, dir);
      return;
    }
    direct = env_direct_two_sample(h, rng, rays) + lights_direct_all(h, rng, rays);
    if (!opt_.indirect) return;
    // One bounce: a BSDF direction from x; the secondary point's directly lit radiance towards x.
    Frame f(h.ns);
    float u0 = rng.next(), u1 = rng.next(), u2 = rng.next();
    vec3 wi = h.brdf.sample(f, u0, u1, u2);
    float pdf = h.brdf.pdf(h.ns, wi);
    if (!(pdf > 0.0f) || glm::dot(wi, h.ng) <= 0.0f) return;
    vec3 fr = h.brdf.eval(h.ns, wi);
    if (fr == vec3(0.0f)) return;
    Hit h2;
    ++rays;
    // The sky is direct light, not a bounce. In ProxiesOnly mode only the proxied objects reflect.
    if (!intersect(offset_origin(h.p, h.ng), wi, h2, bounce_scene_ ? bounce_scene_.get() : geom_scene_.get(),
                   bounce_scene_ ? bounce_object_ : geom_object_))
      return;
    vec3 lo = env_direct_one_sample(h2, rng, rays) + lights_direct_one(h2, rng, rays);
    indirect = fr * glm::dot(h.ns, wi) / pdf * lo;
  }

 private:
  // --- scene setup ---------------------------------------------------------------------------
  // The Embree triangle geometry of posed object oi (the set-up the G-buffer pass shares), or none
  // when it has no triangles.
  embree::GeometryHandle triangle_geometry(std::size_t oi) {
    const scene::PosedObject& o = posed_.objects[oi];
    if (!embree::traced(o)) return nullptr;
    return embree::new_triangle_geometry(device_.get(), state_, o, "reference");
  }

  void build_geometry() {
    geom_scene_.reset(rtcNewScene(device_.get()));
    rtcSetSceneBuildQuality(geom_scene_.get(), RTC_BUILD_QUALITY_HIGH);
    for (std::size_t oi = 0; oi < posed_.objects.size(); ++oi) {
      embree::GeometryHandle g = triangle_geometry(oi);
      if (!g) continue;
      unsigned id = rtcAttachGeometry(geom_scene_.get(), g.get());
      if (geom_object_.size() <= id) geom_object_.resize(id + 1, -1);
      geom_object_[id] = static_cast<int>(oi);
    }
    rtcCommitScene(geom_scene_.get());
  }

  // Shadow blockers in the proxy modes: every proxy sphere; in Proxies mode also the real triangles
  // of the objects that no proxy set stands for (ground, walls: paper 004 Figure 7(b) replaces only
  // the blockers that have sphere sets). In ProxiesOnly mode those objects are receivers alone, as
  // for a sphere-proxy technique: they shadow nothing and reflect no light onto other surfaces, so
  // bounce rays see only the proxied objects.
  void build_proxies() {
    std::vector<char> proxied(scene_.nodes.size(), 0);
    for (std::size_t k = 0; k < scene_.proxies.size() && k < posed_.proxies.size(); ++k) {
      const int node = scene_.proxies[k].node;
      if (node >= 0 && node < static_cast<int>(proxied.size())) proxied[node] = 1;
      for (const auto& s : posed_.proxies[k])
        if (s.radius > 0.0f && finite3(s.center) && std::isfinite(s.radius)) proxies_.spheres.push_back(s);
    }
    // Proxies mode stands for Figure 7(b), which needs sphere sets. ProxiesOnly on a scene without
    // them is what a sphere-proxy technique computes there: nothing shadows.
    const bool only = opt_.blockers == ReferenceOptions::Blockers::ProxiesOnly;
    if (proxies_.spheres.empty() && !only)
      throw std::invalid_argument("reference: blockers = proxies, but scene '" + scene_.name + "' has no proxy spheres");
    proxy_scene_.reset(rtcNewScene(device_.get()));
    if (!proxies_.spheres.empty()) {
      embree::GeometryHandle g(rtcNewGeometry(device_.get(), RTC_GEOMETRY_TYPE_USER));
      check_embree("creating the proxy geometry");
      rtcSetGeometryUserPrimitiveCount(g.get(), static_cast<unsigned>(proxies_.spheres.size()));
      rtcSetGeometryUserData(g.get(), &proxies_);
      rtcSetGeometryBoundsFunction(g.get(), proxy_bounds, nullptr);
      rtcSetGeometryIntersectFunction(g.get(), proxy_intersect);
      rtcSetGeometryOccludedFunction(g.get(), proxy_occluded);
      rtcCommitGeometry(g.get());
      rtcAttachGeometry(proxy_scene_.get(), g.get());
    }
    if (only) bounce_scene_.reset(rtcNewScene(device_.get()));
    for (std::size_t oi = 0; oi < posed_.objects.size(); ++oi) {
      const int node = posed_.objects[oi].node;
      const bool has_proxies = node >= 0 && node < static_cast<int>(proxied.size()) && proxied[node];
      if (has_proxies != only) continue;
      embree::GeometryHandle t = triangle_geometry(oi);
      if (!t) continue;
      if (!only) {
        rtcAttachGeometry(proxy_scene_.get(), t.get());
        continue;
      }
      const unsigned id = rtcAttachGeometry(bounce_scene_.get(), t.get());
      if (bounce_object_.size() <= id) bounce_object_.resize(id + 1, -1);
      bounce_object_[id] = static_cast<int>(oi);
    }
    rtcCommitScene(proxy_scene_.get());
    if (only) rtcCommitScene(bounce_scene_.get());
  }

  // The one camera model (render/camera.hpp), so that with jitter off pixel (x, y) sees what the
  // techniques' G-buffer pixel (x, y) sees.
  void setup_camera() {
    int w = opt_.width, h = opt_.height;
    render::resolve_resolution(scene_.camera, w, h);
    if (static_cast<long long>(w) * h > kMaxPixels)
      throw std::invalid_argument("reference: image size " + std::to_string(w) + "x" + std::to_string(h) + " of scene '" +
                                  scene_.name + "' exceeds " + std::to_string(kMaxPixels) + " pixels");
    camera_ = render::make_pinhole_camera(scene_, w, h, "reference");
  }

  // --- tracing -------------------------------------------------------------------------------
  // First hit in `scene`, whose geometry ids name posed objects through `object_of`.
  bool intersect(const vec3& o, const vec3& d, Hit& h, RTCScene scene, const std::vector<int>& object_of) const {
    RTCIntersectContext ctx;
    embree::init_context(ctx);
    RTCRayHit rh = embree::make_ray_hit(o, d);
    rtcIntersect1(scene, &ctx, &rh);
    if (!embree::is_hit(rh)) return false;
    const scene::PosedObject& obj = posed_.objects[object_of[rh.hit.geomID]];
    const float u = rh.hit.u, v = rh.hit.v;
    const embree::Surface sf = embree::surface_at(obj, rh.hit.primID, u, v, d);  // the G-buffer's surface rules
    h.p = sf.p;
    h.ng = sf.ng;
    h.ns = sf.ns;
    static const scene::Material kDefault{};
    const scene::Material& m =
        obj.material >= 0 && obj.material < static_cast<int>(scene_.materials.size()) ? scene_.materials[obj.material] : kDefault;
    h.brdf.albedo = scene::surface_albedo(scene_, obj, rh.hit.primID, u, v);
    h.brdf.glossy = m.phong_ns > 0.0f ? std::clamp(m.glossy, 0.0f, 1.0f) : 0.0f;
    h.brdf.ns = m.phong_ns;
    const vec3 wo = -d;
    h.brdf.reflect_dir = 2.0f * glm::dot(h.ns, wo) * h.ns - wo;
    return true;
  }

  // Shadow ray from the receiver h towards wi, up to tfar.
  bool visible(const Hit& h, const vec3& wi, float tfar, long long& rays) const {
    ++rays;
    ProxyReceiver rec;
    embree::init_context(rec.ctx);
    rec.p = h.p;
    rec.n = h.ns;
    rec.rule = opt_.replacement_rule;
    RTCRay ray = embree::make_ray(offset_origin(h.p, h.ng), wi, 0.0f, tfar);
    rtcOccluded1(proxy_scene_ ? proxy_scene_.get() : geom_scene_.get(), &rec.ctx, &ray);
    return embree::unoccluded(ray);
  }

  // --- direct light --------------------------------------------------------------------------
  // f L cos / pdf_sum for one direction, with visibility; pdf_sum is the MIS denominator.
  vec3 env_contribution(const Hit& h, const vec3& wi, float pdf_sum, long long& rays) const {
    if (!(pdf_sum > 0.0f)) return vec3(0.0f);
    float c = glm::dot(h.ns, wi);
    if (c <= 0.0f || glm::dot(h.ng, wi) <= 0.0f) return vec3(0.0f);
    vec3 fr = h.brdf.eval(h.ns, wi);
    if (fr == vec3(0.0f)) return vec3(0.0f);
    vec3 l = env_.radiance(wi);
    if (l == vec3(0.0f)) return vec3(0.0f);
    if (!visible(h, wi, kInf, rays)) return vec3(0.0f);
    return fr * l * (c / pdf_sum);
  }
  // Multi-sample MIS, balance heuristic (Veach 1997 eq. 9.13 with n_b = n_l = 1): one BSDF and
  // one light sample, each weighted by pdf_own / (pdf_b + pdf_l).
  vec3 env_direct_two_sample(const Hit& h, Rng& rng, long long& rays) const {
    Frame f(h.ns);
    float u0 = rng.next(), u1 = rng.next(), u2 = rng.next();
    vec3 wb = h.brdf.sample(f, u0, u1, u2);
    vec3 sum = env_contribution(h, wb, h.brdf.pdf(h.ns, wb) + env_.pdf(wb), rays);
    if (env_.has_sampler()) {
      vec3 wl = env_.sample(rng);
      sum += env_contribution(h, wl, h.brdf.pdf(h.ns, wl) + env_.pdf(wl), rays);
    }
    return sum;
  }
  // One-sample MIS (Veach 1997 section 9.2.4): pick a strategy with probability 1/2, divide by the
  // mixture pdf.
  vec3 env_direct_one_sample(const Hit& h, Rng& rng, long long& rays) const {
    float pick = rng.next();
    vec3 wi;
    if (env_.has_sampler() && pick < 0.5f) {
      wi = env_.sample(rng);
    } else {
      Frame f(h.ns);
      float u0 = rng.next(), u1 = rng.next(), u2 = rng.next();
      wi = h.brdf.sample(f, u0, u1, u2);
    }
    float pdf = env_.has_sampler() ? 0.5f * (h.brdf.pdf(h.ns, wi) + env_.pdf(wi)) : h.brdf.pdf(h.ns, wi);
    return env_contribution(h, wi, pdf, rays);
  }

  // A spherical light (paper 004 section 7; paper 001 section 7.3) of radiance Le: uniform sample of
  // the cone it subtends, pdf 1 / (2 pi (1 - cos theta_max)), visibility up to its surface. Lights
  // are emitters only: they neither block the environment nor appear in camera rays. A receiver
  // inside a light receives nothing from it.
  vec3 light_sample(const Hit& h, const scene::SphericalLight& L, Rng& rng, long long& rays) const {
    float u1 = rng.next(), u2 = rng.next();
    vec3 to = L.position - h.p;
    float d2 = glm::dot(to, to), r2 = L.radius * L.radius;
    if (!(d2 > r2) || !(L.radius > 0.0f)) return vec3(0.0f);
    float d = std::sqrt(d2);
    vec3 axis = to / d;
    float sin2 = r2 / d2;
    float cos_max = std::sqrt(std::max(0.0f, 1.0f - sin2));
    float one_minus_cos = sin2 / (1.0f + cos_max);  // without cancellation for distant lights
    vec3 wi = sample_cone(axis, one_minus_cos, u1, u2);
    float c = glm::dot(h.ns, wi);
    if (c <= 0.0f || glm::dot(h.ng, wi) <= 0.0f) return vec3(0.0f);
    vec3 fr = h.brdf.eval(h.ns, wi);
    if (fr == vec3(0.0f)) return vec3(0.0f);
    // Distance to the near intersection with the light's sphere.
    float b = glm::dot(to, wi);
    float t = b - std::sqrt(std::max(0.0f, b * b - (d2 - r2)));
    if (!visible(h, wi, t * (1.0f - 1e-4f), rays)) return vec3(0.0f);
    float pdf = 1.0f / (2.0f * kPi * one_minus_cos);
    return fr * L.radiance * (c / pdf);
  }
  vec3 lights_direct_all(const Hit& h, Rng& rng, long long& rays) const {
    vec3 sum(0.0f);
    for (const auto& L : posed_.lights) sum += light_sample(h, L, rng, rays);
    return sum;
  }
  vec3 lights_direct_one(const Hit& h, Rng& rng, long long& rays) const {
    const std::size_t n = posed_.lights.size();
    if (n == 0) return vec3(0.0f);
    std::size_t k = std::min(n - 1, static_cast<std::size_t>(rng.next() * static_cast<float>(n)));
    return static_cast<float>(n) * light_sample(h, posed_.lights[k], rng, rays);
  }

  const scene::Scene& scene_;
  const ReferenceOptions& opt_;
  scene::PosedScene posed_;
  EnvLight env_;
  embree::DeviceState state_;     // outlives the device that reports to it
  ProxyGeometry proxies_;         // user data of the proxy geometry: outlives the scenes
  embree::DeviceHandle device_;   // declared before the scenes: released after them
  // Primary and bounce rays; shadow rays of the proxy modes; ProxiesOnly's bounce rays (the
  // proxied objects alone). The vectors map a scene's geometry id to its posed object.
  embree::SceneHandle geom_scene_, proxy_scene_, bounce_scene_;
  std::vector<int> geom_object_, bounce_object_;
  render::PinholeCamera camera_;
};

void check_options(const ReferenceOptions& opt) {
  if (opt.spp <= 0 || opt.spp > kMaxSpp)
    throw std::invalid_argument("reference: spp = " + std::to_string(opt.spp) + " is outside 1.." + std::to_string(kMaxSpp));
  if (opt.light_sh_order < 0 || opt.light_sh_order > sh::kMaxOrder)
    throw std::invalid_argument("reference: light SH order " + std::to_string(opt.light_sh_order) +
                                " is outside 1.." + std::to_string(sh::kMaxOrder) + " (0 = full environment)");
  if (!std::isfinite(opt.time)) throw std::invalid_argument("reference: time is not finite");
  // The printed reading can grow a sphere beyond S, outside the box the BVH was built from.
  if (opt.replacement_rule == proxies::ReplacementRule::Printed)
    throw std::invalid_argument("reference: replacement rule 'printed' is not supported (its spheres can outgrow the proxy "
                                "spheres the BVH bounds; expected off, continuous or clamped)");
  if (opt.width < 0 || opt.height < 0 || opt.width > kMaxDimension || opt.height > kMaxDimension)
    throw std::invalid_argument("reference: image size " + std::to_string(opt.width) + "x" + std::to_string(opt.height) +
                                " is outside 0.." + std::to_string(kMaxDimension) + " (0 = the camera's)");
}

}  // namespace

ReferenceResult render_reference(const scene::Scene& sc, const ReferenceOptions& opt,
                                 const std::function<void(double)>& progress, const PassCallback& on_pass) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  check_options(opt);
  Renderer r(sc, opt);
  const double setup = std::chrono::duration<double>(clock::now() - t0).count();
  const int W = r.width(), H = r.height();
  const int tiles_x = (W + kTile - 1) / kTile, tiles_y = (H + kTile - 1) / kTile, tiles = tiles_x * tiles_y;
  const std::size_t npix = static_cast<std::size_t>(W) * H;
  std::vector<glm::dvec3> acc_direct(npix, glm::dvec3(0.0)), acc_indirect(npix, glm::dvec3(0.0));
  std::atomic<long long> rays{0};

  // Passes end at cumulative spp 1, 2, 4, ..., opt.spp.
  std::vector<int> ends;
  for (int e = 1; e < opt.spp; e *= 2) ends.push_back(e);
  ends.push_back(opt.spp);
  const double total_work = static_cast<double>(tiles) * opt.spp;
  double done_work = 0.0;
  const int batch = std::max(1, 4 * tbb::this_task_arena::max_concurrency());

  ReferenceResult res;
  auto fill = [&](int spp_done) {
    res.direct = Image(W, H);
    res.indirect = Image(W, H);
    res.final_image = Image(W, H);
    const double inv = 1.0 / spp_done;
    for (std::size_t i = 0; i < npix; ++i) {
      vec3 d(acc_direct[i] * inv), in(acc_indirect[i] * inv);
      if (!finite3(d) || !finite3(in))
        throw std::runtime_error("reference: non-finite radiance at pixel (" + std::to_string(i % W) + ", " +
                                 std::to_string(i / W) + ") of scene '" + sc.name + "'");
      res.direct.rgb[i] = d;
      res.indirect.rgb[i] = in;
      res.final_image.rgb[i] = d + in;
    }
    res.spp = spp_done;
    res.rays = rays.load();
    res.setup_seconds = setup;
    res.seconds = std::chrono::duration<double>(clock::now() - t0).count();
    res.seconds_per_sample = (res.seconds - setup) / spp_done;
  };

  if (progress) progress(0.0);
  int begin = 0;
  for (int end : ends) {
    for (int b0 = 0; b0 < tiles; b0 += batch) {
      const int b1 = std::min(tiles, b0 + batch);
      tbb::parallel_for(tbb::blocked_range<int>(b0, b1, 1), [&](const tbb::blocked_range<int>& range) {
        long long local_rays = 0;
        for (int t = range.begin(); t != range.end(); ++t) {
          const int tx = (t % tiles_x) * kTile, ty = (t / tiles_x) * kTile;
          for (int y = ty; y < std::min(H, ty + kTile); ++y)
            for (int x = tx; x < std::min(W, tx + kTile); ++x) {
              glm::dvec3 sd(0.0), si(0.0);
              for (int k = begin; k < end; ++k) {
                vec3 d, in;
                r.sample(x, y, k, d, in, local_rays);
                sd += glm::dvec3(d);
                si += glm::dvec3(in);
              }
              const std::size_t i = static_cast<std::size_t>(y) * W + x;
              acc_direct[i] += sd;
              acc_indirect[i] += si;
            }
        }
        rays += local_rays;
      });
      r.check_embree("tracing");
      done_work += static_cast<double>(b1 - b0) * (end - begin);
      if (progress) progress(std::min(1.0, done_work / total_work));
    }
    begin = end;
    if (on_pass && end < opt.spp) {
      fill(end);
      on_pass(end, res);
    }
  }
  fill(opt.spp);
  if (on_pass) on_pass(opt.spp, res);
  return res;
}

}  // namespace softgi::reference
