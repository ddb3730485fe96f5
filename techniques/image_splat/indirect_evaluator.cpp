// Paper 000 section 5: per receiver-proxy indirect radiance I_i . H(N) (the summand of eq. 10's
// second term before the eq. 12 normalisation) and the proxy solid angle omega_i (eq. 2), for the
// point-sampled (eq. 13), averaged (eq. 15) and exact (eqs. 16-17) operators.
#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/sh/rotation.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"
#include "splat_math.hpp"

namespace softgi::techniques::image_splat {

namespace {
using sh::kPi;
constexpr int kMaxN = common::kMaxOrder;  // 6
constexpr int kMaxN2 = kMaxN * kMaxN;
constexpr int kRampRows = 4;  // section 4.1: "the 4 table entries around 1/eta"

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("image_splat::IndirectEvaluator: " + what); }
}  // namespace

struct IndirectEvaluator::Impl {
  IndirectSetup setup;
  int n = 0, n2 = 0, rows = 0;
  float scale = 0.0f;         // theta -> row coordinate (the ZhTable's)
  float lt[kMaxN2 * 3] = {};  // L~, coefficient-major: lt[3 k + c]
  common::ZhTable vis;         // F_l = sqrt(4pi/(2l+1)) V_l of the proxy's own visibility (clamped if asked)
  // V . H(N) = sum_l F_l vh_l P_l(d . N) (addition theorem: sum_m y_lm(d) y_lm(N) = (2l+1)/(4pi) P_l),
  // vh_l = (g_cos,l / pi) sqrt((2l+1)/(4pi)).
  float vh[kMaxN] = {};
  // Averaged: per row the n factors sqrt(4pi/(2l+1)) D_l (eq. 8 folded in), so that
  // kappa = sum_l dfac_l sum_m y_lm(d) L~_lm (eq. 15).
  std::vector<float> dfac;
  common::ZhTable dtab;  // dfac in ZhTable layout (value, slope per row) for the batched kernel
  // Exact: per row the m-blocks of M (block-diagonal in m: same m, same sign), block m holds
  // M_(l,m),(l',m) for l, l' in |m|..n-1, row-major; offsets per m + n - 1. Rows pre-multiplied by
  // the clamp weight (M carries the visibility of the proxy itself).
  std::vector<float> mtab;
  std::array<int, 2 * kMaxN> moff{};
  int mrow = 0;  // floats per row
  // Rot(Q), Q = Rx(-90 deg) (takes +z to +y), band blocks: with Rz cheap, Ry(a) = Q Rz(a) Q^T.
  std::vector<float> qrot;
  std::array<int, kMaxN> qoff{};
  float hc[kMaxN] = {};  // H(N)_lm = hc_l y_lm(N): sqrt(4pi/(2l+1)) g_cos,l / pi

  // One pair: returns per-channel I . H(N) without albedo / pi; theta row coordinate u.
  void pair(const glm::vec3& dir, const glm::vec3& nrm, float u, float* out) const;
};

namespace {
// Rotation about z by angle a of the function (f'(phi) = f(phi - a)): for m > 0, A = f_lm (cos m phi),
// B = f_l,-m (sin m phi): A' = A cos(ma) - B sin(ma), B' = A sin(ma) + B cos(ma). cm[m], sm[m] are
// cos(ma), sin(ma).
inline void rotate_z(int n, const float* cm, const float* sm, float* f) {
  for (int l = 1; l < n; ++l)
    for (int m = 1; m <= l; ++m) {
      float& A = f[sh::index(l, m)];
      float& B = f[sh::index(l, -m)];
      const float a = A, b = B;
      A = a * cm[m] - b * sm[m];
      B = a * sm[m] + b * cm[m];
    }
}
// out = blocks f (transpose: out = blocks^T f), per band.
inline void apply_blocks(int n, const float* blocks, const int* off, bool transpose, const float* f, float* out) {
  for (int l = 0; l < n; ++l) {
    const int w = 2 * l + 1, base = l * l;
    const float* b = blocks + off[l];
    for (int i = 0; i < w; ++i) {
      float s = 0.0f;
      for (int j = 0; j < w; ++j) s += (transpose ? b[j * w + i] : b[i * w + j]) * f[base + j];
      out[base + i] = s;
    }
  }
}
inline void multiples(int n, float c, float s, float* cm, float* sm) {
  cm[0] = 1.0f;
  sm[0] = 0.0f;
  for (int m = 1; m < n; ++m) {
    cm[m] = cm[m - 1] * c - sm[m - 1] * s;
    sm[m] = sm[m - 1] * c + cm[m - 1] * s;
  }
}
}  // namespace

