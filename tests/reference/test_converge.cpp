// render_converged_reference (core/src/reference/converge.cpp): the target is met, the halves are the
// seeded renders, the sample count follows the 1 / spp law, the cap is honoured and reported, the noise
// estimate agrees with the error against an independent, much longer render, and bad options are errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "softgi/metrics/image_metrics.hpp"
#include "softgi/metrics/reference_noise.hpp"
#include "softgi/reference/converge.hpp"
#include "softgi/scene/builtin.hpp"

#include "../support/thrown_message.hpp"

namespace softgi::reference {
namespace {

// The built-in spheres on their plane, 48 pixels wide: direct light and one-bounce indirect both noisy.
scene::Scene small_spheres() {
  scene::Scene s = scene::make_builtin("spheres");
  s.camera.height = std::max(1, 48 * s.camera.height / std::max(1, s.camera.width));
  s.camera.width = 48;
  return s;
}

using test::thrown_message;

TEST(Converge, MeetsTheTargetAndItsHalvesAreTheSeededRenders) {
  const scene::Scene s = small_spheres();
  ReferenceOptions opt;
  opt.seed = 5;
  ConvergeOptions c;
  c.target_noise = 2e-3;
  c.min_spp = 4;
  const ConvergedReference r = render_converged_reference(s, opt, c);
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.noise, c.target_noise);
  EXPECT_GT(r.noise, 0.0);  // a Monte Carlo render has noise: the estimate is not trivially 0
  // 4 spp is far from 2e-3 on this scene, so at least one more round ran, each with more samples.
  ASSERT_GE(r.rounds.size(), 2u);
  for (std::size_t i = 1; i < r.rounds.size(); ++i) EXPECT_GT(r.rounds[i].spp, r.rounds[i - 1].spp);
  EXPECT_EQ(r.rounds.front().spp, 4);
  EXPECT_EQ(r.result.spp, r.rounds.back().spp);
  EXPECT_EQ(r.rounds.back().noise, r.noise);
  // The halves are exactly the renders with the two seeds at half the samples.
  ReferenceOptions a = opt, b = opt;
  a.spp = b.spp = r.result.spp / 2;
  b.seed = half_b_seed(opt.seed);
  EXPECT_NE(b.seed, opt.seed);
  EXPECT_EQ(r.half_a.final_image.rgb, render_reference(s, a).final_image.rgb);
  EXPECT_EQ(r.half_b.final_image.rgb, render_reference(s, b).final_image.rgb);
  EXPECT_EQ(r.result.final_image.rgb, metrics::mean_of_halves(r.half_a.final_image, r.half_b.final_image).rgb);
  EXPECT_EQ(r.result.indirect.rgb, metrics::mean_of_halves(r.half_a.indirect, r.half_b.indirect).rgb);
  // The noise is averaged over the lit pixels: the spheres and the plane fill most of the frame.
  const long long all = static_cast<long long>(r.result.final_image.rgb.size());
  EXPECT_GT(r.pixels, all / 4);
  EXPECT_LE(r.pixels, all);
}

TEST(Converge, TheNextRoundFollowsTheOneOverSppLaw) {
  const scene::Scene s = small_spheres();
  ConvergeOptions c;
  c.target_noise = 1e-3;
  c.min_spp = 4;
  c.max_spp = 1 << 16;
  const ConvergedReference r = render_converged_reference(s, ReferenceOptions{}, c);
  ASSERT_GE(r.rounds.size(), 2u);
  const ConvergeRound& first = r.rounds[0];
  // spp_next / 2 = max(ceil(spp / 2 * noise / target * 1.2), spp): the prediction, at least doubled.
  const double predicted = std::ceil(0.5 * first.spp * first.noise / c.target_noise * 1.2);
  EXPECT_EQ(r.rounds[1].spp, 2 * static_cast<int>(std::max(predicted, static_cast<double>(first.spp))));
  // noise * spp is about constant (Monte Carlo variance ~ 1 / spp). A factor of 2 either way allows for
  // the estimate's own spread at 4 spp and for relMSE's weights 1 / (r^2 + eps) changing as r converges.
  const double c0 = first.noise * first.spp, c1 = r.rounds[1].noise * r.rounds[1].spp;
  EXPECT_GT(c1, 0.5 * c0);
  EXPECT_LT(c1, 2.0 * c0);
}

TEST(Converge, NoiseEstimateMatchesTheErrorAgainstAMuchLongerRender) {
  const scene::Scene s = small_spheres();
  ConvergeOptions c;
  c.target_noise = 4e-3;
  c.min_spp = 8;
  const ConvergedReference r = render_converged_reference(s, ReferenceOptions{}, c);
  ASSERT_TRUE(r.converged);
  // An independent render with 16 times the samples stands in for the converged image: its own noise adds
  // about noise / 16 to the error of r against it.
  ReferenceOptions longer;
  longer.seed = 1234567;
  longer.spp = 16 * r.result.spp;
  const Image truth = render_reference(s, longer).final_image;
  // The error is measured over the pixels the noise was (the lit ones) with the same epsilon.
  Mask lit{truth.width, truth.height, std::vector<std::uint8_t>(truth.rgb.size(), 0)};
  for (std::size_t i = 0; i < lit.on.size(); ++i) {
    const glm::vec3 v = r.half_a.final_image.rgb[i] + r.half_b.final_image.rgb[i];
    lit.on[i] = (v.r > 0.0f || v.g > 0.0f || v.b > 0.0f) ? 1 : 0;
  }
  metrics::MetricOptions mo;
  mo.relmse_epsilon = c.relmse_epsilon;
  const double observed = metrics::compare(r.result.final_image, truth, lit, mo).relmse;
  const double expected = r.noise * (1.0 + 1.0 / 16.0);
  // Both the estimate (from one pair of halves) and the observed error (one realisation) scatter by
  // about sqrt(2 / pixels) of their size over ~1000 independent pixels, more where a few bright pixels
  // dominate; a factor of 1.5 either way is beyond that and well inside the factor of 2 by which an
  // estimator that forgot the halves' mean (noise of one half, not of their mean) would miss.
  EXPECT_GT(observed, expected / 1.5) << "observed " << observed << ", estimated " << expected;
  EXPECT_LT(observed, expected * 1.5) << "observed " << observed << ", estimated " << expected;
}

TEST(Converge, StopsAtTheCapAndSaysSo) {
  const scene::Scene s = small_spheres();
  ConvergeOptions c;
  c.target_noise = 1e-12;
  c.min_spp = 4;
  c.max_spp = 16;
  const ConvergedReference r = render_converged_reference(s, ReferenceOptions{}, c);
  EXPECT_FALSE(r.converged);
  EXPECT_GT(r.noise, c.target_noise);
  ASSERT_EQ(r.rounds.size(), 2u);  // 4, then the prediction (far above) clamped to the cap
  EXPECT_EQ(r.rounds[0].spp, 4);
  EXPECT_EQ(r.rounds[1].spp, 16);
  EXPECT_EQ(r.result.spp, 16);
}

TEST(Converge, RejectsBadOptions) {
  const scene::Scene s = small_spheres();
  auto msg = [&](ConvergeOptions c) { return thrown_message([&] { render_converged_reference(s, ReferenceOptions{}, c); }); };
  ConvergeOptions c;
  c.target_noise = 0.0;
  EXPECT_NE(msg(c).find("target noise must be a finite number > 0, got 0"), std::string::npos) << msg(c);
  c.target_noise = std::nan("");
  EXPECT_NE(msg(c).find("target noise"), std::string::npos);
  c = {};
  c.min_spp = 3;
  EXPECT_NE(msg(c).find("even and >= 2"), std::string::npos) << msg(c);
  c = {};
  c.max_spp = 8;
  EXPECT_NE(msg(c).find("largest spp must be even and >= the first round's 16, got 8"), std::string::npos) << msg(c);
  c = {};
  c.relmse_epsilon = -1.0;
  EXPECT_NE(msg(c).find("epsilon"), std::string::npos);
  c = {};
  c.mask = Mask{3, 3, std::vector<std::uint8_t>(9, 1)};
  EXPECT_NE(msg(c).find("mask"), std::string::npos) << msg(c);
}

}  // namespace
}  // namespace softgi::reference
