// Receiver-buffer upsampling (paper 000 section 4.2, eq. 11): bilateral weights do not mix across
// depth or normal discontinuities while plain bilinear does, bilinear reproduces affine data, scale 1
// is the identity, misses are flagged exactly where the coarse buffer has no matching sample, the
// fallbacks of the contract, and bad input.
#include <gtest/gtest.h>
#include <iostream>
#include <bit>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "../../techniques/common/tap_pack.hpp"
#include "../../techniques/common/upsample.hpp"

using namespace softgi::techniques::common;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Weights are normalised in float by their float sum (three roundings: ~1.8e-7 relative), and each
// quotient rounds once more (6e-8): a sum of four is within ~4e-7 of 1; 1e-6 leaves room.
constexpr double kSumTol = 1e-6;
// Relative error of a value interpolated with such float weights (and float accumulation of at
// most four products) against the exact weighted mean: a few float ulps; 1e-6 leaves room.
constexpr double kFloatSlack = 1e-6;

struct Surface {
  float depth;
  glm::vec3 normal;
};
using SceneFn = std::function<Surface(double, double)>;  // display point -> receiver plane (or background)

// A receiver buffer sampled from a synthetic scene at its pixel centres, display point
// ((x + 0.5) scale, (y + 0.5) scale), as the G-buffer (one ray per pixel centre) would.
struct Buffer {
  int width = 0, height = 0, scale = 1;
  std::vector<float> depth;
  std::vector<glm::vec3> normal;
  PlaneView view() const { return PlaneView{width, height, scale, depth.data(), normal.data()}; }
  double cx(int x) const { return (x + 0.5) * scale; }
  double cy(int y) const { return (y + 0.5) * scale; }
};

Buffer sample(const SceneFn& scene, int width, int height, int scale) {
  Buffer b;
  b.width = width;
  b.height = height;
  b.scale = scale;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const Surface s = scene(b.cx(x), b.cy(y));
      b.depth.push_back(s.depth);
      b.normal.push_back(s.normal);
    }
  return b;
}

// Per-pixel values of a coarse buffer from a function of the display point.
std::vector<float> coarse_values(const Buffer& c, int channels, const std::function<float(double, double, int)>& f) {
  std::vector<float> v;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x)
      for (int k = 0; k < channels; ++k) v.push_back(f(c.cx(x), c.cy(y), k));
  return v;
}

// Contract of UpsampleWeights for every pixel: background pixels have no taps and are no miss;
// other taps are packed to the front, index a coarse pixel, have weight in (0, 1] and sum to 1.
void expect_well_formed(const UpsampleWeights& w, const Buffer& coarse, const Buffer& fine) {
  ASSERT_EQ(w.width, fine.width);
  ASSERT_EQ(w.height, fine.height);
  const std::size_t n = fine.depth.size();
  ASSERT_EQ(w.index.size(), n);
  ASSERT_EQ(w.weight.size(), n);
  ASSERT_EQ(w.miss.size(), n);
  std::size_t misses = 0;
  for (std::size_t p = 0; p < n; ++p) {
    misses += w.miss[p];
    if (std::isinf(fine.depth[p])) {
      EXPECT_EQ(w.miss[p], 0) << "background pixel " << p;
      for (int k = 0; k < 4; ++k) EXPECT_EQ(w.index[p][k], -1) << "background pixel " << p;
      continue;
    }
    double sum = 0.0;
    bool packed = true;
    for (int k = 0; k < 4; ++k) {
      const int i = w.index[p][k];
      if (i < 0) {
        EXPECT_EQ(w.weight[p][k], 0.0f);
        packed = false;
        continue;
      }
      EXPECT_TRUE(packed) << "taps not packed at pixel " << p;
      EXPECT_LT(i, coarse.width * coarse.height);
      EXPECT_FALSE(std::isinf(coarse.depth[i])) << "background coarse tap at pixel " << p;
      EXPECT_GT(w.weight[p][k], 0.0f);
      EXPECT_LE(w.weight[p][k], 1.0f);
      sum += w.weight[p][k];
    }
    if (w.index[p][0] >= 0) {
      EXPECT_NEAR(sum, 1.0, kSumTol) << "pixel " << p;
    }
  }
  EXPECT_EQ(misses, w.misses);
}

std::vector<float> apply(const UpsampleWeights& w, const std::vector<float>& in, int channels) {
  std::vector<float> out(static_cast<std::size_t>(w.width) * w.height * channels, -7.0f);
  upsample_apply(w, in.data(), channels, out.data());
  return out;
}

UpsampleOptions with_mode(UpsampleMode m, double epsilon_rel = UpsampleOptions{}.epsilon_rel, int power = 32) {
  UpsampleOptions o;
  o.mode = m;
  o.epsilon_rel = epsilon_rel;
  o.normal_power = power;
  return o;
}

constexpr int kChannels = 2;
const float kA[kChannels] = {1.0f, -2.0f};  // value on the left part
const float kB[kChannels] = {5.0f, 3.0f};   // value on the right part
// A bilinear tap across the edge carries weight 0.5 - 0.5/s >= 0.25 at the display pixel next to
// the edge (the edge lies on a coarse pixel boundary, see the scenes); 0.2 is clearly visible.
constexpr double kVisibleMix = 0.2;

