// The CPU pieces of the image-space technique's passes (techniques/image_splat/image_splat_internal.hpp):
// receivers in tile order, tile binning against the full proxy list (the coverage oracle must not
// change a single sum), the support of the clamped tables, and the eq. 12 normalisation's bounds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "../../techniques/image_splat/image_splat_internal.hpp"

using namespace softgi;
using namespace softgi::techniques;
using namespace softgi::techniques::image_splat;

namespace {

// A coarse receiver buffer seeing a wavy ground: z = 0.15 sin(x) cos(y), normals from the
// gradient; every 7th pixel background.
render::GBuffer wavy_buffer(int w, int h, float extent) {
  render::GBuffer gb;
  gb.width = w;
  gb.height = h;
  gb.scale = 2;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  gb.position.assign(n, glm::vec3(0.0f));
  gb.normal.assign(n, glm::vec3(0.0f));
  gb.depth.assign(n, std::numeric_limits<float>::infinity());
  gb.object.assign(n, -1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (i % 7 == 3) continue;
      const float px = extent * (x / float(w - 1) - 0.5f), pz = extent * (y / float(h - 1) - 0.5f);
      const float py = 0.15f * std::sin(px) * std::cos(pz);
      gb.position[i] = {px, py, pz};
      gb.normal[i] = glm::normalize(glm::vec3(-0.15f * std::cos(px) * std::cos(pz), 1.0f, 0.15f * std::sin(px) * std::sin(pz)));
      gb.depth[i] = 5.0f + pz;
      gb.object[i] = 0;
    }
  return gb;
}

// Random proxies above (and a few straddling) the ground, radii 0.05..0.3.
void random_proxies(unsigned seed, int count, float extent, techniques::common::BlockerList& shadow, ProxyList& ind, int order) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  shadow = techniques::common::BlockerList{order, {}, {}, {}, {}, {}};
  ind = ProxyList{};
  for (int k = 0; k < count; ++k) {
    const glm::vec3 c(extent * (u(rng) - 0.5f), 0.6f * u(rng) - 0.05f, extent * (u(rng) - 0.5f));
    const float r = 0.05f + 0.25f * u(rng);
    shadow.push(c, r, nullptr);
    ind.push(c, r, glm::vec3(0.3f + 0.6f * u(rng), 0.5f, 0.9f * u(rng)));
  }
}

// The order-4 tables, built once (the log tables take seconds in a sanitizer build).
const std::shared_ptr<const sh::ShTables>& order4_tables() {
  static const std::shared_ptr<const sh::ShTables> t = [] {
    sh::TableOptions opt;
    opt.order = 4;
    opt.resolution = 256;
    opt.measure_error = false;
    return std::make_shared<const sh::ShTables>(opt);
  }();
  return t;
}

ShadowTables make_tables(double eta, bool smooth) {
  const int order = 4;
  ShadowTables t;
  t.order = order;
  t.sh = order4_tables();
  const techniques::common::ZhTable log = techniques::common::make_zh_table(t.sh->cap_log(), order, true);
  t.eta_shadow = eta;
  if (smooth) {
    t.log = clamp_zh_table(log, eta, kClampRampRows);
    t.support_alpha_shadow = clamped_support_alpha(256, eta, kClampRampRows);
  } else {
    t.log = log;
    t.hard_cut = true;
    t.support_alpha_shadow = 1.0 / eta;
  }
  return t;
}

}  // namespace

