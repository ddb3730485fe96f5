// Image-space proxy accumulation (paper 000, Sloan et al. 2007): the frame resources of the
// technique's passes and the CPU pieces they are made of, exposed to tests/image_splat and to later
// backends (a Vulkan implementation of these passes fills the same structures). Not installed;
// include by path.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "../common/accumulation.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/scene/scene.hpp"
#include "softgi/sh/tables.hpp"
#include "splat_math.hpp"
#include "../common/upsample.hpp"

namespace softgi::render {
class FrameContext;
}

namespace softgi::techniques::image_splat {

// Upsampling is the shared library's (paper 000 section 4.2; techniques/common/upsample.hpp).
using common::cpu_upsample_kernels;
using common::parse_upsample_fallback;
using common::parse_upsample_mode;
using common::PlaneView;
using common::upsample_apply;
using common::upsample_apply_bilinear;
using common::upsample_weights;
using common::UpsampleFallback;
using common::UpsampleKernels;
using common::UpsampleMode;
using common::UpsampleOptions;
using common::UpsampleWeights;

// The paper's expansion factors (section 4.1): eta = 15 for order-4 shadows, 10 for order-3 indirect.
inline constexpr double kPaperEtaShadow = 15.0;
inline constexpr double kPaperEtaIndirect = 10.0;
// Rows of the smooth clamp ramp (section 4.1: "the 4 table entries around 1/eta").
inline constexpr int kClampRampRows = 4;

enum class Coverage { Derived, Environment, Paper, Off };
const char* to_string(Coverage c);
enum class ExpMode { HYB, OL, PSStar, PS, Exact };
// What the direct shading interpolates with the eq. 11 weights: transfer rows (common::ShadeTransfer)
// or O_p (section 4.2 as written). The same value in exact arithmetic.
enum class ShadeInterpolation { Transfer, Visibility };
// shade_interpolation=auto takes transfer rows from this receiver_scale on: each coarse sample's row
// (a (3 n^2) x n^2 matrix-vector product, 3 or 4 n^2 floats stored) then serves 16 display pixels or
// more. Measured at 1024x1024 (bench/README.md, "image_splat's direct shading through transfer
// rows"): no faster than O_p at scale 2, faster from scale 4 on, on character and cornell.
inline constexpr int kTransferMinScale = 4;

// The technique's parameters, read and cross-checked once per frame (read_settings throws
// std::invalid_argument naming the parameters).
struct Settings {
  int order = 4;                // shadow SH order n
  bool indirect = true;
  int indirect_order = 3;
  IndirectOperator op = IndirectOperator::AveragedPolynomial;
  bool normalize_indirect = true;  // eq. 12 (off: the plain sum, for the overlap test)
  int receiver_scale = 2;
  Coverage coverage = Coverage::Derived;
  LightNormalisation eta_light = LightNormalisation::UnitShading;  // of the eta derivation
  double eta_threshold = 1.0 / 256.0;
  double eta_shadow = 0.0, eta_indirect = 0.0;  // overrides (0 = from coverage)
  bool smooth_clamp = true;
  ExpMode exp = ExpMode::HYB;
  int ps_degree = 2;
  common::ReplacementRule rule = common::ReplacementRule::Continuous;
  double window_h = 0.0;        // resolved (-1 -> 2n); 0 = off
  int table_resolution = 256;
  double log_threshold = 0.02;
  UpsampleOptions upsample;
  UpsampleFallback fallback = UpsampleFallback::Robust;
  ShadeInterpolation shade_interpolation = ShadeInterpolation::Transfer;
  int tile_size = 16;
  bool device_binning = false;  // binning = device: a backend's compute pass bins (DeviceKernels::bin_proxies)
  bool raster_splats = false;   // splatting = raster: a backend rasterises the splats (DeviceKernels::splat_log, splat_indirect)
  bool lights = true;
  common::KernelIsa isa = common::KernelIsa::Scalar;
};
std::vector<render::ParamDesc> param_descs();
Settings read_settings(const render::ParamSet& p);

// --- tables (section 4.1) ------------------------------------------------------------------------
struct ShadowTables {
  int order = 0;
  std::shared_ptr<const sh::ShTables> sh;  // cap log / visibility and OL tables at the shadow order
  common::ZhTable log;                      // log occlusion ZH, smoothly clamped at eta_shadow (or hard: see below)
  bool hard_cut = false;                   // smooth_clamp = false: log unclamped, pairs cut at eta r exactly
  double eta_shadow = 0.0;                 // 0 = no sphere of influence
  double eta_indirect = 0.0;
  // Where the tables are exactly zero: a pair with r / d <= support_alpha_* contributes exactly 0
  // (the clamped rows and the linear interpolation between them). 0 = no support bound.
  double support_alpha_shadow = 0.0, support_alpha_indirect = 0.0;
  std::size_t bytes() const;
};
// The sine of the largest theta below which a theta-sampled table with these rows, clamped by
// clamp_zh_table(eta, ramp_rows), reads exactly 0 under linear interpolation (0 when eta <= 1).
double clamped_support_alpha(int rows, double eta, int ramp_rows);

// --- receivers (section 4) -----------------------------------------------------------------------
// The receiver buffer's hit pixels as shexp receivers, ordered by screen tile (tile_size x tile_size
// coarse pixels), with each tile's world-space bounding box for the binning of proxies.
struct ReceiverTile {
  std::size_t begin = 0, end = 0;  // range in the tile-ordered receiver arrays
  glm::vec3 lo{0.0f}, hi{0.0f};    // AABB of the tile's receiver positions
};
struct ReceiverBuffer {
  int width = 0, height = 0, scale = 1, tile_size = 16, tiles_x = 0, tiles_y = 0;
  common::ReceiverSoA soa;                // tile order
  std::vector<std::int32_t> pixel;       // receiver -> coarse pixel index
  std::vector<std::int32_t> receiver;    // coarse pixel -> receiver, -1 = background
  std::vector<ReceiverTile> tiles;       // only tiles with receivers
  std::size_t bytes() const;
};
ReceiverBuffer make_receivers(const render::GBuffer& coarse, int tile_size);

// --- binning (section 4.1, CPU form of splatting the spheres of influence) ------------------------
// Per receiver tile, the proxies whose sphere of influence reaches the tile's box: a sphere of
// radius r with support alpha (see ShadowTables) reaches receivers within r / alpha of its centre.
// Splatting the sphere of influence and testing each receiver's depth (Figure 3) selects exactly the
// receivers for which the table is non-zero; binning to tiles selects a superset, and the extra
// pairs read exactly 0 from the clamped table, so both give the same sums.
struct ProxyBins {
  std::vector<common::BlockerList> shadow;  // per tile (index as ReceiverBuffer::tiles)
  std::vector<ProxyList> indirect;         // per tile; empty when indirect light is off
  double pairs_tested = 0.0;               // tile-proxy tests
  double shadow_tile_pairs = 0.0, indirect_tile_pairs = 0.0;
  std::size_t bytes() const;
};
// What a binning found, per tile, for the pass record (host or device binning alike).
struct BinCounts {
  std::vector<std::uint32_t> shadow_counts, indirect_counts;  // entries per tile (indirect: empty when off)
  double pairs_tested = 0.0;                                  // tile-proxy tests
  std::size_t bytes = 0;                                      // of the lists
  double gpu_seconds = -1.0;                                  // device binning: GPU time of its dispatches
  std::size_t upload_bytes = 0, download_bytes = 0;           // device binning: transfers
};
BinCounts bin_counts(const ProxyBins& bins);
// influence_radius(r) = r / alpha (1 + kInfluenceMargin), or infinity for alpha <= 0 (no sphere of
// influence). The margin covers the float rounding of the distance the kernels compute (a few ulps):
// binning more than needed costs pairs that add exactly 0, binning less would drop contributions.
inline constexpr double kInfluenceMargin = 1e-4;
float influence_radius(float r, double support_alpha);
bool sphere_meets_box(const glm::vec3& c, float radius, const glm::vec3& lo, const glm::vec3& hi);
// All proxy spheres of the posed scene, flat, with the albedo of their set (scene.proxies[s].albedo).
void flat_proxies(const scene::Scene& scene, const scene::PosedScene& posed, int order, common::BlockerList* shadow,
                  ProxyList* indirect);
ProxyBins bin_proxies(const ReceiverBuffer& rec, const common::BlockerList& all_shadow, double alpha_shadow,
                      const ProxyList* all_indirect, double alpha_indirect);

// --- accumulation --------------------------------------------------------------------------------
// Sum of log occlusion vectors (eq. 4, exponent) for receivers [begin, end) over `list`. The clamped
// table goes through common::accumulate_log (the SHEXP kernel, self-shadowing rules included); with
// hard_cut, pairs with |c - p| >= eta r are skipped first (scalar path: rule, then eq. 34 per pair).
// The per-pair cut of accumulate_log_range: a pair counts only where |c - p| < factor r; 0 when the
// clamped table alone confines each proxy (then the SHEXP kernel runs unchanged). Shared with the
// Vulkan pass, whose shader applies the same cut.
float pair_cut_factor(const ShadowTables& t, common::ReplacementRule rule);
// influence_radius(r, alpha) / r: the per-pair cut of a sphere of influence (0 for alpha <= 0).
float reach_factor(double support_alpha);
void accumulate_log_range(const ShadowTables& t, common::ReplacementRule rule, common::KernelIsa isa,
                          const common::ReceiverSoA& rec, std::size_t begin, std::size_t end,
                          const common::BlockerList& list, float* out);
// O_p = exp(log) for `count` receivers (order^2 floats each).
void exponentiate(const ShadowTables& t, ExpMode mode, int ps_degree, common::KernelIsa isa, const float* f, float* g,
                  std::size_t count, std::size_t first);

// Eq. 12: xi_p = (1 - O_p)_0 / (omega_p / sqrt(4 pi)), (1 - O_p)_0 = sqrt(4 pi) - O_p,0: the solid angle
// of the union of the proxies over the sum of their solid angles. The exact quantities satisfy
// 0 <= union <= sum, so xi lies in [0, 1]; the SH exponential's error (O_p,0 above sqrt(4 pi) or below
// sqrt(4 pi) - omega_p / sqrt(4 pi)) and the different clamps of the shadow and indirect tables can
// push the computed ratio outside, hence the clamp. omega_p -> 0 (no proxy in reach): xi = 1, harmless
// since the sum it scales is 0 too.
float indirect_normalisation(float o0, float omega);

// --- shading (eq. 10) -----------------------------------------------------------------------------
// Direct shading of receivers: E_i = (H(N_i) * (W O_i)) . L per channel plus the spherical lights'
// L_H . (W O_i) (the light-lobe table of SHEXP), clamped at 0; W is the visibility window.
// Without O (no proxies) the receivers are unshadowed.
struct DirectShader {
  int order = 0;
  ShadeInterpolation interpolate = ShadeInterpolation::Transfer;  // for DirectKernels::surface on the CPU
  std::vector<float> L;      // 3 x n^2, channel-major (windowed when window_h > 0)
  std::vector<float> hcoef;  // n^2: H(N)_lm = hcoef y_lm(N)
  std::vector<float> gwin;   // n^2: window on the visibility
  std::shared_ptr<const common::LightLobeTable> lights_table;  // null: no spherical light shading
  std::vector<scene::SphericalLight> lights;
  common::KernelIsa isa = common::KernelIsa::Scalar;
  // out[i - begin] for receivers [begin, end) of rec; g: visibility of receiver i at g + i n^2 (null:
  // unshadowed). A receiver with a zero normal (no surface) gets 0. Returns the receivers clamped at 0.
  long long shade(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end, const float* g,
                  glm::vec3* out) const;
  // The same with the visibility interpolated from a coarse field in the kernel (BatchShade::Taps).
  // The spherical lights read it per receiver: when shades_lights(), taps.out must hold n^2 floats
  // per receiver of rec (the kernel writes them, the lights read them).
  // transfer: taps.coarse holds transfer rows of this shader (common::ShadeTransfer) instead of O_p;
  // with spherical lights (they read O_p per receiver) rows that carry it.
  long long shade(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end, const common::BatchShade::Taps& taps,
                  const common::ShadeTransfer* transfer, glm::vec3* out) const;
  bool shades_lights() const { return common::shades_lights(lights_table.get(), lights); }
  // SHEXP's batch-shading constants over this shader's floats (g: visibility, n^2 per receiver).
  common::BatchShade batch(const float* g) const;
};
DirectShader make_direct_shader(const std::vector<glm::vec3>& env_sh, int order, double window_h,
                                std::shared_ptr<const common::LightLobeTable> lt, const std::vector<scene::SphericalLight>& lights,
                                common::KernelIsa isa);
// L~ (irradiance SH of the windowed environment, per channel) at `order` for the indirect evaluator.
std::vector<glm::vec3> irradiance_sh(const std::vector<glm::vec3>& env_sh, int order);

// --- per-frame fields ----------------------------------------------------------------------------
struct Field {  // per receiver (tile order), `channels` floats
  int channels = 0;
  std::vector<float> v;
};
struct IndirectSums {  // per receiver: sum_i albedo_i/pi I_i . H(N) (3 floats) and omega_p
  std::vector<float> rgb, omega;
  double pairs = 0.0;
};
struct Upsampled {  // display resolution
  UpsampleWeights w;
  int order = 0;
  // O_p is not stored at display resolution (n^2 floats per pixel, 64 MB at 1024^2 and order 4):
  // shade_direct interpolates it with w per block of surface pixels from this coarse copy.
  std::vector<float> coarse_visibility;  // n^2 per coarse pixel (empty without proxies)
  // O_p left on the device by a GPU exponentiate (the resource is deferred): the resource's name;
  // coarse_visibility then stays empty and a device kernel gathers from O_p in receiver order,
  // through the coarse pixels' receivers. A host kernel has it read back first (pass_shade_direct).
  const char* device_visibility = nullptr;
  std::vector<std::int32_t> coarse_receiver;  // per coarse pixel, its receiver (-1: background)
  std::vector<std::int32_t> surface;     // display pixels that hit a surface, in scan order
  std::vector<float> indirect;           // 3 per display pixel (empty without indirect)
  std::size_t bytes() const;
};
// The kernels of shade_direct (eq. 10's first term): the pass body is one (image_splat.cpp
// pass_shade_direct); the kernels are DirectShader::shade on the CPU and shaders/common/shade.comp on
// Vulkan (vulkan_direct_kernels, image_splat_vulkan.hpp).
struct DirectKernels {
  // out[k] for the display surface pixels up.surface[k] of `fine`: O_p interpolated with the eq. 11
  // weights (section 4.2; a pixel without a tap, or a frame without O_p, is unshadowed), then shaded.
  // Returns the pixels clamped at 0.
  std::function<long long(const DirectShader& d, const render::GBuffer& fine, const Upsampled& up, glm::vec3* out)> surface;
  // out[i] for every receiver of rec, visibility g (n^2 per receiver; null: unshadowed).
  std::function<long long(const DirectShader& d, const common::ReceiverSoA& rec, const float* g, glm::vec3* out)> receivers;
  // Whether `surface` gathers O_p from the device when Upsampled::device_visibility is set.
  bool reads_device_visibility = false;
};
// pool: where per-frame scratch (the transfer rows) comes from; null: allocated per call.
DirectKernels cpu_direct_kernels(render::FramePool* pool = nullptr);

// For fallback = robust: the misses shaded from the full proxy list.
struct RobustMisses {
  std::vector<std::int32_t> pixel;  // display pixel of each miss
  common::ReceiverSoA soa;
  std::vector<float> visibility;    // n^2 per miss (empty without proxies)
  std::vector<float> indirect;      // 3 per miss (empty without indirect)
};


// A backend's implementations of image_splat's GPU passes (image_splat_vulkan.hpp), reading and
// writing the same frame resources as the host passes. exp_supports / indirect_supported: the
// methods and operators the backend runs (the others run the host pass there).
struct DeviceKernels {
  // accumulate_log writes the log occlusion (a shared_ptr<const Field>) as resource `out`;
  // exponentiate reads resource `in` (the log occlusion) and writes O_p as `out`. A device backend
  // may leave them on the device (FrameContext::put_deferred), read back only for a host pass.
  // bin_proxies writes the per-tile lists of the flat proxy lists as resource `out` (a device copy,
  // the host ProxyBins deferred) and returns the counts for the record; accumulate_log and
  // accumulate_indirect read the lists of resource `bins` (the device copy where there is one).
  std::function<BinCounts(render::FrameContext&, const ReceiverBuffer&, std::shared_ptr<const common::BlockerList> all_shadow,
                          double alpha_shadow, std::shared_ptr<const ProxyList> all_indirect, double alpha_indirect,
                          const std::string& out)>
      bin_proxies;
  std::function<void(render::FrameContext&, const Settings&, const ShadowTables&, const ReceiverBuffer&, const std::string& bins,
                     const std::string& out)>
      accumulate_log;
  // accumulate_log as paper 000 draws it (section 4.1, Figure 3): the spheres of influence of the
  // flat shadow list rasterised into the receiver buffer, summed by blending; writes resource `out`
  // as accumulate_log does (splatting = raster; splat_indirect below is its indirect counterpart).
  std::function<void(render::FrameContext&, const Settings&, const ShadowTables&, const ReceiverBuffer&, const common::BlockerList& all,
                     double alpha_shadow, const std::string& out)>
      splat_log;
  std::function<bool(ExpMode)> exp_supports;
  std::function<void(render::FrameContext&, const Settings&, const ShadowTables&, const std::string& in, const std::string& out)>
      exponentiate;
  std::function<bool(IndirectOperator)> indirect_supported;
  std::function<std::shared_ptr<IndirectSums>(render::FrameContext&, const ReceiverBuffer&, const std::string& bins,
                                              const IndirectEvaluator&)>
      accumulate_indirect;
  // accumulate_indirect by rasterised splats of the flat re-radiating proxy list (splatting = raster).
  std::function<std::shared_ptr<IndirectSums>(render::FrameContext&, const ReceiverBuffer&, const ProxyList& all, double alpha_indirect,
                                              const IndirectEvaluator&)>
      splat_indirect;
  std::function<UpsampleKernels(render::FrameContext&)> upsample;
  // The DC coefficient of every row of a field a GPU pass left on the device (resource `name`, n^2
  // floats per receiver): what normalize_indirect's xi_p needs of O_p, read back without the rest.
  std::function<std::vector<float>(render::FrameContext&, const std::string& name)> field_dc;
  std::function<DirectKernels(render::FrameContext&)> direct;
};
// Registers (or replaces) `backend`'s kernels; plan() adds them to every graph it builds after.
void register_device_kernels(const std::string& backend, DeviceKernels kernels);

}  // namespace softgi::techniques::image_splat