// Largest |value - A| / |B - A| over channels.
double mix(const float* v) {
  double m = 0.0;
  for (int k = 0; k < kChannels; ++k) m = std::max(m, std::abs(double(v[k]) - kA[k]) / std::abs(double(kB[k]) - kA[k]));
  return m;
}

constexpr int kW = 64, kH = 8;
constexpr double kEdge = 32.0;  // display x of the discontinuity: a multiple of every scale tested

std::vector<float> two_valued(const Buffer& c) {
  return coarse_values(c, kChannels, [](double x, double, int k) { return x < kEdge ? kA[k] : kB[k]; });
}

}  // namespace

// Depth discontinuity: near plane (z1) left of the edge, far plane (z2) right of it, same normal.
// For a display pixel on plane P, a matching tap has eps w_z = 1 and w_N = 1, the other plane's tap
// eps w_z = eps / (eps + |z1 - z2|) (eps = epsilon_rel z_p); with the edge on a coarse pixel boundary
// the bilinear mass of the other plane's column is at most that of its own (0.5 - 0.5/s vs. 0.5 + 0.5/s
// at worst), so the normalised weight leaking across is at most F / N <= eps / (eps + |z1 - z2|).
TEST(Upsample, BilateralDoesNotMixAcrossDepthEdge) {
  constexpr float kZ1 = 1.0f, kZ2 = 1000.0f;
  const SceneFn scene = [](double x, double) { return Surface{x < kEdge ? kZ1 : kZ2, glm::vec3(0, 0, -1)}; };
  const Buffer fine = sample(scene, kW, kH, 1);
  for (int s : {2, 4, 8})
    for (double eps_rel : {0.01, 1e-4}) {
      SCOPED_TRACE("scale " + std::to_string(s) + ", epsilon_rel " + std::to_string(eps_rel));
      const Buffer coarse = sample(scene, kW / s, kH / s, s);
      const std::vector<float> in = two_valued(coarse);
      const UpsampleWeights w = upsample_weights(coarse.view(), fine.view(), with_mode(UpsampleMode::Bilateral, eps_rel));
      expect_well_formed(w, coarse, fine);
      // Every pixel has its own plane's taps with bilinear mass >= 0.5: the miss measure is >= 0.5.
      EXPECT_EQ(w.misses, 0u);
      const std::vector<float> out = apply(w, in, kChannels);
      double worst_near = 0.0;
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
          const std::size_t p = std::size_t(y) * kW + x;
          const bool near = fine.cx(x) < kEdge;
          const double eps = eps_rel * fine.depth[p];
          const double leak_bound = eps / (eps + (kZ2 - kZ1));  // the derivation above
          const double m = near ? mix(&out[p * kChannels]) : 1.0 - mix(&out[p * kChannels]);
          EXPECT_LE(m, leak_bound + kFloatSlack) << "pixel (" << x << ", " << y << ")";
          if (near) worst_near = std::max(worst_near, m);
        }
      // The depths are chosen so that the near side's bound is tiny: eps / (eps + 999) < 1.1e-5.
      EXPECT_LE(worst_near, 1.1e-5 + kFloatSlack);

      // Plain bilinear mixes the planes next to the edge; so would a broken depth weight.
      const UpsampleWeights b = upsample_weights(coarse.view(), fine.view(), with_mode(UpsampleMode::Bilinear));
      expect_well_formed(b, coarse, fine);
      EXPECT_EQ(b.misses, 0u);
      const std::vector<float> outb = apply(b, in, kChannels);
      const int x_left = static_cast<int>(kEdge) - 1;  // the display pixel just left of the edge
      EXPECT_GE(mix(&outb[x_left * kChannels]), kVisibleMix);
      EXPECT_GE(1.0 - mix(&outb[(x_left + 1) * kChannels]), kVisibleMix);
    }
}

// Normal discontinuity: a 90 degree valley z = z0 + |x - edge| (display units), equal depth along
// the crease; the depth differences between neighbouring taps (<= about 2 s) are small against
// eps = 0.01 z0 = 10, so only the normal weight can separate the planes. Across the crease
// N_p . N_i = 0 (up to float rounding, < 1e-7), and (1e-7)^32 underflows to 0: no leak at all beyond
// float slack. With normal_power 0 (normal weight off) and in bilinear mode the planes do mix.
TEST(Upsample, NormalWeightsSeparateACrease) {
  constexpr double kZ0 = 1000.0;
  const glm::vec3 n_left = glm::normalize(glm::vec3(-1, 0, -1)), n_right = glm::normalize(glm::vec3(1, 0, -1));
  const SceneFn scene = [&](double x, double) {
    return Surface{static_cast<float>(kZ0 + std::abs(x - kEdge)), x < kEdge ? n_left : n_right};
  };
  const Buffer fine = sample(scene, kW, kH, 1);
  for (int s : {2, 4, 8}) {
    SCOPED_TRACE("scale " + std::to_string(s));
    const Buffer coarse = sample(scene, kW / s, kH / s, s);
    const std::vector<float> in = two_valued(coarse);
    const UpsampleWeights w = upsample_weights(coarse.view(), fine.view(), with_mode(UpsampleMode::Bilateral));
    expect_well_formed(w, coarse, fine);
    // Own taps: bilinear mass >= 0.5, depth difference <= s <= 8 against eps >= 10: measure >= 0.27.
    EXPECT_EQ(w.misses, 0u);
    const std::vector<float> out = apply(w, in, kChannels);
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const std::size_t p = std::size_t(y) * kW + x;
        const double m = fine.cx(x) < kEdge ? mix(&out[p * kChannels]) : 1.0 - mix(&out[p * kChannels]);
        EXPECT_LE(m, kFloatSlack) << "pixel (" << x << ", " << y << ")";
      }
    const int x_left = static_cast<int>(kEdge) - 1;
    for (const UpsampleOptions& o : {with_mode(UpsampleMode::Bilateral, 0.01, 0), with_mode(UpsampleMode::Bilinear)}) {
      SCOPED_TRACE(std::string(to_string(o.mode)) + ", normal_power " + std::to_string(o.normal_power));
      const std::vector<float> outm = apply(upsample_weights(coarse.view(), fine.view(), o), in, kChannels);
      EXPECT_GE(mix(&outm[x_left * kChannels]), kVisibleMix);
      EXPECT_GE(1.0 - mix(&outm[(x_left + 1) * kChannels]), kVisibleMix);
    }
  }
}