TEST(ImageSplatReceivers, TileOrderCoversEveryHitOnce) {
  const render::GBuffer gb = wavy_buffer(37, 23, 6.0f);
  const ReceiverBuffer r = make_receivers(gb, 8);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) hits += gb.hit(i);
  ASSERT_EQ(r.soa.size(), hits);
  EXPECT_EQ(r.tiles_x, 5);
  EXPECT_EQ(r.tiles_y, 3);
  std::size_t expect_begin = 0;
  for (const ReceiverTile& t : r.tiles) {
    EXPECT_EQ(t.begin, expect_begin);
    expect_begin = t.end;
    for (std::size_t k = t.begin; k < t.end; ++k) {
      const glm::vec3 p(r.soa.px[k], r.soa.py[k], r.soa.pz[k]);
      EXPECT_TRUE(glm::all(glm::lessThanEqual(t.lo, p)) && glm::all(glm::lessThanEqual(p, t.hi)));
      EXPECT_EQ(r.receiver[r.pixel[k]], static_cast<std::int32_t>(k));
      EXPECT_EQ(p, gb.position[r.pixel[k]]);
      // A tile holds the pixels of one 8 x 8 block.
      const int x = r.pixel[k] % gb.width, y = r.pixel[k] / gb.width;
      const int x0 = r.pixel[t.begin] % gb.width, y0 = r.pixel[t.begin] / gb.width;
      EXPECT_EQ(x / 8, x0 / 8);
      EXPECT_EQ(y / 8, y0 / 8);
    }
  }
  EXPECT_EQ(expect_begin, hits);
  for (std::size_t i = 0; i < gb.object.size(); ++i) EXPECT_EQ(r.receiver[i] >= 0, gb.hit(i));
}

TEST(ImageSplatBinning, SupportOfTheClampedTableIsWhereItIsExactlyZero) {
  for (double eta : {4.0, 10.0, 15.0, 28.0}) {
    const ShadowTables t = make_tables(eta, true);
    const double a = t.support_alpha_shadow;
    ASSERT_GT(a, 0.0);
    // The sphere of influence is at least the requested one (alpha <= 1/eta) ...
    EXPECT_LE(a, 1.0 / eta);
    // ... and not much more: within the ramp's rows past asin(1/eta).
    const double row = (sh::kPi / 2.0) / 255.0;
    EXPECT_GE(std::asin(a), std::asin(1.0 / eta) - 3.0 * row) << eta;
    std::array<float, 8> v{};
    for (int k = 0; k <= 100; ++k) {
      const float theta = static_cast<float>(std::asin(a) * k / 100.0);
      t.log.lookup(theta, v.data());
      for (int l = 0; l < 4; ++l) EXPECT_EQ(v[l], 0.0f) << "eta " << eta << " theta " << theta;
    }
  }
}

