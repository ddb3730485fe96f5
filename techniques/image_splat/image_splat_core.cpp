// Image-space proxy accumulation (paper 000, Sloan et al. 2007): the CPU pieces of the passes
// (receivers, binning, accumulation, normalisation, shading). image_splat.cpp wires them into the
// technique's pass graph.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "image_splat_internal.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::techniques::image_splat {

using common::BlockerList;
using common::ReceiverSoA;

const char* to_string(Coverage c) {
  switch (c) {
    case Coverage::Derived: return "derived";
    case Coverage::Environment: return "environment";
    case Coverage::Paper: return "paper";
    case Coverage::Off: return "off";
  }
  return "?";
}

// --- tables --------------------------------------------------------------------------------------

std::size_t ShadowTables::bytes() const { return (sh ? sh->bytes() : 0) + log.bytes(); }

double clamped_support_alpha(int rows, double eta, int ramp_rows) {
  if (!(eta > 1.0) || !std::isfinite(eta) || rows < 2) return 0.0;
  // clamp_zh_table's weights depend on the table's sampling only (rows uniform in theta on [0, pi/2]).
  common::ZhTable probe;
  probe.order = 1;
  probe.rows = rows;
  probe.scale = static_cast<float>((rows - 1) / (sh::kPi / 2.0));
  probe.data.assign(static_cast<std::size_t>(rows) * 2, 0.0f);
  probe.band = probe.data;
  int last_zero = -1;
  while (last_zero + 1 < rows && clamp_row_weight(probe, eta, ramp_rows, last_zero + 1) == 0.0) ++last_zero;
  // Rows 0..k are zero, so the interpolated table is exactly zero for theta <= theta_k. One row of
  // margin: the kernels compute theta and the row coordinate in float, and a theta a rounding error
  // below theta_k must not land in row k's interval with a non-zero slope.
  const int k = last_zero - 1;
  if (k < 1) return 0.0;
  return std::sin(k * (sh::kPi / 2.0) / (rows - 1));
}

// --- receivers -----------------------------------------------------------------------------------

std::size_t ReceiverBuffer::bytes() const {
  return soa.size() * (6 * sizeof(float) + sizeof(std::int32_t)) + receiver.size() * sizeof(std::int32_t) +
         tiles.size() * sizeof(ReceiverTile);
}

ReceiverBuffer make_receivers(const render::GBuffer& coarse, int tile_size) {
  if (tile_size < 1) throw std::invalid_argument("image_splat: tile size " + std::to_string(tile_size) + " must be >= 1");
  const std::size_t npix = static_cast<std::size_t>(coarse.width) * static_cast<std::size_t>(coarse.height);
  if (coarse.width < 0 || coarse.height < 0 || coarse.object.size() != npix || coarse.position.size() != npix ||
      coarse.normal.size() != npix)
    throw std::invalid_argument("image_splat: receiver buffer of " + std::to_string(coarse.width) + "x" +
                                std::to_string(coarse.height) + " pixels has inconsistent planes");
  ReceiverBuffer r;
  r.width = coarse.width;
  r.height = coarse.height;
  r.scale = coarse.scale;
  r.tile_size = tile_size;
  r.tiles_x = (coarse.width + tile_size - 1) / tile_size;
  r.tiles_y = (coarse.height + tile_size - 1) / tile_size;
  r.receiver.assign(npix, -1);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < npix; ++i) hits += coarse.hit(i);
  r.soa.resize(hits);
  r.pixel.resize(hits);
  std::size_t k = 0;
  for (int ty = 0; ty < r.tiles_y; ++ty)
    for (int tx = 0; tx < r.tiles_x; ++tx) {
      ReceiverTile t;
      t.begin = k;
      t.lo = glm::vec3(std::numeric_limits<float>::max());
      t.hi = glm::vec3(-std::numeric_limits<float>::max());
      for (int y = ty * tile_size; y < std::min(coarse.height, (ty + 1) * tile_size); ++y)
        for (int x = tx * tile_size; x < std::min(coarse.width, (tx + 1) * tile_size); ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * coarse.width + x;
          if (!coarse.hit(i)) continue;
          r.soa.set(k, coarse.position[i], coarse.normal[i]);
          r.pixel[k] = static_cast<std::int32_t>(i);
          r.receiver[i] = static_cast<std::int32_t>(k);
          t.lo = glm::min(t.lo, coarse.position[i]);
          t.hi = glm::max(t.hi, coarse.position[i]);
          ++k;
        }
      t.end = k;
      if (t.end > t.begin) r.tiles.push_back(t);
    }
  return r;
}