// On one plane of constant depth and normal, bilateral weights equal the bilinear ones, and
// bilinear interpolation of samples of an affine function is exact wherever the 2x2 block is not
// clamped at the border. Also checks the mapping for a fine buffer that is itself subsampled.
TEST(Upsample, BilinearReproducesAffineFunctions) {
  const SceneFn plane = [](double, double) { return Surface{10.0f, glm::vec3(0, 0, -1)}; };
  const auto affine = [](double x, double y, int k) { return static_cast<float>(3.0 + 0.25 * x - 0.5 * y + 2.0 * k); };
  // Values stay below ~30; float interpolation with float weights is exact to a few ulps of that
  // (30 * 2^-24 = 1.8e-6 each), so 2e-5 absolute.
  constexpr double kAffineTol = 2e-5;
  constexpr int kDisplay = 48;  // a multiple of every scale below
  struct Case {
    int fine_scale, coarse_scale;
  };
  for (const Case c : {Case{1, 2}, Case{1, 3}, Case{1, 4}, Case{1, 8}, Case{2, 6}, Case{3, 12}}) {
    const Buffer fine = sample(plane, kDisplay / c.fine_scale, kDisplay / 2 / c.fine_scale, c.fine_scale);
    const Buffer coarse = sample(plane, kDisplay / c.coarse_scale, kDisplay / 2 / c.coarse_scale, c.coarse_scale);
    const std::vector<float> in = coarse_values(coarse, kChannels, affine);
    for (UpsampleMode m : {UpsampleMode::Bilinear, UpsampleMode::Bilateral}) {
      SCOPED_TRACE(std::string(to_string(m)) + ", fine scale " + std::to_string(c.fine_scale) + ", coarse scale " +
                   std::to_string(c.coarse_scale));
      const UpsampleWeights w = upsample_weights(coarse.view(), fine.view(), with_mode(m));
      expect_well_formed(w, coarse, fine);
      EXPECT_EQ(w.misses, 0u);
      const std::vector<float> out = apply(w, in, kChannels);
      int interior = 0;
      for (int y = 0; y < fine.height; ++y)
        for (int x = 0; x < fine.width; ++x) {
          // Not clamped: the pixel centre lies between the first and last coarse centres.
          const bool inside = fine.cx(x) >= coarse.cx(0) && fine.cx(x) <= coarse.cx(coarse.width - 1) &&
                              fine.cy(y) >= coarse.cy(0) && fine.cy(y) <= coarse.cy(coarse.height - 1);
          if (!inside) continue;
          ++interior;
          for (int k = 0; k < kChannels; ++k)
            EXPECT_NEAR(out[(std::size_t(y) * fine.width + x) * kChannels + k], affine(fine.cx(x), fine.cy(y), k),
                        kAffineTol)
                << "pixel (" << x << ", " << y << ")";
        }
      EXPECT_GT(interior, fine.width * fine.height / 4);  // the check covered a real area
    }
  }
}

// Identical buffers at scale 1: every pixel takes exactly its own sample, in both modes, also with
// random depths, normals and background pixels.
TEST(Upsample, ScaleOneIsIdentity) {
  constexpr int kWid = 23, kHei = 17;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), z(1.0f, 50.0f), coin(0.0f, 1.0f);
  Buffer b;
  b.width = kWid;
  b.height = kHei;
  std::vector<float> in;
  for (int i = 0; i < kWid * kHei; ++i) {
    b.depth.push_back(coin(rng) < 0.2f ? kInf : z(rng));
    b.normal.push_back(glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0, 0, 0.01f)));
    in.push_back(u(rng));
    in.push_back(z(rng));
  }
  for (UpsampleMode m : {UpsampleMode::Bilateral, UpsampleMode::Bilinear}) {
    SCOPED_TRACE(to_string(m));
    const UpsampleWeights w = upsample_weights(b.view(), b.view(), with_mode(m));
    expect_well_formed(w, b, b);
    EXPECT_EQ(w.misses, 0u);
    const std::vector<float> out = apply(w, in, 2);
    for (int p = 0; p < kWid * kHei; ++p) {
      if (std::isinf(b.depth[p])) {
        EXPECT_EQ(out[2 * p], -7.0f) << "background pixel " << p << " was written";
        continue;
      }
      EXPECT_EQ(w.index[p][0], p);
      EXPECT_EQ(w.weight[p][0], 1.0f);
      EXPECT_EQ(w.index[p][1], -1);
      EXPECT_EQ(out[2 * p], in[2 * p]);
      EXPECT_EQ(out[2 * p + 1], in[2 * p + 1]);
    }
  }
}

