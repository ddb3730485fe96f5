// Image-space proxy accumulation (paper 000, Sloan et al. 2007): the math that does not depend on
// images. The coverage oracle (section 4.1), smooth clamping of the ZH tables at the boundary of a
// proxy's sphere of influence (section 4.1), and the three indirect operators (section 5, eqs.
// 12-17). Not installed; include by path (techniques/image_splat/...).
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "../common/accumulation.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::techniques::image_splat {

// --- Coverage oracle (section 4.1) ----------------------------------------------------------
// A proxy of radius r influences receivers within eta * r of its centre; beyond, its half-angle
// sine alpha = r/d is below 1/eta. eta is derived as the paper does: the largest half-angle theta
// whose worst-case shading difference stays below `threshold`, eta = 1 / sin(theta).
struct EtaDerivation {
  int order = 0;
  double threshold = 0.0;     // shading difference bound (1/256: 8-bit output)
  double eta = 0.0;           // 1 / sin(theta)
  double theta_deg = 0.0;     // the largest admissible half-angle
  double max_difference = 0.0;  // worst-case shading difference at theta (<= threshold)
  std::string light;          // "delta" (worst case over lights) or "environment"
  // The difference was non-decreasing over the scanned bracket [0, theta] (if not, theta is where
  // it first exceeds the threshold: the conservative choice).
  bool monotone = true;
};
// Shadows: the light is an order-n delta (the peakiest light of that order) towards the receiver
// normal, scaled so that unshadowed shading is exactly 1; a blocker of half-angle theta anywhere on
// the receiver's sphere of directions; difference = unshadowed - shadowed shading, maximised over
// the blocker direction. With env_sh (order-n SH of an actual environment, per channel): that light,
// scaled so that the largest unshadowed shading over all normals is 1, maximised over normals and
// blocker directions.
//
// Light normalisation: the paper's text says "normalized so that unshadowed shading maps to a unit
// result" (UnitShading, the default). Its printed numbers (eta ~ 15 at order 4 for shadows, 10 at
// order 3 for indirect) are reproduced instead by a light whose peak radiance is 1 (UnitPeakRadiance:
// delta: L_n(w) = 1; environment: max over directions and channels of L(s) = 1); both are selectable.
enum class LightNormalisation { UnitShading, UnitPeakRadiance };
EtaDerivation derive_eta_shadow(int order, double threshold, const std::vector<glm::vec3>* env_sh = nullptr,
                                LightNormalisation norm = LightNormalisation::UnitShading);
// Indirect: a proxy of half-angle theta with albedo 1 re-radiating the same normalised light
// (averaged operator, eq. 15), its shading contribution at the receiver maximised over the light
// (or normal) and proxy directions.
EtaDerivation derive_eta_indirect(int order, double threshold, const std::vector<glm::vec3>* env_sh = nullptr,
    LightNormalisation norm = LightNormalisation::UnitShading);
// The worst-case differences themselves (the functions derive_eta_* invert), for tests and reports.
double shadow_difference(int order, double theta, const std::vector<glm::vec3>* env_sh = nullptr,
    LightNormalisation norm = LightNormalisation::UnitShading);
double indirect_difference(int order, double theta, const std::vector<glm::vec3>* env_sh = nullptr,
    LightNormalisation norm = LightNormalisation::UnitShading);

// --- Smooth clamping (section 4.1) ----------------------------------------------------------
// A copy of a theta-sampled ZH table (log occlusion for shadows, proxy visibility for indirect)
// whose rows up to and including the first row at or above asin(1/eta) are 0 (so that the linearly
// interpolated lookup is exactly 0 for every theta <= asin(1/eta)) and whose next `ramp_rows` rows (the paper's
// "4 table entries around 1/eta") are weighted smoothly from 0 to 1, so that a proxy's contribution
// goes to 0 continuously as a receiver leaves its sphere of influence. eta <= 1 or infinite: copy.
common::ZhTable clamp_zh_table(const common::ZhTable& table, double eta, int ramp_rows = 4);
// The weight clamp_zh_table applied to row k (for reports and tests).
double clamp_row_weight(const common::ZhTable& table, double eta, int ramp_rows, int row);

// --- Indirect operators (section 5) ---------------------------------------------------------
enum class IndirectOperator {
  PointSampled,        // eq. 13: L~(-d) over the whole disk
  AveragedPolynomial,  // eq. 15 with the paper's polynomial fit of D (order 3 only)
  AveragedExact,       // eq. 15 with D(theta) by quadrature (sh::ShTables::D_averaged)
  Exact                // eqs. 16-17: R^-1 M(theta) R L~
};
const char* to_string(IndirectOperator op);  // "point", "averaged_poly", "averaged", "exact"
IndirectOperator parse_indirect_operator(const std::string& s);  // throws naming the value

// The operator in the canonical frame (proxy centre on +z at distance 1, radius alpha, receiver at
// the origin): n^2 x n^2 row-major, mapping the SH of the irradiance function L~ to the SH of the
// radiance I the proxy shows at the receiver (its visibility V times what it re-radiates).
std::vector<double> canonical_operator(IndirectOperator op, int order, double alpha);
// Figure 5 (top): Frobenius norm of (operator - exact operator M), absolute and relative to ||M||_F.
struct OperatorError {
  double alpha = 0.0;
  double point_abs = 0.0, point_rel = 0.0;
  double averaged_abs = 0.0, averaged_rel = 0.0;          // D by quadrature
  double averaged_poly_abs = 0.0, averaged_poly_rel = 0.0;  // paper's polynomial D (order 3; else -1)
  // The same relative errors for the operators composed with the clamped-cosine convolution
  // (L~ = C L), i.e. as operators on the incident radiance L, which is how the paper measures them.
  double point_rel_L = 0.0, averaged_rel_L = 0.0, averaged_poly_rel_L = 0.0;
};
std::vector<OperatorError> operator_error_curve(int order, int samples);