// --- binning -------------------------------------------------------------------------------------

float influence_radius(float r, double support_alpha) {
  if (!(support_alpha > 0.0)) return std::numeric_limits<float>::infinity();
  return static_cast<float>(r / support_alpha * (1.0 + kInfluenceMargin));
}

bool sphere_meets_box(const glm::vec3& c, float radius, const glm::vec3& lo, const glm::vec3& hi) {
  if (std::isinf(radius)) return true;
  const glm::vec3 q = glm::clamp(c, lo, hi);
  const glm::vec3 d = c - q;
  return glm::dot(d, d) <= radius * radius;
}

void flat_proxies(const scene::Scene& scene, const scene::PosedScene& posed, int order, BlockerList* shadow,
                  ProxyList* indirect) {
  if (shadow) *shadow = BlockerList{order, {}, {}, {}, {}, {}};
  if (indirect) *indirect = ProxyList{};
  for (std::size_t s = 0; s < posed.proxies.size(); ++s) {
    const scene::ProxySet* set = s < scene.proxies.size() ? &scene.proxies[s] : nullptr;
    for (std::size_t k = 0; k < posed.proxies[s].size(); ++k) {
      const scene::Sphere& sp = posed.proxies[s][k];
      if (shadow) shadow->push(sp.center, sp.radius, nullptr);
      if (indirect) indirect->push(sp.center, sp.radius, set ? set->albedo_of(k) : glm::vec3(0.8f));
    }
  }
}

ProxyBins bin_proxies(const ReceiverBuffer& rec, const BlockerList& all_shadow, double alpha_shadow,
                      const ProxyList* all_indirect, double alpha_indirect) {
  ProxyBins b;
  const std::size_t nt = rec.tiles.size();
  b.shadow.assign(nt, BlockerList{all_shadow.order, {}, {}, {}, {}, {}});
  if (all_indirect) b.indirect.assign(nt, ProxyList{});
  std::vector<float> rs(all_shadow.size()), ri(all_indirect ? all_indirect->size() : 0);
  for (std::size_t p = 0; p < rs.size(); ++p) rs[p] = influence_radius(all_shadow.r[p], alpha_shadow);
  for (std::size_t p = 0; p < ri.size(); ++p) ri[p] = influence_radius(all_indirect->r[p], alpha_indirect);
  for (std::size_t t = 0; t < nt; ++t) {
    const ReceiverTile& tile = rec.tiles[t];
    for (std::size_t p = 0; p < rs.size(); ++p) {
      const glm::vec3 c(all_shadow.cx[p], all_shadow.cy[p], all_shadow.cz[p]);
      if (sphere_meets_box(c, rs[p], tile.lo, tile.hi)) b.shadow[t].push(c, all_shadow.r[p], &all_shadow.w[p * all_shadow.order]);
    }
    for (std::size_t p = 0; p < ri.size(); ++p) {
      const glm::vec3 c(all_indirect->cx[p], all_indirect->cy[p], all_indirect->cz[p]);
      if (sphere_meets_box(c, ri[p], tile.lo, tile.hi)) b.indirect[t].push(c, all_indirect->r[p], all_indirect->albedo[p]);
    }
    b.pairs_tested += static_cast<double>(rs.size() + ri.size());
    b.shadow_tile_pairs += static_cast<double>(b.shadow[t].size());
    if (all_indirect) b.indirect_tile_pairs += static_cast<double>(b.indirect[t].size());
  }
  return b;
}

std::size_t ProxyBins::bytes() const {
  std::size_t n = 0;
  for (const auto& l : shadow) n += l.bytes();
  for (const auto& l : indirect) n += l.size() * 7 * sizeof(float);
  return n;
}

// --- accumulation --------------------------------------------------------------------------------