// Eq. 11 evaluated pixel by pixel as section 4.2 states it, for comparison with upsample_weights's
// run-wise kernel: the 2x2 bilinear block (clamp-to-edge, taps of zero bilinear weight dropped),
// w~ = w_b eps / (eps + |z_p - z_i|) max(0, N_p . N_i)^power over hit taps, normalised; a miss
// below the threshold; bilinear over hit taps where every w~ vanishes.
struct ReferencePixel {
  std::array<std::int32_t, 4> idx{-1, -1, -1, -1};
  std::array<double, 4> w{};
  bool miss = false;
  double measure = 0.0;
};
ReferencePixel reference_pixel(const Buffer& c, const Buffer& f, const UpsampleOptions& o, int X, int Y) {
  ReferencePixel r;
  const std::size_t p = static_cast<std::size_t>(Y) * f.width + X;
  if (std::isinf(f.depth[p])) return r;
  const double ratio = static_cast<double>(f.scale) / c.scale;
  const auto axis = [&](double u, int n, int& i0, int& i1, double& t) {
    u = std::clamp(u, 0.0, static_cast<double>(n - 1));
    i0 = std::min(static_cast<int>(std::floor(u)), std::max(n - 2, 0));
    i1 = std::min(i0 + 1, n - 1);
    t = u - i0;
  };
  int x0, x1, y0, y1;
  double fx, fy;
  axis((X + 0.5) * ratio - 0.5, c.width, x0, x1, fx);
  axis((Y + 0.5) * ratio - 0.5, c.height, y0, y1, fy);
  const int xs[4] = {x0, x1, x0, x1}, ys[4] = {y0, y0, y1, y1};
  const double wb[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  const double zp = f.depth[p], eps = o.epsilon_rel * zp;
  const glm::dvec3 np(f.normal[p]);
  std::array<double, 4> w{}, wbil{};
  for (int k = 0; k < 4; ++k) {
    const std::size_t i = static_cast<std::size_t>(ys[k]) * c.width + xs[k];
    if (!(wb[k] > 0.0) || std::isinf(c.depth[i])) continue;
    wbil[k] = wb[k];
    const double cosine = std::max(0.0, glm::dot(np, glm::dvec3(c.normal[i])));
    w[k] = wb[k] * eps / (eps + std::abs(zp - c.depth[i])) * std::pow(cosine, o.normal_power);
  }
  double sum = 0.0, sum_bil = 0.0;
  for (int k = 0; k < 4; ++k) {
    sum += w[k];
    sum_bil += wbil[k];
  }
  r.measure = sum;
  r.miss = !(sum > 0.0) || sum < o.miss_threshold;
  const std::array<double, 4>& use = sum > 0.0 ? w : wbil;
  const double norm = sum > 0.0 ? sum : sum_bil;
  int m = 0;
  for (int k = 0; k < 4; ++k)
    if (use[k] > 0.0) {
      r.idx[m] = ys[k] * c.width + xs[k];
      r.w[m++] = use[k] / norm;
    }
  return r;
}

// upsample_weights (bilateral) against reference_pixel on random planes: background in both
// buffers (their normals NaN or infinite, which must not reach any weight), normals that face away,
// display widths that cross and end inside the kernel's runs of pixels, coarse buffers of floor and
// ceil size, scales 1 to 4 and several powers, epsilons and thresholds. Taps, their order and the
// miss flags must be the same; weights within kWeightTol. The kernel works in float, the reference
// in double with std::pow. The float dot product of two unit normals is off by up to ~3 ulps of 1
// (u = 6e-8), which the power P multiplies by P / d relative to the weight (d >= 0.8 between the
// normals that face each other here: 1.25 * 32 * 3u = 7.2e-6), plus ~15 roundings of the products,
// squarings and the division (~1e-6); the normalisation can double that, on weights of at most 1:
// 2e-5 (the worst seen is 9.5e-7). A power off by one moves weights by a factor d, 20 % and more.
TEST(Upsample, BilateralWeightsMatchAPerPixelEvaluationOfEq11) {
  constexpr double kWeightTol = 2e-5;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), coin(0.0f, 1.0f);
  const auto plane = [&](int w, int h, int scale, float background) {
    Buffer b;
    b.width = w;
    b.height = h;
    b.scale = scale;
    for (int i = 0; i < w * h; ++i) {
      const bool bg = coin(rng) < background;
      // Depths cluster on two layers, so that some taps match and some do not.
      b.depth.push_back(bg ? kInf : (coin(rng) < 0.5f ? 5.0f : 20.0f) * (1.0f + 0.02f * u(rng)));
      glm::vec3 n = glm::normalize(glm::vec3(0.3f * u(rng), 0.3f * u(rng), 1.0f) + (coin(rng) < 0.2f ? glm::vec3(0, 0, -2.5f) : glm::vec3(0)));
      if (bg) n = coin(rng) < 0.5f ? glm::vec3(std::nanf("")) : glm::vec3(kInf, -kInf, kInf);
      b.normal.push_back(n);
    }
    return b;
  };
  struct Case {
    int fine_w, fine_h, coarse_scale, power;
    double epsilon_rel, threshold;
    bool ceil;
  };
  const Case cases[] = {{150, 9, 4, 32, 0.01, 0.05, true},  {150, 9, 4, 32, 0.01, 0.05, false}, {64, 5, 2, 1, 0.1, 0.3, true},
                        {129, 7, 3, 7, 0.02, 0.5, true},   {65, 6, 1, 0, 0.01, 0.05, true},    {200, 4, 4, 2, 1e-4, 0.01, false},
                        {1, 3, 4, 32, 0.01, 0.05, true},   {63, 1, 4, 32, 0.05, 0.05, true}};
  int compared = 0, misses = 0, fallbacks = 0;
  for (const Case& cs : cases) {
    const int cw = cs.ceil ? (cs.fine_w + cs.coarse_scale - 1) / cs.coarse_scale : std::max(1, cs.fine_w / cs.coarse_scale);
    const int ch = cs.ceil ? (cs.fine_h + cs.coarse_scale - 1) / cs.coarse_scale : std::max(1, cs.fine_h / cs.coarse_scale);
    const Buffer coarse = plane(cw, ch, cs.coarse_scale, 0.15f), fine = plane(cs.fine_w, cs.fine_h, 1, 0.1f);
    UpsampleOptions o = with_mode(UpsampleMode::Bilateral, cs.epsilon_rel, cs.power);
    o.miss_threshold = cs.threshold;
    const UpsampleWeights w = upsample_weights(coarse.view(), fine.view(), o);
    for (int Y = 0; Y < fine.height; ++Y)
      for (int X = 0; X < fine.width; ++X) {
        const std::size_t p = static_cast<std::size_t>(Y) * fine.width + X;
        const ReferencePixel r = reference_pixel(coarse, fine, o, X, Y);
        SCOPED_TRACE("fine " + std::to_string(fine.width) + "x" + std::to_string(fine.height) + " scale " +
                     std::to_string(cs.coarse_scale) + " power " + std::to_string(cs.power) + " pixel (" +
                     std::to_string(X) + ", " + std::to_string(Y) + ")");
        // A measure within its float error (relative, as the weights') of the threshold may fall either way.
        if (std::abs(r.measure - o.miss_threshold) > kWeightTol * o.miss_threshold) {
          EXPECT_EQ(w.miss[p] != 0, r.miss);
        }
        for (int k = 0; k < 4; ++k) {
          EXPECT_EQ(w.index[p][k], r.idx[k]);
          EXPECT_NEAR(w.weight[p][k], r.w[k], kWeightTol);
        }
        ++compared;
        misses += r.miss;
        fallbacks += !std::isinf(fine.depth[p]) && !(r.measure > 0.0);
      }
  }
  // The random planes exercise every branch: matches, misses and the bilinear fallback.
  EXPECT_GT(compared, 3000);
  EXPECT_GT(misses, 50);
  EXPECT_GT(fallbacks, 10);
}

