// The relMSE against a noisy reference with the reference's own noise removed (two independent
// halves): it recovers a known error under synthetic noise, its interval covers the truth at about
// its stated rate, and on the path tracer the noise it estimates from two halves matches the spread
// of two independent references.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "softgi/metrics/image_metrics.hpp"
#include "softgi/metrics/reference_noise.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

// A converged image m, a test image m + delta (relMSE against m known), and two halves m + noise
// whose mean has per-channel noise variance sigma^2.
struct Synthetic {
  Image m, t, a, b;
  double true_relmse = 0.0;
};
Synthetic synthetic(int w, int h, double delta, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> level(0.5f, 2.0f);
  std::normal_distribution<float> nrm(0.0f, 1.0f);
  Synthetic s{Image(w, h), Image(w, h), Image(w, h), Image(w, h)};
  const float half_sigma = static_cast<float>(sigma * std::sqrt(2.0));  // each half: variance 2 sigma^2
  double sum = 0.0;
  for (std::size_t i = 0; i < s.m.rgb.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const float m = level(rng);
      const float d = static_cast<float>(delta) * (rng() % 2 ? 1.0f : -1.0f);
      s.m.rgb[i][c] = m;
      s.t.rgb[i][c] = m + d;
      s.a.rgb[i][c] = m + half_sigma * nrm(rng);
      s.b.rgb[i][c] = m + half_sigma * nrm(rng);
      sum += static_cast<double>(d) * d / (static_cast<double>(m) * m + 1e-2);
    }
  s.true_relmse = sum / (3.0 * s.m.rgb.size());
  return s;
}

}  // namespace

// The test image is off by 0.02 everywhere; the reference's noise (sigma 0.03) alone adds about twice
// that error. The corrected value lands within its interval of the truth; without the correction (the
// raw relMSE) it is far outside. The weights come from the noisy reference: a bias of about
// 6 (sigma / m)^2 of the noise term (docs/metrics.md), under 2 % of it here, inside the interval.
TEST(ReferenceNoise, RecoversAKnownErrorUnderReferenceNoise) {
  const Synthetic s = synthetic(128, 128, 0.02, 0.03, 1);
  const metrics::NoiseCorrectedError e = metrics::noise_corrected_relmse(s.t, s.a, s.b);
  std::printf("true %.6f raw %.6f noise %.6f corrected %.6f [%.6f, %.6f]\n", s.true_relmse, e.raw, e.noise, e.corrected, e.ci_low,
              e.ci_high);
  EXPECT_EQ(e.pixels, 128 * 128);
  EXPECT_LE(e.ci_low, s.true_relmse);
  EXPECT_GE(e.ci_high, s.true_relmse);
  EXPECT_GT(e.raw, 2.0 * s.true_relmse);
  EXPECT_TRUE(e.ci_high < e.raw);
  EXPECT_FALSE(e.below_noise_floor() && e.noise < 0.1 * e.corrected);
  // relMSE against the two halves' mean is the raw value.
  const metrics::Metrics m = metrics::compare(s.t, metrics::mean_of_halves(s.a, s.b));
  EXPECT_NEAR(m.relmse, e.raw, 1e-6 * e.raw);
  // An exact test image: the corrected error is zero within its interval, and below the noise floor.
  const metrics::NoiseCorrectedError z = metrics::noise_corrected_relmse(s.m, s.a, s.b);
  EXPECT_LE(z.ci_low, 0.0);
  EXPECT_GE(z.ci_high, 0.0);
  EXPECT_TRUE(z.below_noise_floor());
}

// Over independent trials the 95 % interval holds the true error in about 95 % of them: 200 trials
// give 190 on average with a binomial standard deviation of 3.1; [178, 200] is four of them below.
TEST(ReferenceNoise, IntervalCoversTheTruthAtItsRate) {
  int covered = 0;
  const int trials = 200;
  for (int k = 0; k < trials; ++k) {
    const Synthetic s = synthetic(24, 24, 0.03, 0.04, 100 + k);
    const metrics::NoiseCorrectedError e = metrics::noise_corrected_relmse(s.t, s.a, s.b);
    covered += e.ci_low <= s.true_relmse && s.true_relmse <= e.ci_high;
  }
  std::printf("covered %d of %d\n", covered, trials);
  EXPECT_GE(covered, 178);
}