float pair_cut_factor(const ShadowTables& t, common::ReplacementRule rule) {
  // The SHEXP kernel has no per-pair cut; it serves every case where the table itself is zero outside
  // the sphere of influence. Two cases need the cut per pair, as splatting (Figure 3) does: a hard cut
  // (smooth_clamp = false, the unclamped table), and the printed replacement rule, whose scale factor
  // grows without bound and can give a far receiver a sphere larger than the proxy (shexp_internal.hpp).
  if (!(t.eta_shadow > 0.0) || !(t.hard_cut || rule == common::ReplacementRule::Printed)) return 0.0f;
  if (t.hard_cut) return static_cast<float>(t.eta_shadow);
  return reach_factor(t.support_alpha_shadow);
}

float reach_factor(double support_alpha) {
  // influence_radius(r, alpha) / r; no support bound: nothing to cut.
  return support_alpha > 0.0 ? static_cast<float>(1.0 / support_alpha * (1.0 + kInfluenceMargin)) : 0.0f;
}

void accumulate_log_range(const ShadowTables& t, common::ReplacementRule rule, common::KernelIsa isa, const ReceiverSoA& rec,
                          std::size_t begin, std::size_t end, const BlockerList& list, float* out) {
  const float cut_factor = pair_cut_factor(t, rule);
  if (cut_factor == 0.0f) {
    common::accumulate_log(isa, t.log, rule, rec, begin, end, list, out);
    return;
  }
  const int n2 = t.order * t.order;
  std::array<float, sh::kMaxCoeffs> v{};
  for (std::size_t i = begin; i < end; ++i) {
    const glm::vec3 p(rec.px[i], rec.py[i], rec.pz[i]), nrm(rec.nx[i], rec.ny[i], rec.nz[i]);
    float* o = out + i * n2;
    for (std::size_t b = 0; b < list.size(); ++b) {
      const glm::vec3 c(list.cx[b], list.cy[b], list.cz[b]);
      if (!(glm::length(c - p) < cut_factor * list.r[b])) continue;
      const common::AdjustedSphere a = common::apply_replacement_rule(rule, p, nrm, c, list.r[b]);
      if (!(a.radius > 0.0f)) continue;
      common::sphere_zh_vector(t.log, p, a.center, a.radius, &list.w[b * list.order], v.data());
      for (int k = 0; k < n2; ++k) o[k] += v[k];
    }
  }
}

void exponentiate(const ShadowTables& t, ExpMode mode, int ps_degree, common::KernelIsa isa, const float* f, float* g,
                  std::size_t count, std::size_t first) {
  sh::ExpOptions opt;
  opt.method = mode == ExpMode::HYB ? sh::ExpMethod::HYB
               : mode == ExpMode::OL ? sh::ExpMethod::OL
               : mode == ExpMode::PSStar ? sh::ExpMethod::PSStar
               : mode == ExpMode::PS ? sh::ExpMethod::PS
                                     : sh::ExpMethod::Exact;
  opt.degree = ps_degree;
  sh::ExpStats stats;
  const int n = t.order, n2 = n * n;
  if (common::exp_batch_supports(opt.method)) {
    common::BatchExp be;
    be.order = n;
    be.method = opt.method;
    be.degree = opt.degree;
    be.tables = t.sh.get();
    be.plan = &common::ProductPlan::get(n);
    common::exp_batch(isa, be, f, g, count, first, stats);
  } else {
    for (std::size_t i = 0; i < count; ++i) sh::exp<float>(n, f + i * n2, g + i * n2, opt, t.sh.get(), &stats);
  }
}

float indirect_normalisation(float o0, float omega) {
  // Below this summed solid angle (steradians) no proxy reaches the receiver: the indirect sum is 0
  // (or a few float ulps of clamped-table tails) and xi has no meaning; 1 leaves that sum untouched.
  constexpr float kMinOmega = 1e-7f;
  if (!(omega > kMinOmega)) return 1.0f;
  const float s4pi = static_cast<float>(sh::kSqrt4Pi);
  const float xi = (s4pi - o0) / (omega / s4pi);
  if (!std::isfinite(xi)) return 1.0f;
  return std::clamp(xi, 0.0f, 1.0f);
}