void IndirectEvaluator::Impl::pair(const glm::vec3& d, const glm::vec3& N, float u, float* out) const {
  int k = std::min(static_cast<int>(std::min(u, static_cast<float>(rows - 1))), rows - 2);
  if (k < 0) k = 0;
  const float fr = u - static_cast<float>(k);
  const IndirectOperator op = setup.op;
  if (op != IndirectOperator::Exact) {
    // V . H(N) from the (clamped) visibility table.
    float F[kMaxN];
    const float* row = vis.data.data() + static_cast<std::size_t>(k) * 2 * n;
    for (int l = 0; l < n; ++l) F[l] = row[2 * l] + fr * row[2 * l + 1];
    const float t = std::clamp(d.x * N.x + d.y * N.y + d.z * N.z, -1.0f, 1.0f);
    float p0 = 1.0f, p1 = t, vdoth = F[0] * vh[0] + (n > 1 ? F[1] * vh[1] * t : 0.0f);
    for (int l = 2; l < n; ++l) {
      const float p2 = ((2 * l - 1) * t * p1 - (l - 1) * p0) / static_cast<float>(l);
      vdoth += F[l] * vh[l] * p2;
      p0 = p1;
      p1 = p2;
    }
    // B_l = sum_m y_lm(d) L~_lm, per channel.
    float y[kMaxN2];
    sh::eval_basis(n, sh::Vec3<float>{d.x, d.y, d.z}, y);
    float fac[kMaxN];
    if (op == IndirectOperator::PointSampled) {
      // eq. 13: L~(-d) = sum_lm L~_lm y_lm(-d), y_lm(-d) = (-1)^l y_lm(d).
      for (int l = 0; l < n; ++l) fac[l] = (l & 1) ? -1.0f : 1.0f;
    } else {
      // eq. 15: kappa = rot(D(theta), d) . L~.
      const float* d0 = dfac.data() + static_cast<std::size_t>(k) * n;
      const float* d1 = d0 + n;
      for (int l = 0; l < n; ++l) fac[l] = d0[l] + fr * (d1[l] - d0[l]);
    }
    float kap[3] = {0, 0, 0};
    for (int l = 0; l < n; ++l) {
      float b[3] = {0, 0, 0};
      for (int i = l * l; i < (l + 1) * (l + 1); ++i)
        for (int c = 0; c < 3; ++c) b[c] += y[i] * lt[3 * i + c];
      for (int c = 0; c < 3; ++c) kap[c] += fac[l] * b[c];
    }
    for (int c = 0; c < 3; ++c) out[c] = kap[c] * vdoth;
    return;
  }
  // eq. 17: I = R^-1 M(theta) R L~ with R taking d to +z; I . H(N) = (M R L~) . (R H(N)) since R is
  // orthogonal, and R H(N) = H(R N) (H is zonal about N). M commutes with rotations about z, so any
  // such R works: R = Ry(-beta) Rz(-phi), d = (sin beta cos phi, sin beta sin phi, cos beta), and
  // Ry(a) = Q Rz(a) Q^T with the fixed Q = Rx(-90 deg).
  const float rho = std::sqrt(d.x * d.x + d.y * d.y);
  const float cphi = rho > 1e-12f ? d.x / rho : 1.0f, sphi = rho > 1e-12f ? d.y / rho : 0.0f;
  const float cb = d.z, sb = rho;
  float cmp[kMaxN], smp[kMaxN], cmb[kMaxN], smb[kMaxN];
  multiples(n, cphi, -sphi, cmp, smp);  // angle -phi
  multiples(n, cb, -sb, cmb, smb);      // angle -beta
  // N' = R N.
  const float x1 = cphi * N.x + sphi * N.y, y1 = -sphi * N.x + cphi * N.y, z1 = N.z;
  const sh::Vec3<float> np{cb * x1 - sb * z1, y1, sb * x1 + cb * z1};
  float hp[kMaxN2];
  sh::eval_basis(n, np, hp);
  for (int l = 0; l < n; ++l)
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) hp[i] *= hc[l];
  // Interpolated M blocks.
  float Mi[2 * kMaxN * kMaxN * kMaxN];
  const float* m0 = mtab.data() + static_cast<std::size_t>(k) * mrow;
  const float* m1 = m0 + mrow;
  for (int i = 0; i < mrow; ++i) Mi[i] = m0[i] + fr * (m1[i] - m0[i]);
  for (int c = 0; c < 3; ++c) {
    float f[kMaxN2], g[kMaxN2];
    for (int i = 0; i < n2; ++i) f[i] = lt[3 * i + c];
    rotate_z(n, cmp, smp, f);
    apply_blocks(n, qrot.data(), qoff.data(), true, f, g);
    rotate_z(n, cmb, smb, g);
    apply_blocks(n, qrot.data(), qoff.data(), false, g, f);  // f = R L~
    float s = 0.0f;
    for (int m = -(n - 1); m <= n - 1; ++m) {
      const int am = std::abs(m), w = n - am;
      const float* B = Mi + moff[m + n - 1];
      for (int a = 0; a < w; ++a) {
        float r = 0.0f;
        for (int b = 0; b < w; ++b) r += B[a * w + b] * f[sh::index(am + b, m)];
        s += hp[sh::index(am + a, m)] * r;
      }
    }
    out[c] = s;
  }
}