// The coverage oracle as tile binning: every receiver's sum over its tile's list equals the sum over
// the full list. Pairs left out read exactly 0 from the clamped table, and adding 0.0f is exact, so
// the only allowed difference is FMA contraction grouping in the kernel: 1e-6 of the sum's scale.
TEST(ImageSplatBinning, TileBinningEqualsTheFullProxyList) {
  constexpr float kRelTol = 1e-6f;
  const render::GBuffer gb = wavy_buffer(48, 40, 8.0f);
  const ReceiverBuffer r = make_receivers(gb, 16);
  techniques::common::BlockerList all;
  ProxyList all_ind;
  random_proxies(11, 60, 8.0f, all, all_ind, 4);
  for (bool smooth : {true, false})
    for (auto rule : {techniques::common::ReplacementRule::Continuous, techniques::common::ReplacementRule::Printed, techniques::common::ReplacementRule::Off}) {
      const ShadowTables t = make_tables(8.0, smooth);
      const double alpha_ind = clamped_support_alpha(256, 6.0, kClampRampRows);
      const ProxyBins bins = bin_proxies(r, all, t.support_alpha_shadow, &all_ind, alpha_ind);
      // The test means something only if binning drops pairs.
      ASSERT_LT(bins.shadow_tile_pairs, 0.8 * static_cast<double>(r.tiles.size() * all.size()));
      ASSERT_LT(bins.indirect_tile_pairs, bins.shadow_tile_pairs);
      const int n2 = 16;
      std::vector<float> binned(r.soa.size() * n2, 0.0f), full(r.soa.size() * n2, 0.0f);
      for (std::size_t k = 0; k < r.tiles.size(); ++k) {
        accumulate_log_range(t, rule, techniques::common::best_kernel_isa(), r.soa, r.tiles[k].begin, r.tiles[k].end, bins.shadow[k], binned.data());
        accumulate_log_range(t, rule, techniques::common::best_kernel_isa(), r.soa, r.tiles[k].begin, r.tiles[k].end, all, full.data());
      }
      float scale = 0.0f;
      for (float v : full) scale = std::max(scale, std::abs(v));
      ASSERT_GT(scale, 0.1f);
      for (std::size_t i = 0; i < full.size(); ++i)
        ASSERT_NEAR(binned[i], full[i], kRelTol * scale) << "smooth " << smooth << " rule " << techniques::common::to_string(rule) << " at " << i;

      IndirectSetup setup;
      setup.order = 3;
      setup.op = IndirectOperator::Exact;
      setup.eta = 6.0;
      setup.smooth_clamp = smooth;
      setup.rule = rule;
      const double ai = smooth ? alpha_ind : 1.0 / 6.0;
      // The printed rule's adjusted sphere can outgrow the proxy: its pairs are cut at the proxy's
      // sphere of influence (as image_splat's indirect_tables pass sets it), without which the sums
      // would depend on the tiles.
      if (rule == techniques::common::ReplacementRule::Printed) setup.reach = reach_factor(ai);
      std::vector<glm::vec3> ltilde(9, glm::vec3(0.0f));
      ltilde[0] = glm::vec3(3.0f, 2.5f, 2.0f);
      ltilde[2] = glm::vec3(1.5f);
      const IndirectEvaluator ev(setup, ltilde);
      const ProxyBins bi = bin_proxies(r, all, t.support_alpha_shadow, &all_ind, ai);
      std::vector<float> rgb_b(r.soa.size() * 3, 0.0f), om_b(r.soa.size(), 0.0f), rgb_f(rgb_b), om_f(om_b);
      long long in_b = 0, in_f = 0;
      for (std::size_t k = 0; k < r.tiles.size(); ++k) {
        in_b += ev.accumulate(r.soa, r.tiles[k].begin, r.tiles[k].end, bi.indirect[k], rgb_b.data(), om_b.data());
        in_f += ev.accumulate(r.soa, r.tiles[k].begin, r.tiles[k].end, all_ind, rgb_f.data(), om_f.data());
      }
      EXPECT_EQ(in_b, in_f) << "every pair inside a sphere of influence is binned";
      float iscale = 0.0f;
      for (float v : rgb_f) iscale = std::max(iscale, std::abs(v));
      ASSERT_GT(iscale, 0.0f);
      for (std::size_t i = 0; i < rgb_f.size(); ++i) ASSERT_NEAR(rgb_b[i], rgb_f[i], kRelTol * iscale) << i;
      for (std::size_t i = 0; i < om_f.size(); ++i) ASSERT_NEAR(om_b[i], om_f[i], kRelTol * 4.0f * static_cast<float>(sh::kPi)) << i;
    }
}

// Eq. 12: xi = union / sum of solid angles, in [0, 1] for any input; exactly the ratio where that is
// in range; 1 where no proxy reaches the receiver.
TEST(ImageSplatNormalisation, XiIsTheSolidAngleRatioAndStaysInTheUnitInterval) {
  const float s4pi = static_cast<float>(sh::kSqrt4Pi);
  // Two disjoint caps of 0.3 sr each: union = sum, xi = 1; the same cap twice: xi = 1/2.
  EXPECT_NEAR(indirect_normalisation(s4pi - 0.6f / s4pi, 0.6f), 1.0f, 1e-5f);
  EXPECT_NEAR(indirect_normalisation(s4pi - 0.3f / s4pi, 0.6f), 0.5f, 1e-5f);
  EXPECT_EQ(indirect_normalisation(s4pi, 0.0f), 1.0f);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-20.0f, 20.0f);
  for (int k = 0; k < 10000; ++k) {
    const float xi = indirect_normalisation(u(rng), std::abs(u(rng)));
    ASSERT_GE(xi, 0.0f);
    ASSERT_LE(xi, 1.0f);
  }
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    const float xi = indirect_normalisation(bad, 1.0f);
    EXPECT_TRUE(xi >= 0.0f && xi <= 1.0f);
    const float xj = indirect_normalisation(1.0f, bad);
    EXPECT_TRUE(xj >= 0.0f && xj <= 1.0f);
  }
}