// Proxies that re-radiate, SoA, with the albedo of the object each one approximates.
struct ProxyList {
  std::vector<float> cx, cy, cz, r;
  std::vector<glm::vec3> albedo;
  std::size_t size() const { return r.size(); }
  void push(const glm::vec3& c, float radius, const glm::vec3& a);
};

// Per receiver-proxy evaluation of I_i . H(N) (eq. 10's second term before normalisation) and
// omega_i (eq. 2, from the same clamped visibility table: omega_i = sqrt(4 pi) V_i,0), for one
// operator at one order. Proxies go through the self-shadowing replacement rule first (the rule-
// adjusted sphere is what the receiver sees), as in the shadow pass.
struct IndirectSetup {
  int order = 3;
  IndirectOperator op = IndirectOperator::AveragedPolynomial;
  double eta = 10.0;            // sphere of influence (<= 0: none)
  bool smooth_clamp = true;     // false: hard cut at eta (for comparison)
  int table_resolution = 256;   // rows in theta of V, D and M
  common::ReplacementRule rule = common::ReplacementRule::Continuous;
  // > 0: a pair counts only where |c - p| < reach r for the proxy as given (before the rule), the
  // receivers binning and splatting give it (influence_radius); 0: every pair. For the printed rule,
  // whose adjusted sphere can outgrow the proxy and reach receivers beyond its sphere of influence.
  double reach = 0.0;
};
class IndirectEvaluator {
 public:
  // ltilde: the environment's L~ (irradiance SH, order `order`, per channel); radiance leaving a
  // diffuse proxy of albedo a is a / pi * L~(normal). Throws std::invalid_argument for an order the
  // operator does not support (averaged_poly: 3 only) or non-finite light.
  IndirectEvaluator(const IndirectSetup& setup, const std::vector<glm::vec3>& ltilde);
  const IndirectSetup& setup() const;
  // For receivers [begin, end) of rec: rgb[3 i + c] += sum_p albedo_p/pi (I_p . H(N_i))_c and
  // omega[i] += sum_p omega_p, over the proxies of `list` (i is the receiver's index in rec, not
  // i - begin). Throws for a bad range or a proxy with a non-finite centre, radius or albedo. Returns the receiver-proxy pairs inside
  // the sphere of influence.
  // Evaluated by the batched kernel on `isa` where batched(), else pair by pair.
  long long accumulate(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end, const ProxyList& list,
                       float* rgb, float* omega, common::KernelIsa isa = common::best_kernel_isa()) const;
  // The same sums by the batched kernel (common::accumulate_proxy_lights, vectorised across
  // receivers) on one instruction set. Throws for the exact operator.
  long long accumulate_batched(common::KernelIsa isa, const common::ReceiverSoA& rec, std::size_t begin, std::size_t end,
                               const ProxyList& list, float* rgb, float* omega) const;
  // One receiver-proxy pair at a time: the reference the batched kernel is tested against and the
  // exact operator's only evaluation.
  long long accumulate_pairwise(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end, const ProxyList& list,
                                float* rgb, float* omega) const;
  bool batched() const;  // the point and averaged operators with no cut or eta > 1
  std::size_t bytes() const;
  // The evaluator's own floats, read-only, for backends that upload them (the Vulkan
  // accumulate_indirect: image_splat_vulkan_shading.cpp) so that both evaluate the same tables.
  struct TableView {
    int order = 0, rows = 0;
    float scale = 0.0f;            // theta -> row coordinate (ZhTable::scale)
    std::span<const float> ltilde;  // L~, coefficient-major: [3 k + c], n^2 x 3
    std::span<const float> vis;     // the (clamped) visibility ZhTable::data: rows x (value, slope) x n
    std::span<const float> vh;      // n: (g_cos,l / pi) sqrt((2l+1)/(4pi)), the V . H(N) band factors
    std::span<const float> dfac;    // averaged operators: rows x n, sqrt(4pi/(2l+1)) D_l; else empty
    // Exact operator (eqs. 16-17) only; empty / 0 for the others.
    std::span<const float> mtab;  // rows x mrow: per row the m-blocks of M (clamp weight folded in)
    std::span<const int> moff;    // 2n - 1: block of m starts at moff[m + n - 1] within a row; block
                                  // m is (n-|m|) x (n-|m|) row-major over l, l' in |m|..n-1
    int mrow = 0;                 // floats per row of mtab
    std::span<const float> qrot;  // band blocks of Rot(Q), Q = Rx(-90 deg): band l at qoff[l],
    std::span<const int> qoff;    // n entries, (2l+1) x (2l+1) row-major
    std::span<const float> hc;    // n: H(N)_lm = hc_l y_lm(N), sqrt(4pi/(2l+1)) g_cos,l / pi
  };
  TableView tables() const;
  ~IndirectEvaluator();
  IndirectEvaluator(IndirectEvaluator&&) noexcept;
  IndirectEvaluator& operator=(IndirectEvaluator&&) noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace softgi::techniques::image_splat