IndirectEvaluator::IndirectEvaluator(const IndirectSetup& setup, const std::vector<glm::vec3>& ltilde)
    : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.setup = setup;
  const int n = setup.order;
  if (n < common::kMinOrder || n > common::kMaxOrder)
    fail("order " + std::to_string(n) + " is outside " + std::to_string(common::kMinOrder) + ".." +
         std::to_string(common::kMaxOrder));
  if (setup.op == IndirectOperator::AveragedPolynomial && n != 3)
    fail("the paper's polynomial D (averaged_poly) exists for order 3 only, got order " + std::to_string(n));
  if (setup.table_resolution < 16 || setup.table_resolution > 65536)
    fail("table_resolution = " + std::to_string(setup.table_resolution) + " is outside 16..65536");
  if (std::isnan(setup.eta)) fail("eta is NaN");
  im.n = n;
  im.n2 = n * n;
  if (static_cast<int>(ltilde.size()) != im.n2)
    fail("L~ has " + std::to_string(ltilde.size()) + " coefficients, order " + std::to_string(n) + " needs " +
         std::to_string(im.n2));
  for (int i = 0; i < im.n2; ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = ltilde[static_cast<std::size_t>(i)][c];
      if (!std::isfinite(v)) fail("L~ coefficient " + std::to_string(i) + " channel " + std::to_string(c) + " is not finite");
      im.lt[3 * i + c] = v;
    }

  const int rows = setup.table_resolution;
  im.rows = rows;
  sh::Table1D vt;
  vt.param = sh::TableParam::Theta;
  vt.width = n;
  for (int k = 0; k < rows; ++k) {
    const double th = (sh::kPi / 2) * k / (rows - 1);
    vt.x.push_back(th);
    std::vector<double> g = sh::cap_visibility_zh(n, th);
    // Proxy visibility V = 1 - (environment visibility): the paper's V_i (eq. 3), O_i = 1 - V_i.
    vt.data.push_back(sh::kSqrt4Pi - g[0]);
    for (int l = 1; l < n; ++l) vt.data.push_back(-g[l]);
  }
  common::ZhTable raw = common::make_zh_table(vt, n, true);  // row 0: empty cap, exactly 0
  im.scale = raw.scale;
  const bool clamp = setup.smooth_clamp && setup.eta > 1.0 && std::isfinite(setup.eta);
  im.vis = clamp ? clamp_zh_table(raw, setup.eta, kRampRows) : raw;

  const std::vector<double> gcos = sh::clamped_cosine_zh(n);
  for (int l = 0; l < n; ++l) {
    im.vh[l] = static_cast<float>(gcos[l] / kPi * std::sqrt((2.0 * l + 1.0) / (4.0 * kPi)));
    im.hc[l] = static_cast<float>(sh::zh_rotation_factor(l) * gcos[l] / kPi);
  }

  if (setup.op == IndirectOperator::AveragedExact || setup.op == IndirectOperator::AveragedPolynomial) {
    im.dfac.resize(static_cast<std::size_t>(rows) * n);
    for (int k = 0; k < rows; ++k) {
      const double a = std::min(1.0, std::sin(vt.x[static_cast<std::size_t>(k)]));
      std::vector<double> D;
      if (setup.op == IndirectOperator::AveragedPolynomial) {
        const auto p = sh::indirect_D_polynomial(a);  // section 5's fit
        D.assign(p.begin(), p.end());
      } else {
        D = sh::indirect_D_quadrature(n, a);  // eq. 14
      }
      for (int l = 0; l < n; ++l)
        im.dfac[static_cast<std::size_t>(k) * n + l] = static_cast<float>(sh::zh_rotation_factor(l) * D[l]);
    }
    common::ZhTable& dt = im.dtab;
    dt.order = n;
    dt.rows = rows;
    dt.scale = im.scale;
    dt.data.assign(static_cast<std::size_t>(rows) * 2 * n, 0.0f);
    dt.band.assign(dt.data.size(), 0.0f);
    for (int k = 0; k < rows; ++k)
      for (int l = 0; l < n; ++l) {
        const float v = im.dfac[static_cast<std::size_t>(k) * n + l];
        const float slope = k + 1 < rows ? im.dfac[static_cast<std::size_t>(k + 1) * n + l] - v : 0.0f;
        dt.data[static_cast<std::size_t>(k) * 2 * n + 2 * l] = v;
        dt.data[static_cast<std::size_t>(k) * 2 * n + 2 * l + 1] = slope;
        dt.band[static_cast<std::size_t>(l) * 2 * rows + k] = v;
        dt.band[static_cast<std::size_t>(l) * 2 * rows + rows + k] = slope;
      }
  }
  if (setup.op == IndirectOperator::Exact) {
    int off = 0;
    for (int m = -(n - 1); m <= n - 1; ++m) {
      im.moff[m + n - 1] = off;
      off += (n - std::abs(m)) * (n - std::abs(m));
    }
    im.mrow = off;
    im.mtab.resize(static_cast<std::size_t>(rows) * off);
    for (int k = 0; k < rows; ++k) {
      const double a = std::min(1.0, std::sin(vt.x[static_cast<std::size_t>(k)]));
      const std::vector<double> M = sh::indirect_M(n, a);  // eq. 16
      const double w = clamp ? clamp_row_weight(raw, setup.eta, kRampRows, k) : 1.0;
      float* dst = im.mtab.data() + static_cast<std::size_t>(k) * off;
      for (int m = -(n - 1); m <= n - 1; ++m) {
        const int am = std::abs(m), wd = n - am;
        for (int a2 = 0; a2 < wd; ++a2)
          for (int b = 0; b < wd; ++b)
            dst[im.moff[m + n - 1] + a2 * wd + b] = static_cast<float>(
                w * M[static_cast<std::size_t>(sh::index(am + a2, m)) * im.n2 + sh::index(am + b, m)]);
      }
    }
    const sh::ShRotation q(n, sh::rotation_from_axis_angle(sh::Vec3<double>{1, 0, 0}, -sh::kPi / 2));
    int qo = 0;
    for (int l = 0; l < n; ++l) {
      im.qoff[l] = qo;
      const int w = 2 * l + 1;
      for (int i = 0; i < w * w; ++i) im.qrot.push_back(static_cast<float>(q.band(l)[i]));
      qo += w * w;
    }
  }
}