// A background plane (z = 100) with two thin foreground bars (z = 1): bar 1 covers display x in
// [8, 9), between the coarse centres 6 and 10 (scale 4), so the coarse buffer misses it entirely and
// its pixels match no tap (measure = eps / (eps + 99) = 1e-4 < 0.05); bar 2 covers [17, 19), which
// contains the coarse centre 18, so its pixels match it with bilinear mass 0.875. Misses are exactly
// the pixels of bar 1. Bilinear mode flags none.
TEST(Upsample, MissesWhereTheCoarseBufferMissesAnObject) {
  constexpr int kS = 4, kWid = 40, kHei = 8;
  const SceneFn scene = [](double x, double) {
    const bool bar = (x >= 8.0 && x < 9.0) || (x >= 17.0 && x < 19.0);
    return Surface{bar ? 1.0f : 100.0f, glm::vec3(0, 0, -1)};
  };
  const Buffer fine = sample(scene, kWid, kHei, 1), coarse = sample(scene, kWid / kS, kHei / kS, kS);
  const UpsampleWeights w = upsample_weights(coarse.view(), fine.view(), with_mode(UpsampleMode::Bilateral));
  expect_well_formed(w, coarse, fine);
  for (int y = 0; y < kHei; ++y)
    for (int x = 0; x < kWid; ++x) EXPECT_EQ(w.miss[std::size_t(y) * kWid + x], x == 8 ? 1 : 0) << "pixel (" << x << ", " << y << ")";
  EXPECT_EQ(w.misses, std::size_t(kHei));

  const UpsampleWeights b = upsample_weights(coarse.view(), fine.view(), with_mode(UpsampleMode::Bilinear));
  expect_well_formed(b, coarse, fine);
  EXPECT_EQ(b.misses, 0u);

  // The "shaded" fallback: bilinear on the miss pixels only, the rest keeps the eq. 11 result.
  const std::vector<float> in = coarse_values(coarse, 1, [](double x, double y, int) { return float(x + 100 * y); });
  std::vector<float> out = apply(w, in, 1);
  const std::vector<float> eq11 = out, bil = apply(b, in, 1);
  upsample_apply_bilinear(w, coarse.view(), fine.view(), in.data(), 1, out.data(), &w.miss);
  for (std::size_t p = 0; p < out.size(); ++p) EXPECT_EQ(out[p], w.miss[p] ? bil[p] : eq11[p]) << "pixel " << p;
  // Without a selection every non-background pixel gets the bilinear result.
  std::vector<float> all(out.size(), -7.0f);
  upsample_apply_bilinear(w, coarse.view(), fine.view(), in.data(), 1, all.data());
  EXPECT_EQ(all, bil);
}