// On the path tracer: a second, independent reference (seeds 3 and 4) differs from the first (seeds 1
// and 2) by its own noise alone, so its corrected error against the first is the noise of one
// reference, which the first one's halves estimate. At 64 spp per half the relative noise per pixel
// is a few percent on the sphere scene (the weight bias above is then below 1 %); the estimates'
// own spread over 64x64 pixels, with the heavy tails of shadow edges, is some 5-10 %; 20 % bounds it.
// The raw error counts the noise of both references: twice the estimate.
TEST(ReferenceNoise, NoiseEstimateMatchesTheSpreadOfIndependentReferences) {
  const scene::Scene sc = scene::make_builtin("sphere_plane");
  reference::ReferenceOptions o;
  o.spp = 64;
  o.width = o.height = 64;
  auto render = [&](unsigned seed) {
    o.seed = seed;
    return reference::render_reference(sc, o).final_image;
  };
  const Image a = render(1), b = render(2), c = render(3), d = render(4);
  const metrics::NoiseCorrectedError e = metrics::noise_corrected_relmse(metrics::mean_of_halves(c, d), a, b);
  std::printf("noise from halves %.7f, independent reference: raw %.7f corrected %.7f [%.7f, %.7f]\n", e.noise, e.raw, e.corrected,
              e.ci_low, e.ci_high);
  EXPECT_GT(e.noise, 0.0);
  EXPECT_NEAR(e.corrected, e.noise, 0.2 * e.noise);
  EXPECT_NEAR(e.raw, 2.0 * e.noise, 0.4 * e.noise);
}

// Two noisy images of one converged image m + delta and m: with both sides' halves, the noise of both
// is taken out and the known error is recovered; the one-sided estimate, which treats the test's
// noise as error, is far above it. Tolerance: the 95 % interval, as above.
TEST(ReferenceNoise, BothSidesNoisyRecoversTheKnownError) {
  Synthetic s = synthetic(128, 128, 0.02, 0.03, 11);
  const Synthetic other = synthetic(128, 128, 0.02, 0.03, 11);  // same m and delta
  std::mt19937 rng(99);
  std::normal_distribution<float> nrm(0.0f, 1.0f);
  const float half_sigma = static_cast<float>(0.03 * std::sqrt(2.0));
  Image ta(128, 128), tb(128, 128);
  for (std::size_t i = 0; i < s.t.rgb.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      ta.rgb[i][c] = other.t.rgb[i][c] + half_sigma * nrm(rng);
      tb.rgb[i][c] = other.t.rgb[i][c] + half_sigma * nrm(rng);
    }
  const metrics::NoiseCorrectedError both = metrics::noise_corrected_relmse_between(ta, tb, s.a, s.b);
  EXPECT_LE(both.ci_low, s.true_relmse);
  EXPECT_GE(both.ci_high, s.true_relmse);
  const metrics::NoiseCorrectedError one = metrics::noise_corrected_relmse(metrics::mean_of_halves(ta, tb), s.a, s.b);
  EXPECT_GT(one.ci_low, s.true_relmse) << "the test's own noise should show as error when only the reference's is removed";
  EXPECT_NEAR(both.noise - one.noise, one.corrected - s.true_relmse, 0.2 * (one.corrected - s.true_relmse));
}