const IndirectSetup& IndirectEvaluator::setup() const { return impl_->setup; }

namespace {
void check_inputs(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end, const ProxyList& list) {
  if (begin > end || end > rec.size())
    fail("receiver range [" + std::to_string(begin) + ", " + std::to_string(end) + ") exceeds " +
         std::to_string(rec.size()) + " receivers");
  const std::size_t np = list.size();
  if (list.cx.size() != np || list.cy.size() != np || list.cz.size() != np || list.albedo.size() != np)
    fail("ProxyList arrays differ in length");
  for (std::size_t p = 0; p < np; ++p)
    if (!std::isfinite(list.cx[p]) || !std::isfinite(list.cy[p]) || !std::isfinite(list.cz[p]) ||
        !std::isfinite(list.r[p]) || !(list.r[p] >= 0.0f) || !std::isfinite(list.albedo[p].x) ||
        !std::isfinite(list.albedo[p].y) || !std::isfinite(list.albedo[p].z))
      fail("proxy " + std::to_string(p) + " has a non-finite centre, radius or albedo, or a negative radius");
}
}  // namespace

bool IndirectEvaluator::batched() const {
  const IndirectSetup& s = impl_->setup;
  // The batched kernel's cut is sin theta > 1/eta, which needs eta > 1; an eta in (0, 1] (every
  // proxy that does not contain the receiver is cut) stays with the per-pair path.
  return s.op != IndirectOperator::Exact && (s.eta <= 0.0 || s.eta > 1.0);
}