// Where every eq. 11 weight is 0 the pixel falls back to bilinear over the valid taps and is a miss;
// with no valid tap it is a miss without taps; background display pixels have neither.
TEST(Upsample, FallbacksAndBackground) {
  constexpr int kS = 2, kWid = 8, kHei = 4;
  const Buffer fine = sample([](double, double) { return Surface{5.0f, glm::vec3(0, 0, -1)}; }, kWid, kHei, 1);
  const std::vector<float> in(std::size_t(kWid / kS) * (kHei / kS), 1.0f);

  // Coarse normals face away (N_p . N_i = -1): w_N = 0 for every tap.
  const Buffer away = sample([](double, double) { return Surface{5.0f, glm::vec3(0, 0, 1)}; }, kWid / kS, kHei / kS, kS);
  const UpsampleWeights w = upsample_weights(away.view(), fine.view(), with_mode(UpsampleMode::Bilateral));
  const UpsampleWeights b = upsample_weights(away.view(), fine.view(), with_mode(UpsampleMode::Bilinear));
  expect_well_formed(w, away, fine);
  EXPECT_EQ(w.misses, std::size_t(kWid * kHei));
  EXPECT_EQ(b.misses, 0u);
  EXPECT_EQ(w.index, b.index);
  EXPECT_EQ(w.weight, b.weight);

  // Some coarse taps are background: bilinear renormalises over the others.
  Buffer holes = sample([](double, double) { return Surface{5.0f, glm::vec3(0, 0, -1)}; }, kWid / kS, kHei / kS, kS);
  holes.depth[0] = kInf;
  holes.normal[0] = glm::vec3(NAN);  // a background pixel's normal is meaningless and must not be read
  for (UpsampleMode m : {UpsampleMode::Bilateral, UpsampleMode::Bilinear}) {
    const UpsampleWeights h = upsample_weights(holes.view(), fine.view(), with_mode(m));
    expect_well_formed(h, holes, fine);  // includes: no tap on the background coarse pixel
    EXPECT_EQ(h.misses, 1u) << to_string(m);  // display pixel (0, 0) sees only coarse pixel 0
    EXPECT_EQ(h.miss[0], 1) << to_string(m);
  }

  // No valid tap at all.
  const Buffer empty = sample([](double, double) { return Surface{kInf, glm::vec3(0, 0, -1)}; }, kWid / kS, kHei / kS, kS);
  for (UpsampleMode m : {UpsampleMode::Bilateral, UpsampleMode::Bilinear}) {
    const UpsampleWeights e = upsample_weights(empty.view(), fine.view(), with_mode(m));
    EXPECT_EQ(e.misses, std::size_t(kWid * kHei)) << to_string(m);
    for (const auto& idx : e.index) EXPECT_EQ(idx[0], -1);
    for (const auto& wt : e.weight) EXPECT_EQ(wt[0], 0.0f);
    const std::vector<float> out = apply(e, in, 1);
    EXPECT_TRUE(std::all_of(out.begin(), out.end(), [](float v) { return v == -7.0f; })) << "pixels without taps were written";
  }

  // Background display pixels.
  const Buffer sky = sample([](double, double) { return Surface{kInf, glm::vec3(0)}; }, kWid, kHei, 1);
  const UpsampleWeights s = upsample_weights(away.view(), sky.view(), with_mode(UpsampleMode::Bilateral));
  expect_well_formed(s, away, sky);
  EXPECT_EQ(s.misses, 0u);
  EXPECT_EQ(s.bytes(), std::size_t(kWid * kHei) * (4 * sizeof(std::int32_t) + 4 * sizeof(float) + 1));
}

namespace {
template <class F>
void expect_error(F&& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  }
}
}  // namespace