// Two frames of a moving image (m0, m1 = m0 + a change), their references as noisy halves with
// seeds of their own. A test whose error is the same in both frames (a fixed bias) has no temporal
// error: the corrected value's interval holds 0, while the raw value (the references' noise) does
// not. A test that flickers (an independent +-delta per frame) has the known temporal error
// mean ((d1 - d0)^2 / (r0^2 + eps)) inside its interval. Tolerance: the 95 % interval.
TEST(ReferenceNoise, TemporalErrorSeesFlickerAndNotAFixedError) {
  const int w = 128, h = 128;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> level(0.5f, 2.0f);
  std::normal_distribution<float> nrm(0.0f, 1.0f);
  const float half_sigma = 0.03f * std::sqrt(2.0f);
  Image m0(w, h), m1(w, h), a0(w, h), b0(w, h), a1(w, h), b1(w, h), fixed0(w, h), fixed1(w, h), flick0(w, h), flick1(w, h);
  double truth = 0.0;
  for (std::size_t i = 0; i < m0.rgb.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      m0.rgb[i][c] = level(rng);
      m1.rgb[i][c] = m0.rgb[i][c] * 1.1f;  // the true change between the frames
      a0.rgb[i][c] = m0.rgb[i][c] + half_sigma * nrm(rng);
      b0.rgb[i][c] = m0.rgb[i][c] + half_sigma * nrm(rng);
      a1.rgb[i][c] = m1.rgb[i][c] + half_sigma * nrm(rng);
      b1.rgb[i][c] = m1.rgb[i][c] + half_sigma * nrm(rng);
      const float bias = 0.05f;
      fixed0.rgb[i][c] = m0.rgb[i][c] + bias;
      fixed1.rgb[i][c] = m1.rgb[i][c] + bias;
      const float d0 = rng() % 2 ? 0.02f : -0.02f, d1 = rng() % 2 ? 0.02f : -0.02f;
      flick0.rgb[i][c] = m0.rgb[i][c] + d0;
      flick1.rgb[i][c] = m1.rgb[i][c] + d1;
      const double r0 = 0.5 * (static_cast<double>(a0.rgb[i][c]) + b0.rgb[i][c]);
      truth += static_cast<double>(d1 - d0) * (d1 - d0) / (r0 * r0 + 1e-2);
    }
  truth /= 3.0 * m0.rgb.size();
  const metrics::NoiseCorrectedError fixed = metrics::temporal_error(fixed0, fixed1, a0, b0, a1, b1);
  const metrics::NoiseCorrectedError flick = metrics::temporal_error(flick0, flick1, a0, b0, a1, b1);
  std::printf("fixed: raw %.6f corrected %.6f [%.6f, %.6f]; flicker: truth %.6f corrected %.6f [%.6f, %.6f]\n", fixed.raw,
              fixed.corrected, fixed.ci_low, fixed.ci_high, truth, flick.corrected, flick.ci_low, flick.ci_high);
  EXPECT_LE(fixed.ci_low, 0.0);
  EXPECT_GE(fixed.ci_high, 0.0);
  EXPECT_GT(fixed.raw, fixed.ci_high) << "the references' noise alone shows as change when it is not taken out";
  EXPECT_LE(flick.ci_low, truth);
  EXPECT_GE(flick.ci_high, truth);
  EXPECT_GT(flick.ci_low, 0.0);
  EXPECT_THROW(metrics::temporal_error(flick0, Image(w, h + 1), a0, b0, a1, b1), std::invalid_argument);
}

TEST(ReferenceNoise, BadInputNamesTheImage) {
  const Image ok(4, 4, glm::vec3(1.0f)), small(3, 4, glm::vec3(1.0f));
  Image nan = ok;
  nan.at(2, 1).g = std::nanf("");
  auto error_of = [](auto f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of([&] { metrics::noise_corrected_relmse(ok, small, ok); }).find("first half image is 3x4"), std::string::npos);
  EXPECT_NE(error_of([&] { metrics::noise_corrected_relmse(ok, ok, nan); }).find("second half image has a non-finite value at pixel (2, 1)"),
            std::string::npos);
  EXPECT_NE(error_of([&] { metrics::noise_corrected_relmse(Image(), ok, ok); }).find("test image is empty"), std::string::npos);
  EXPECT_NE(error_of([&] { metrics::noise_corrected_relmse(ok, ok, ok, {}, 0.0); }).find("epsilon"), std::string::npos);
  Mask none{4, 4, std::vector<std::uint8_t>(16, 0)};
  EXPECT_NE(error_of([&] { metrics::noise_corrected_relmse(ok, ok, ok, none); }).find("selects no pixels"), std::string::npos);
  Mask wrong{2, 2, std::vector<std::uint8_t>(4, 1)};
  EXPECT_NE(error_of([&] { metrics::noise_corrected_relmse(ok, ok, ok, wrong); }).find("mask is 2x2"), std::string::npos);
}