long long IndirectEvaluator::accumulate(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end,
                                        const ProxyList& list, float* rgb, float* omega, common::KernelIsa isa) const {
  if (batched()) return accumulate_batched(isa, rec, begin, end, list, rgb, omega);
  return accumulate_pairwise(rec, begin, end, list, rgb, omega);
}

long long IndirectEvaluator::accumulate_batched(common::KernelIsa isa, const common::ReceiverSoA& rec, std::size_t begin,
                                                std::size_t end, const ProxyList& list, float* rgb, float* omega) const {
  const Impl& im = *impl_;
  if (!batched()) fail(std::string("the batched kernel does not evaluate the ") + to_string(im.setup.op) + " operator");
  check_inputs(rec, begin, end, list);
  if (begin == end || list.size() == 0) return 0;
  if (!rgb || !omega) fail("null output buffer");
  common::ProxyLightTables t;
  t.vis = &im.vis;
  t.band_factor = im.setup.op == IndirectOperator::PointSampled ? nullptr : &im.dtab;
  t.ltilde = im.lt;
  t.vh = im.vh;
  t.rule = im.setup.rule;
  // An infinite eta or reach admits every pair, as no cut and no reach test do (a radius-0 proxy,
  // which the per-pair path's inf * 0 = NaN comparison drops, has sin theta = 0 and is dropped too).
  t.eta = im.setup.eta > 0.0 && std::isfinite(im.setup.eta) ? static_cast<float>(im.setup.eta) : 0.0f;
  t.reach = im.setup.reach > 0.0 && std::isfinite(im.setup.reach) ? static_cast<float>(im.setup.reach) : 0.0f;
  common::ProxyLightList l;
  l.cx = list.cx.data();
  l.cy = list.cy.data();
  l.cz = list.cz.data();
  l.r = list.r.data();
  l.albedo = list.albedo.data();
  l.count = list.size();
  return common::accumulate_proxy_lights(isa, t, rec, begin, end, l, rgb, omega);
}