// --- shading -------------------------------------------------------------------------------------

DirectShader make_direct_shader(const std::vector<glm::vec3>& env_sh, int order, double window_h,
                                std::shared_ptr<const common::LightLobeTable> lt, const std::vector<scene::SphericalLight>& lights,
                                common::KernelIsa isa) {
  DirectShader d;
  d.order = order;
  const int n2 = order * order;
  if (static_cast<int>(env_sh.size()) < n2)
    throw std::invalid_argument("image_splat: environment SH of " + std::to_string(env_sh.size()) + " coefficients for order " +
                                std::to_string(order));
  d.L.assign(3 * static_cast<std::size_t>(n2), 0.0f);
  d.hcoef.assign(n2, 0.0f);
  d.gwin.assign(n2, 1.0f);
  const std::vector<double> cc = sh::clamped_cosine_zh(order);
  for (int l = 0; l < order; ++l) {
    // Paper 004 section 7: the cosine window on the light and the visibility (SHEXP's defaults), so
    // that both techniques shade with the same light.
    const float w = window_h > 0.0 ? static_cast<float>(sh::window_factor(l, window_h)) : 1.0f;
    for (int m = -l; m <= l; ++m) {
      const int k = sh::index(l, m);
      d.hcoef[k] = static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / sh::kPi);
      d.gwin[k] = w;
      for (int c = 0; c < 3; ++c) d.L[static_cast<std::size_t>(c) * n2 + k] = env_sh[k][c] * w;
    }
  }
  d.lights_table = std::move(lt);
  d.lights = lights;
  d.isa = isa;
  return d;
}

common::BatchShade DirectShader::batch(const float* g) const {
  return common::BatchShade::make(order, L.data(), hcoef.data(), gwin.data(), g);
}

long long DirectShader::shade(const ReceiverSoA& rec, std::size_t begin, std::size_t end, const float* g, glm::vec3* out) const {
  const common::BatchShade bs = batch(g);
  // Eq. 10's first term: (H(N) * O) . L per channel = O . L~(N) by the triple-product identity.
  common::shade_batch(isa, bs, rec, begin, end, out);
  return common::add_lights_and_clamp(isa, lights_table.get(), lights, order, gwin.data(), rec, begin, end, g, true, out);
}

long long DirectShader::shade(const ReceiverSoA& rec, std::size_t begin, std::size_t end, const common::BatchShade::Taps& taps,
                              const common::ShadeTransfer* transfer, glm::vec3* out) const {
  if (shades_lights() && !taps.out)
    throw std::logic_error("image_splat: spherical lights with interpolated visibility need it written out");
  if (shades_lights() && transfer && !transfer->carries_visibility)
    throw std::logic_error("image_splat: spherical lights read O_p, which these transfer rows do not carry");
  common::BatchShade bs = batch(nullptr);
  bs.taps = &taps;
  bs.transfer = transfer;
  common::shade_batch(isa, bs, rec, begin, end, out);
  return common::add_lights_and_clamp(isa, lights_table.get(), lights, order, gwin.data(), rec, begin, end, taps.out, true, out);
}

std::vector<glm::vec3> irradiance_sh(const std::vector<glm::vec3>& env_sh, int order) {
  const int n2 = order * order;
  if (static_cast<int>(env_sh.size()) < n2)
    throw std::invalid_argument("image_splat: environment SH of " + std::to_string(env_sh.size()) + " coefficients for order " +
                                std::to_string(order));
  std::vector<glm::vec3> out(n2);
  std::vector<float> in(n2), res(n2);
  for (int c = 0; c < 3; ++c) {
    for (int k = 0; k < n2; ++k) in[k] = env_sh[k][c];
    sh::irradiance_env<float>(order, in.data(), res.data());
    for (int k = 0; k < n2; ++k) out[k][c] = res[k];
  }
  return out;
}

std::size_t Upsampled::bytes() const {
  return w.bytes() + (coarse_visibility.size() + indirect.size()) * sizeof(float) + surface.size() * sizeof(std::int32_t);
}

}  // namespace softgi::techniques::image_splat