// upsample_apply runs its loop with the channel count fixed at compile time for 1 and 3 channels
// and read at run time otherwise: for every count, each channel of the result equals the same
// channel applied alone (1 channel) and the weighted sum of the taps written out here, on a sloped
// surface with background pixels at scale 4. Tolerance: the same products summed in the same order,
// so equal unless a compiler contracts some of them into fused multiply-adds: a few units in the
// last place of values of order 1 (a wrong stride or tap is off by order 1).
TEST(Upsample, EveryChannelCountAppliesTheSameWeights) {
  constexpr float kTol = 1e-6f;
  const SceneFn slope = [](double x, double y) {
    if (x + 2.0 * y < 9.0) return Surface{kInf, glm::vec3(0, 0, -1)};
    return Surface{static_cast<float>(3.0 + 0.05 * x + 0.02 * y), glm::normalize(glm::vec3(0.05f, 0.02f, -1.0f))};
  };
  const Buffer fine = sample(slope, 32, 24, 1), coarse = sample(slope, 8, 6, 4);
  const UpsampleWeights w = upsample_weights(coarse.view(), fine.view(), UpsampleOptions{});
  const std::size_t nc = static_cast<std::size_t>(coarse.width) * coarse.height;
  std::size_t written = 0;
  for (int channels : {1, 2, 3, 4, 5}) {
    SCOPED_TRACE("channels " + std::to_string(channels));
    const std::vector<float> in = coarse_values(coarse, channels, [](double x, double y, int k) {
      return static_cast<float>(std::sin(0.3 * x + k) + 0.1 * y * (k + 1));
    });
    const std::vector<float> out = apply(w, in, channels);
    for (int c = 0; c < channels; ++c) {
      std::vector<float> one(nc);
      for (std::size_t i = 0; i < nc; ++i) one[i] = in[i * channels + c];
      const std::vector<float> alone = apply(w, one, 1);
      for (std::size_t p = 0; p < alone.size(); ++p) {
        float expect = -7.0f;
        if (w.index[p][0] >= 0) {
          expect = 0.0f;
          for (int k = 0; k < 4 && w.index[p][k] >= 0; ++k) expect += w.weight[p][k] * one[static_cast<std::size_t>(w.index[p][k])];
          ++written;
        }
        ASSERT_NEAR(out[p * channels + c], alone[p], kTol * (1.0f + std::abs(alone[p]))) << "pixel " << p << " channel " << c;
        ASSERT_NEAR(alone[p], expect, kTol * (1.0f + std::abs(expect))) << "pixel " << p;
      }
    }
  }
  EXPECT_GT(written, 0u);
}

TEST(Upsample, BadInputIsRejectedWithAClearMessage) {
  const SceneFn plane = [](double, double) { return Surface{2.0f, glm::vec3(0, 0, -1)}; };
  const Buffer fine = sample(plane, 16, 8, 1), coarse = sample(plane, 4, 2, 4);
  const UpsampleOptions ok;
  EXPECT_NO_THROW(upsample_weights(coarse.view(), fine.view(), ok));
  // Coarse sizes from floor and ceil of display / scale are both fine.
  const Buffer odd = sample(plane, 18, 9, 1);
  EXPECT_NO_THROW(upsample_weights(sample(plane, 4, 2, 4).view(), odd.view(), ok));
  EXPECT_NO_THROW(upsample_weights(sample(plane, 5, 3, 4).view(), odd.view(), ok));

  const auto run = [&](PlaneView c, PlaneView f, UpsampleOptions o = UpsampleOptions{}) {
    return [=] { upsample_weights(c, f, o); };
  };
  PlaneView c = coarse.view(), f = fine.view();
  expect_error(run(sample(plane, 3, 2, 4).view(), f), "do not cover the same display area");
  expect_error(run(sample(plane, 4, 3, 4).view(), f), "do not cover the same display area");
  PlaneView bad = c;
  bad.scale = 0;
  expect_error(run(bad, f), "scale 0 must be at least 1");
  bad = f;
  bad.scale = 8;
  expect_error(run(c, bad), "exceeds coarse buffer scale");
  bad = c;
  bad.depth = nullptr;
  expect_error(run(bad, f), "coarse buffer depth pointer is null");
  bad = f;
  bad.normal = nullptr;
  expect_error(run(c, bad), "fine buffer normal pointer is null");
  bad = f;
  bad.width = 0;
  expect_error(run(c, bad), "must be positive");
  bad = f;
  bad.width = bad.height = 70000;  // rejected before any pixel is read
  expect_error(run(sample(plane, 1, 1, 1).view(), bad), "more pixels than an int32");

  UpsampleOptions o;
  for (double e : {0.0, -0.01, double(NAN), double(INFINITY)}) {
    o = ok;
    o.epsilon_rel = e;
    expect_error(run(c, f, o), "epsilon_rel");
  }
  o = ok;
  o.normal_power = -1;
  expect_error(run(c, f, o), "normal_power = -1");
  o = ok;
  o.miss_threshold = NAN;
  expect_error(run(c, f, o), "miss_threshold");
  o = ok;
  o.mode = static_cast<UpsampleMode>(7);
  expect_error(run(c, f, o), "unknown mode");

  // Depths and normals of the buffers (the fine one is checked inside the parallel loop).
  Buffer bf = fine;
  bf.depth[3 * 16 + 5] = NAN;
  expect_error(run(c, bf.view()), "fine depth at pixel (5, 3)");
  bf = fine;
  bf.depth[7] = -kInf;
  expect_error(run(c, bf.view()), "fine depth at pixel (7, 0)");
  Buffer bc = coarse;
  bc.depth[1] = -1.0f;
  expect_error(run(bc.view(), f), "coarse depth at pixel (1, 0)");
  bc = coarse;
  bc.normal[2] = glm::vec3(NAN);
  expect_error(run(bc.view(), f), "coarse normal at pixel (2, 0) is not finite");

  // Applying weights.
  const UpsampleWeights w = upsample_weights(c, f, ok);
  std::vector<float> in(8, 1.0f), out(16 * 8, 0.0f);
  expect_error([&] { upsample_apply(w, nullptr, 1, out.data()); }, "input pointer is null");
  expect_error([&] { upsample_apply(w, in.data(), 1, nullptr); }, "output pointer is null");
  expect_error([&] { upsample_apply(w, in.data(), 0, out.data()); }, "channels = 0");
  UpsampleWeights broken = w;
  broken.miss.pop_back();
  expect_error([&] { upsample_apply(broken, in.data(), 1, out.data()); }, "inconsistent array sizes");
  const std::vector<std::uint8_t> short_sel(5, 1);
  expect_error([&] { upsample_apply_bilinear(w, c, f, in.data(), 1, out.data(), &short_sel); }, "pixel selection has 5");
  expect_error([&] { upsample_apply_bilinear(w, c, odd.view(), in.data(), 1, out.data()); }, "do not match fine buffer");

  expect_error([] { parse_upsample_mode("bicubic"); }, "'bicubic'");
  expect_error([] { parse_upsample_fallback("magic"); }, "'magic'");
}

