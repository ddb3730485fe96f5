// The shared proxy-accumulation library: what more than one technique builds on. Log-space
// accumulation of sphere blockers in SH (paper 004 sections 5-6: ZH tables, the rotation rule of
// eq. 34, the replacement rules of section 6.2) in receiver and blocker structure-of-arrays layout,
// vectorised kernels (AVX-512, AVX2, scalar), batched SH exponentials and shading, and analytic
// spherical lights (paper 004 section 7). SHEXP (paper 004) and image-space accumulation (paper 000)
// both run on these; citations resolve in docs/papers.md. Not installed; include by path
// (techniques/common/...).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/proxies/self_shadow.hpp"
#include "softgi/scene/scene.hpp"
#include "softgi/sh/exp_log.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::render {
class FrameContext;
}

namespace softgi::techniques::common {

inline constexpr int kMinOrder = 3;   // SH orders the accumulation techniques shade at
inline constexpr int kMaxOrder = 6;
inline constexpr int kMaxAccOrder = 8;  // accumulation may run above the shading order (Figure 7e)

// ---------------------------------------------------------------------------------------------
// Self-shadowing replacement rules (paper 004 section 6.2, Figure 5): the core's one definition,
// shared with the reference renderer's proxy blockers (softgi/proxies/self_shadow.hpp has the rules
// and the reading of the paper's scale factor). The vector kernels (kernel_body.hpp) and the GLSL
// port (shaders/include/replacement_rule.glsl) implement the same rules and are tested against
// apply_replacement_rule (tests/shexp: ShexpKernel.*, ShexpRules.*).
using proxies::AdjustedSphere;
using proxies::apply_replacement_rule;
using proxies::ReplacementRule;
const char* to_string(ReplacementRule r);
ReplacementRule parse_replacement_rule(const std::string& s);  // throws naming the value

// ---------------------------------------------------------------------------------------------
// A ZH table in float for the hot loops: per theta sample k (uniform in [0, pi/2]), the n values
// F_l(theta_k) = sqrt(4 pi/(2l+1)) zh_l(theta_k) (the rotation rule's factor folded in, so that
// f_lm = F_l y_lm(s), eq. 34), each followed by its slope F_l(theta_{k+1}) - F_l(theta_k): the
// kernel fetches a band's (value, slope) pair with one 64-bit gather.
struct ZhTable {
  int order = 0, rows = 0;
  float scale = 0.0f;        // (rows - 1) / (pi/2): theta to row coordinate
  std::vector<float> data;   // rows * 2 * order: (value, slope) of band 0, band 1, ...
  std::vector<float> band;   // the same, band-major: per band, rows values then rows slopes
  void lookup(float theta, float* out) const;  // linear interpolation, theta clamped to [0, pi/2]
  std::size_t bytes() const { return (data.size() + band.size()) * sizeof(float); }
};
// From a theta-sampled sh::Table1D of width >= order (cap log or cap visibility ZH). Row 0 of a log
// table is forced to exactly 0 (a sphere of radius 0 changes nothing).
ZhTable make_zh_table(const sh::Table1D& table, int order, bool zero_first_row);

// eq. 34 (and eq. 38 with band weights w, nullptr = 1) for one receiver and one sphere, scalar:
// out[n^2] = W F(theta(p, c, r)) y(s(p, c)). theta = asin(min(1, r/|c - p|)).
void sphere_zh_vector(const ZhTable& table, const glm::vec3& p, const glm::vec3& c, float r, const float* w,
                      float* out);

// ---------------------------------------------------------------------------------------------
// Receivers in structure-of-arrays layout, ordered by receiver cluster.
struct ReceiverSoA {
  std::vector<float> px, py, pz, nx, ny, nz;
  std::size_t size() const { return px.size(); }
  void resize(std::size_t n);
  void set(std::size_t i, const glm::vec3& p, const glm::vec3& n);
};

// A blocker list (one receiver cluster's cut, or the flat leaf list), SoA, with band weights
// w[b * order + l] (eq. 37 ratio vectors; 1 for leaves and for the flat list).
struct BlockerList {
  int order = 0;
  std::vector<float> cx, cy, cz, r, w;
  std::size_t size() const { return r.size(); }
  void push(const glm::vec3& c, float radius, const float* weights /* nullptr: all 1 */);
  std::size_t bytes() const { return (cx.size() * 4 + w.size()) * sizeof(float); }
};

// ---------------------------------------------------------------------------------------------
// The accumulation kernel (eq. 34 / eq. 38 summed over a blocker list, with the replacement rules):
// out[i * n^2 + k] = sum_b W_b F(theta_ib) y_k(s_ib) for receivers i in [begin, end) of `rec`,
// n = table.order (3..8). Vectorised across receivers (16 lanes with AVX-512, 8 with AVX2+FMA):
// every lane shares the blocker, so blocker data is broadcast and only the table rows are gathered.
enum class KernelIsa { Scalar, Avx2, Avx512 };
const char* to_string(KernelIsa isa);
KernelIsa best_kernel_isa();            // what this CPU runs (checked at run time)
bool kernel_isa_supported(KernelIsa isa);
int kernel_lanes(KernelIsa isa);
void accumulate_log(KernelIsa isa, const ZhTable& table, ReplacementRule rule, const ReceiverSoA& rec,
                    std::size_t begin, std::size_t end, const BlockerList& blockers, float* out);

// ---------------------------------------------------------------------------------------------
// Sphere proxies as diffuse secondary lights of SH radiance L~ (paper 000 section 5): for receivers
// i in [begin, end) of `rec`, rgb[3 i + c] += sum_p albedo_p/pi kappa_c(p, i) (V . H(N_i))(p, i) and
// omega[i] += sum_p F_0, where the proxy is first adjusted by the replacement rule (as the shadow
// kernel), theta its angular radius, s the direction to it, F_l(theta) its own visibility (`vis`),
// V . H(N) = sum_l F_l vh_l P_l(s . N) and kappa_c = sum_l fac_l sum_m y_lm(s) L~_lm,c with
// fac_l = (-1)^l (point-sampled, eq. 13; band_factor null) or fac_l(theta) from `band_factor`
// (averaged, eq. 15: sqrt(4pi/(2l+1)) D_l, on the rows of `vis`). A pair counts where |c - p| <
// reach r (reach > 0, the proxy as given) and sin theta > 1/eta (eta > 1; eta <= 0: no cut). Returns
// the pairs counted. Vectorised across receivers like accumulate_log; the exact operator (eqs.
// 16-17) and the per-pair reference are image_splat's IndirectEvaluator.
struct ProxyLightTables {
  const ZhTable* vis = nullptr;          // order n in [kMinOrder, kMaxOrder]
  const ZhTable* band_factor = nullptr;  // null: point-sampled
  const float* ltilde = nullptr;         // n^2 x 3, coefficient-major: [3 k + c]
  const float* vh = nullptr;             // n: (g_cos,l / pi) sqrt((2l+1)/(4pi))
  ReplacementRule rule = ReplacementRule::Continuous;
  float eta = 0.0f;
  float reach = 0.0f;
};
struct ProxyLightList {
  const float *cx = nullptr, *cy = nullptr, *cz = nullptr, *r = nullptr;
  const glm::vec3* albedo = nullptr;
  std::size_t count = 0;
};
long long accumulate_proxy_lights(KernelIsa isa, const ProxyLightTables& tables, const ReceiverSoA& rec, std::size_t begin,
                                  std::size_t end, const ProxyLightList& lights, float* rgb, float* omega);

// One receiver against a list of spheres, a sphere per lane: the transpose of accumulate_log, for
// a technique that keeps each sphere's own term (paper 001's spherical lights, eqs. 21-23, where a
// light is darkened by the lights in front of it). For sphere j in [0, count) adjusted by `rule` as
// seen from (p, n) (apply_replacement_rule): alive[j] = 0 where the rule eliminates it or p is not
// outside it; else 1, key[j] = |P'_j - p| - rho_j and g[j n^2 ..] its eq. 34 log vector
// (sphere_zh_vector of `log`, order n; no band weights). With emission (L non-null), rgb[3 j + c] is
// the sphere's SH intensity averaged over it as seen from p (paper 001 eq. 18), for every sphere:
// rgb_c = sum_l w_l(theta) sqrt(4 pi/(2l+1)) sum_m y_lm(d) L_lm,c with theta = asin(r/|p - c|) of the
// sphere as given (pi/2 from inside it) and d the unit direction from its centre to p in its own
// frame (+z at the centre). Throws std::invalid_argument for a table order outside [3, 8], missing
// arrays or an ISA this CPU lacks.
struct SphereFan {
  const float *cx = nullptr, *cy = nullptr, *cz = nullptr, *r = nullptr;
  std::size_t count = 0;
  // Emission (L null: none). Per sphere j an index id[j] into L (3 n^2 floats each, channel-major:
  // the intensity in the sphere's own frame) and rot (9 floats each: the column-major 3 x 3 from that
  // frame to the world); weight: weight_rows x n band weights w_l(theta_k), theta_k = k (pi/2) /
  // (weight_rows - 1), linear in theta between rows.
  const int* id = nullptr;
  const float* L = nullptr;
  const float* rot = nullptr;
  const float* weight = nullptr;
  int weight_rows = 0;
};
void sphere_fan(KernelIsa isa, const ZhTable& log, ReplacementRule rule, const glm::vec3& p, const glm::vec3& n, const SphereFan& spheres,
                float* g, float* key, std::uint8_t* alive, float* rgb);

// Floating-point operations per receiver-blocker pair of the kernel at this order and rule, counted
// by running the kernel's own code on a counting number type (add, sub, mul, div, sqrt = 1,
// fma = 2, a refined reciprocal square root = 2 for the sqrt and division it replaces; compares,
// selects, min/max, conversions, loads and permutes = 0). A sphere entirely in front of every
// lane's tangent plane skips the replacement rules; `straddling` counts the path through them.
double kernel_flops_per_pair(int order, ReplacementRule rule, bool straddling = false);

// ---------------------------------------------------------------------------------------------
// Batched SH products, exponentials and shading over blocks of receivers (the same instruction sets
// as the kernel). The triple-product terms of sh::TripleProduct, grouped by output index.
struct ProductPlan {
  int order = 0;
  // Squares: out_i = sum over [sq_begin[i], sq_begin[i+1]) of sq_v f_j f_k (symmetric terms merged).
  std::vector<int> sq_begin;
  std::vector<std::uint16_t> sq_j, sq_k;
  std::vector<float> sq_v;
  // Products: [pr_begin[i], pr_offdiag_end[i]) are j < k terms v (f_j g_k + f_k g_j), the rest of
  // [.., pr_begin[i+1]) are j == k terms v f_j g_j.
  std::vector<int> pr_begin, pr_offdiag_end;
  std::vector<std::uint16_t> pr_j, pr_k;
  std::vector<float> pr_v;
  static const ProductPlan& get(int order);  // cached, thread-safe
};

// out = f * f, and out = f * g (eq. 3), for `count` SH vectors of `order` (receiver-major, order^2
// floats each), through ProductPlan::get(order) and the code exp_batch and shade_batch use: the plan's
// terms written out for orders 1..6 (gen/sh_plan_cpp.cpp), a loop over them above. Throws
// std::invalid_argument for an order outside 1..8 or an instruction set this CPU lacks.
void square_batch(KernelIsa isa, int order, const float* f, float* out, std::size_t count);
void product_batch(KernelIsa isa, int order, const float* f, const float* g, float* out, std::size_t count);

struct BatchExp {
  int order = 0;
  sh::ExpMethod method = sh::ExpMethod::HYB;  // HYB, OL, PSStar or PS
  int degree = 2;                             // PS*-p, PS-p
  const sh::ShTables* tables = nullptr;       // OL a, b (HYB, OL)
  const ProductPlan* plan = nullptr;
};
bool exp_batch_supports(sh::ExpMethod m);
// g = exp*(f) for `count` receivers, f and g receiver-major (order^2 floats each), the same rules
// and statistics as sh::exp per receiver. `first` numbers the receivers in error messages. Throws
// std::invalid_argument for non-finite input and std::overflow_error for results out of range.
void exp_batch(KernelIsa isa, const BatchExp& e, const float* f, float* g, std::size_t count, std::size_t first,
               sh::ExpStats& stats);

struct ShadeTransfer;
struct BatchShade {
  int order = 0;
  const ProductPlan* plan = nullptr;
  const float* L = nullptr;      // light, 3 x order^2 (channel-major)
  const float* hcoef = nullptr;  // order^2: H(N)_lm = hcoef y_lm(N) (clamped cosine / pi, rotation factor folded in)
  const float* gwin = nullptr;   // order^2: window factor of the visibility per coefficient (1 = none)
  const float* g = nullptr;      // visibility, receiver-major order^2 per receiver; null = unshadowed
  // Instead of g: the visibility of receiver i interpolated from a coarse field (paper 000 eq. 11),
  // g_i = sum_t weight[pixel[i]][t] coarse[index[pixel[i]][t] order^2 + k], the taps packed to the
  // front (-1 unused); a receiver whose first tap is -1 is unshadowed. Interpolated in the kernel,
  // straight into its lanes, so that no receiver-major copy is needed. A reader after the kernel
  // that wants g_i per receiver (add_lights_and_clamp's spherical lights) has it written to `out`.
  struct Taps {
    const std::int32_t* pixel = nullptr;                 // per receiver of rec
    const std::array<std::int32_t, 4>* index = nullptr;  // per pixel
    const std::array<float, 4>* weight = nullptr;        // per pixel
    const float* coarse = nullptr;                       // order^2 per coarse sample
    float* out = nullptr;  // null, or g_i written at out + i order^2 (the unshadowed vector where no tap)
  };
  const Taps* taps = nullptr;
  // With taps: taps->coarse holds the coarse samples' transfer rows (ShadeTransfer::stride() floats
  // each) instead of their visibility, and a receiver is shaded as y(N) . sum_t w_t R_t; taps->out
  // receives g_i only from rows that carry the visibility (ShadeTransfer::carries_visibility).
  const ShadeTransfer* transfer = nullptr;
  // The plan of `order` with the given arrays (ProductPlan::get is cached).
  static BatchShade make(int order, const float* L, const float* hcoef, const float* gwin, const float* g);
};
// Paper 000 eq. 10's first term with the eq. 11 interpolation (section 4.2) carried past the SH
// product. (H(N) * g) . L_c is linear in g and H(N)_a = hcoef_a y_a(N), so it equals y(N) . R_c(g) with
//   R_c,a(g) = hcoef_a sum_b A_c[a][b] gwin_b g_b,   A_c[a][b] = sum_k C_abk L_c,k,
// C the truncated triple-product tensor that ProductPlan walks. A pixel that interpolates g from
// coarse samples G_t can therefore interpolate R(G_t) and take one dot product:
//   sum_t w_t (H(N) * (gwin G_t)) . L_c = y(N) . sum_t w_t R_c(G_t),
// the same value as BatchShade's SH product per pixel in exact arithmetic, for one matrix-vector
// product per coarse sample instead of an SH product per display pixel.
// A reader that needs g_i itself per receiver as well (the spherical lights) takes rows that carry
// it: [R(g) | g], interpolated together, so that one interpolation serves both.
struct ShadeTransfer {
  int order = 0;
  bool carries_visibility = false;
  std::vector<float> at;          // n^2 rows of 3 n^2: row b holds dR/dg_b (channel-major R_c,a)
  std::vector<float> unshadowed;  // stride(): the row of the unshadowed vector (sqrt(4 pi), 0, ...)
  int stride() const { return (carries_visibility ? 4 : 3) * order * order; }
  // From b's plan, L, hcoef and gwin (A summed in double).
  static ShadeTransfer make(const BatchShade& b, bool carries_visibility = false);
};
// r[s] = the row of g[s] (R(g[s]), then g[s] where the rows carry it) for `count` visibility vectors
// (n^2 floats each), stride() floats each. An all-zero vector (a coarse pixel without a receiver)
// gives a zero row without arithmetic.
void transfer_rows(KernelIsa isa, const ShadeTransfer& t, const float* g, std::size_t count, float* r);

// out[i - begin] = (H(N_i) * g_i) . L per channel, for receivers [begin, end).
void shade_batch(KernelIsa isa, const BatchShade& b, const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out);

// ---------------------------------------------------------------------------------------------
// Product-space accumulation (Zhou et al. 2005, paper 004 eq. 6), vectorised: the baseline SHEXP
// compares its log-space accumulation with.
// The same, vectorised across receivers like the log-space kernel (the product pass's
// implementation, so that log and product space are compared with equal vectorisation): the
// visibility vectors come from the kernel's own geometry code, the products from ProductPlan. Lanes
// where a blocker is eliminated multiply by the constant 1. Returns the SH products done (per
// receiver, summed).
long long accumulate_product_batch(KernelIsa isa, const ZhTable& vis_table, ReplacementRule rule, const ReceiverSoA& rec,
                                   std::size_t begin, std::size_t end, const BlockerList& blockers, float* out);

// The SH basis-recurrence constants and asin coefficients of the CPU kernel (kernel.cpp), laid out
// as softgi_shared.h's kBasis* offsets: the Vulkan shaders evaluate the basis with the same floats.
std::vector<float> basis_recurrence_constants();

// ---------------------------------------------------------------------------------------------
// Analytic spherical lights (paper 004 section 7): L_H(theta, f) = L(theta, f) * H((0, 0, 1)) for a
// light of angular radius theta whose centre direction makes angle f with the normal (canonical
// frame: N = z, light in the xz plane), fitted per (theta, f) by a single-lobe ZH (Sloan et al. 2005):
// L_H ~ k_l y_lm(a(psi)), a(psi) = (sin psi, 0, cos psi). Stored normalised by the light's solid
// angle so that the table stays smooth as theta -> 0. Bilinear lookup.
struct LightLobeTable {
  int order = 0, rows_theta = 0, rows_f = 0;
  double window_h = 0.0;
  std::vector<float> psi;  // rows_theta * rows_f
  std::vector<float> k;    // rows_theta * rows_f * order: k_l / solid angle
  // max over theta of (max over f of ||L_H - lobe||) / (max over f of ||L_H||): the fit's error
  // relative to the light's strongest L_H at that size (a light near the horizon has a small L_H
  // whose shape one lobe fits poorly, but which contributes little).
  double max_fit_error = 0.0;
  // Lobe of a light of angular radius theta at angle f from the normal (k multiplied back by the solid angle).
  void lookup(float theta, float f, float& psi_out, float* k_out) const;
  // The same bilinear lookup with k per unit solid angle, as stored.
  void lookup_unit(float theta, float f, float& psi_out, float* k_out) const;
  std::size_t bytes() const { return (psi.size() + k.size()) * sizeof(float); }
};
// window_h > 0 windows the light's projection (section 7) before the product with H.
LightLobeTable make_light_lobe_table(int order, int rows_theta, int rows_f, double window_h);
// The exact canonical L_H(theta, f) (double, n^2), for tests.
std::vector<double> light_lh_canonical(int order, double theta, double f, double window_h);
// L_H of a spherical light (centre c, radius R) at receiver p with normal N, in world SH (n^2 floats),
// through the fitted lobe; false when the light is behind the receiver's horizon entirely or degenerate.
bool light_lh_world(const LightLobeTable& t, const glm::vec3& p, const glm::vec3& n, const glm::vec3& c, float radius,
                    float* out);
// The smallest theta the light table samples (and the floor of its solid-angle normalisation): the
// normalised L_H / Omega has a finite limit at theta -> 0 (a directional light), which this stands in for.
inline constexpr double kLightThetaFloor = 1e-3;
// The end of the diffuse shading of receivers [begin, end) of rec, shared by SHEXP's shade pass and
// image_splat's shade_direct (and mirrored by shaders/common/shade.comp): out[i - begin] holds
// (H(N) * g) . L (shade_batch); adds the spherical lights' L_H . (gwin g_i) (section 7; g_i at
// g + i n^2, null: unshadowed) when `table` is given, then clamps at 0. zero_normal_empty: a receiver
// with a zero normal (no surface) gets 0 and is not counted. Returns the receivers clamped at 0.
// shades_lights says whether it shades spherical lights (and so reads g) at all.
inline bool shades_lights(const LightLobeTable* table, const std::vector<scene::SphericalLight>& lights) {
  return table && !lights.empty();
}
// The lights are evaluated by lights_batch with `isa`.
long long add_lights_and_clamp(KernelIsa isa, const LightLobeTable* table, const std::vector<scene::SphericalLight>& lights,
                               int order, const float* gwin, const ReceiverSoA& rec, std::size_t begin, std::size_t end,
                               const float* g, bool zero_normal_empty, glm::vec3* out);
// The spherical lights' term alone, across receivers: out[i - begin] += sum over lights of
// (L_H . (gwin g_i)) radiance, L_H as light_lh_world builds it (the fitted lobe of the table, turned to
// the receiver's frame) but with the angles by shaders/common/shade.comp's polynomials (asin, acos,
// sin, cos: accum_math.glsl), so that both backends evaluate the same functions. g null: unshadowed.
// table.order must be `order`.
void lights_batch(KernelIsa isa, const LightLobeTable& table, const std::vector<scene::SphericalLight>& lights, int order,
                  const float* gwin, const ReceiverSoA& rec, std::size_t begin, std::size_t end, const float* g, glm::vec3* out);

// ---------------------------------------------------------------------------------------------
// The diffuse shading of receivers on the GPU (shaders/common/shade.comp): what shade_batch followed
// by add_lights_and_clamp computes on the CPU, out[i] = max(0, (H(N_i) * g_i) . L + lights), for
// SHEXP's shade pass and image_splat's shade_direct.
struct GpuShade {
  const BatchShade* b = nullptr;  // order, L, hcoef, gwin; b->g: n^2 per receiver (null: unshadowed, or `gather`)
  const LightLobeTable* lights_table = nullptr;  // null: no spherical light shading
  const std::vector<scene::SphericalLight>* lights = nullptr;
  bool zero_normal_empty = false;  // add_lights_and_clamp's flag
  // Paper 000 eq. 11 (image_splat): the visibility of receiver i interpolated from a coarse field,
  // g_i = sum_t weight[pixel[i]][t] coarse[index[pixel[i]][t]] (taps packed to the front, -1 unused;
  // no tap: unshadowed), in place of b->g.
  struct Gather {
    const std::int32_t* pixel = nullptr;               // per receiver
    const std::array<std::int32_t, 4>* index = nullptr;  // per display pixel
    const std::array<float, 4>* weight = nullptr;        // per display pixel
    std::size_t pixels = 0;                              // display pixels
    const float* coarse = nullptr;                       // n^2 per coarse sample
    std::size_t coarse_count = 0;
    // Instead of `coarse`: the frame resource whose device copy holds the field (a GPU pass left it
    // there); coarse_count is then taken from it.
    const char* coarse_resource = nullptr;
    // A field in another order than the coarse samples (O_p in receiver order): tap sample q reads
    // row coarse_row[q] (coarse_rows entries); null: row q.
    const std::int32_t* coarse_row = nullptr;
    std::size_t coarse_rows = 0;
  };
  const Gather* gather = nullptr;
  // The frame resource holding the visibility when a GPU pass left it on the device (b->g null):
  // the kernel binds the device copy instead of uploading b->g.
  const char* visibility_resource = nullptr;
};
// A backend's implementation of that shading (common::vulkan_shade on Vulkan): shades every receiver
// of rec into out[0, rec.size()); returns the receivers clamped at 0 and sets the pass record's
// kernel_gpu_seconds.
using ShadeKernel = std::function<long long(render::FrameContext& ctx, const GpuShade& in, const ReceiverSoA& rec, glm::vec3* out)>;

}  // namespace softgi::techniques::common