long long IndirectEvaluator::accumulate_pairwise(const common::ReceiverSoA& rec, std::size_t begin, std::size_t end,
                                                 const ProxyList& list, float* rgb, float* omega) const {
  const Impl& im = *impl_;
  check_inputs(rec, begin, end, list);
  const std::size_t np = list.size();
  if (begin == end || np == 0) return 0;
  if (!rgb || !omega) fail("null output buffer");
  const float eta = static_cast<float>(im.setup.eta);
  const bool cut = im.setup.eta > 0.0;
  const float reach = static_cast<float>(im.setup.reach);
  const float inv_pi = static_cast<float>(1.0 / kPi);
  long long pairs = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const glm::vec3 p{rec.px[i], rec.py[i], rec.pz[i]};
    const glm::vec3 N{rec.nx[i], rec.ny[i], rec.nz[i]};
    float acc[3] = {0, 0, 0}, om = 0.0f;
    for (std::size_t j = 0; j < np; ++j) {
      const glm::vec3 c{list.cx[j], list.cy[j], list.cz[j]};
      if (reach > 0.0f && !(glm::length(c - p) < reach * list.r[j])) continue;
      // Self-shadowing replacement rules (paper 004 section 6.2), as in the shadow pass.
      const common::AdjustedSphere s = common::apply_replacement_rule(im.setup.rule, p, N, c, list.r[j]);
      if (!(s.radius > 0.0f)) continue;
      const glm::vec3 dv = s.center - p;
      const float dist = std::sqrt(dv.x * dv.x + dv.y * dv.y + dv.z * dv.z);
      if (!(dist > 0.0f)) continue;
      if (cut && dist >= eta * s.radius) continue;  // outside the sphere of influence (section 4.1)
      ++pairs;
      const float alpha = std::min(1.0f, s.radius / dist);  // eq. 1
      const float u = std::asin(alpha) * im.scale;
      const glm::vec3 d = dv / dist;
      // omega_i = sqrt(4pi) V_i,0 = F_0 (y_00 = 1/sqrt(4pi)), eq. 2 through the DC term.
      {
        int k = std::min(static_cast<int>(std::min(u, static_cast<float>(im.rows - 1))), im.rows - 2);
        const float* row = im.vis.data.data() + static_cast<std::size_t>(k) * 2 * im.n;
        om += row[0] + (u - static_cast<float>(k)) * row[1];
      }
      float c3[3];
      im.pair(d, N, u, c3);
      const glm::vec3& a = list.albedo[j];
      acc[0] += a.x * inv_pi * c3[0];  // diffuse proxy: radiance albedo / pi L~
      acc[1] += a.y * inv_pi * c3[1];
      acc[2] += a.z * inv_pi * c3[2];
    }
    rgb[3 * i + 0] += acc[0];
    rgb[3 * i + 1] += acc[1];
    rgb[3 * i + 2] += acc[2];
    omega[i] += om;
  }
  return pairs;
}

IndirectEvaluator::TableView IndirectEvaluator::tables() const {
  const Impl& im = *impl_;
  TableView v;
  v.order = im.n;
  v.rows = im.rows;
  v.scale = im.scale;
  v.ltilde = std::span<const float>(im.lt, static_cast<std::size_t>(3 * im.n2));
  v.vis = im.vis.data;
  v.vh = std::span<const float>(im.vh, static_cast<std::size_t>(im.n));
  v.dfac = im.dfac;
  if (im.setup.op == IndirectOperator::Exact) {
    v.mtab = im.mtab;
    v.moff = std::span<const int>(im.moff.data(), static_cast<std::size_t>(2 * im.n - 1));
    v.mrow = im.mrow;
    v.qrot = im.qrot;
    v.qoff = std::span<const int>(im.qoff.data(), static_cast<std::size_t>(im.n));
    v.hc = std::span<const float>(im.hc, static_cast<std::size_t>(im.n));
  }
  return v;
}

std::size_t IndirectEvaluator::bytes() const {
  const Impl& im = *impl_;
  return sizeof(Impl) + im.vis.bytes() + im.dtab.bytes() + (im.dfac.size() + im.mtab.size() + im.qrot.size()) * sizeof(float);
}

IndirectEvaluator::~IndirectEvaluator() = default;
IndirectEvaluator::IndirectEvaluator(IndirectEvaluator&&) noexcept = default;
IndirectEvaluator& IndirectEvaluator::operator=(IndirectEvaluator&&) noexcept = default;

}  // namespace softgi::techniques::image_splat