// The packing of the eq. 11 taps (detail::pack_taps, the last step of upsample_weights): every
// pixel keeps the taps whose unnormalised weight is positive, in tap order, then -1 and 0. Checked
// against the rule written out here, for every 4-bit pattern of kept taps in every pixel position of
// a 16-pixel vector (patterns shifted across the pixels), run lengths that end inside and past a
// vector, a tap-row stride longer than the run, and NaN, -0 and negative weights (dropped). Exact:
// packing only moves values. Where this processor has AVX-512, pack_taps takes the vector path and
// pack_taps_portable is compared too, so both paths are held to the rule.
TEST(Upsample, TapPackingKeepsPositiveTapsInTapOrder) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> pattern(0, 15), value(0, 1 << 20);
  const float dropped[] = {0.0f, -0.0f, -1.0f, std::nanf("")};
  for (const int n : {0, 1, 15, 16, 17, 31, 32, 47, 64, 70}) {
    const int stride = n + 3;
    std::vector<std::int32_t> tap(4 * stride);
    std::vector<float> weight(4 * stride), live(4 * stride);
    std::vector<int> masks(n);
    for (int t = 0; t < n; ++t) {
      // Each pattern in turn at each position, then random ones.
      masks[t] = n >= 16 && t < 16 ? (t + n) % 16 : pattern(rng);
      for (int k = 0; k < 4; ++k) {
        const std::size_t i = static_cast<std::size_t>(k) * stride + t;
        tap[i] = value(rng);
        weight[i] = static_cast<float>(value(rng)) / (1 << 20);
        live[i] = (masks[t] >> k) & 1 ? 1e-30f + weight[i] : dropped[value(rng) % 4];
      }
    }
    const auto check = [&](auto pack, const char* which) {
      std::vector<std::array<std::int32_t, 4>> oi(n + 1, {7, 7, 7, 7});
      std::vector<std::array<float, 4>> ow(n + 1, {7.0f, 7.0f, 7.0f, 7.0f});
      pack(tap.data(), weight.data(), live.data(), stride, n, oi.data(), ow.data());
      for (int t = 0; t < n; ++t) {
        SCOPED_TRACE(std::string(which) + " n " + std::to_string(n) + " pixel " + std::to_string(t) + " mask " + std::to_string(masks[t]));
        int m = 0;
        for (int k = 0; k < 4; ++k)
          if ((masks[t] >> k) & 1) {
            const std::size_t i = static_cast<std::size_t>(k) * stride + t;
            EXPECT_EQ(oi[t][m], tap[i]);
            EXPECT_EQ(ow[t][m], weight[i]);
            ++m;
          }
        for (; m < 4; ++m) {
          EXPECT_EQ(oi[t][m], -1);
          EXPECT_EQ(std::bit_cast<std::uint32_t>(ow[t][m]), 0u);  // +0, not -0
        }
      }
      EXPECT_EQ(oi[n][0], 7) << which << ": wrote past the run";
    };
    check(detail::pack_taps, "pack_taps");
    check(detail::pack_taps_portable, "pack_taps_portable");
  }
  if (!detail::pack_taps_vectorised()) std::cout << "[ note ] no AVX-512 here: pack_taps took the portable path\n";
}

TEST(Upsample, NamesRoundTrip) {
  for (UpsampleMode m : {UpsampleMode::Bilateral, UpsampleMode::Bilinear}) EXPECT_EQ(parse_upsample_mode(to_string(m)), m);
  for (UpsampleFallback f : {UpsampleFallback::Robust, UpsampleFallback::Shaded, UpsampleFallback::None})
    EXPECT_EQ(parse_upsample_fallback(to_string(f)), f);
  EXPECT_STREQ(to_string(UpsampleMode::Bilateral), "bilateral");
  EXPECT_STREQ(to_string(UpsampleFallback::Shaded), "shaded");
}
