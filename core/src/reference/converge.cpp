// Rendering a reference until its noise meets a target (docs/reference.md, "Rendering until converged").
#include "softgi/reference/converge.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <sstream>
#include <stdexcept>
#include <string>

#include "softgi/metrics/reference_noise.hpp"
#include "softgi/render/camera.hpp"

namespace softgi::reference {

namespace {

// The estimate of the noise is itself noisy; asking for 20 % more samples than the 1 / spp law predicts
// makes a second round that falls just short of the target rare.
constexpr double kSppMargin = 1.2;

void check(const ConvergeOptions& c) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("reference convergence: " + what); };
  if (!std::isfinite(c.target_noise) || c.target_noise <= 0.0) {
    std::ostringstream os;
    os << "target noise must be a finite number > 0, got " << c.target_noise;
    fail(os.str());
  }
  if (c.min_spp < 2 || c.min_spp % 2 != 0)
    fail("the first round's spp must be even and >= 2 (two equal halves), got " + std::to_string(c.min_spp));
  if (c.max_spp < c.min_spp || c.max_spp % 2 != 0)
    fail("the largest spp must be even and >= the first round's " + std::to_string(c.min_spp) + ", got " +
         std::to_string(c.max_spp));
  if (!std::isfinite(c.relmse_epsilon) || c.relmse_epsilon <= 0.0) fail("relMSE epsilon must be finite and > 0");
}

}  // namespace

Mask lit_pixels(const Image& a, const Image& b) {
  Mask m{a.width, a.height, std::vector<std::uint8_t>(a.rgb.size(), 0)};
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const glm::vec3 s = a.rgb[i] + b.rgb[i];
    m.on[i] = (s.r > 0.0f || s.g > 0.0f || s.b > 0.0f) ? 1 : 0;
  }
  return m;
}

unsigned half_b_seed(unsigned seed) { return seed ^ 0x9E3779B9u; }

ConvergedReference render_converged_reference(const scene::Scene& scene, const ReferenceOptions& opt,
                                              const ConvergeOptions& converge,
                                              const std::function<void(int, int, double)>& progress) {
  check(converge);
  if (!converge.mask.on.empty()) {
    // The size render_reference will use, so that a wrong mask fails before any rendering.
    int w = opt.width, h = opt.height;
    render::resolve_resolution(scene.camera, w, h);
    if (converge.mask.width != w || converge.mask.height != h || converge.mask.on.size() != std::size_t(w) * std::size_t(h))
      throw std::invalid_argument("reference convergence: the mask is " + std::to_string(converge.mask.width) + "x" +
                                  std::to_string(converge.mask.height) + ", the image " + std::to_string(w) + "x" +
                                  std::to_string(h));
  }
  ConvergedReference out;
  double total_seconds = 0.0;
  int half = converge.min_spp / 2;
  for (int round = 0;; ++round) {
    ReferenceOptions a = opt, b = opt;
    a.spp = b.spp = half;
    b.seed = half_b_seed(opt.seed);
    const int spp = 2 * half;
    auto report = [&](double base) {
      return [&, base](double f) {
        if (progress) progress(round, spp, base + 0.5 * f);
      };
    };
    out.half_a = render_reference(scene, a, report(0.0));
    out.half_b = render_reference(scene, b, report(0.5));
    const Mask mask = converge.mask.on.empty() ? lit_pixels(out.half_a.final_image, out.half_b.final_image) : converge.mask;
    const bool any = std::any_of(mask.on.begin(), mask.on.end(), [](std::uint8_t v) { return v != 0; });
    // Nothing received light: there is no noise to measure, and the (black) image is exact.
    double noise = 0.0;
    long long pixels = 0;
    if (any || !converge.mask.on.empty()) {
      const Image mean = metrics::mean_of_halves(out.half_a.final_image, out.half_b.final_image);
      const metrics::NoiseCorrectedError e =
          metrics::noise_corrected_relmse(mean, out.half_a.final_image, out.half_b.final_image, mask, converge.relmse_epsilon);
      noise = e.noise;
      pixels = e.pixels;
    }
    const double seconds = out.half_a.seconds + out.half_b.seconds;
    total_seconds += seconds;
    out.rounds.push_back({spp, noise, seconds});
    out.noise = noise;
    out.pixels = pixels;
    out.converged = noise <= converge.target_noise;
    if (out.converged || spp >= converge.max_spp) break;
    // noise ~ c / spp: the count that reaches the target, with margin, at least doubled.
    const double predicted = std::ceil(0.5 * spp * (noise / converge.target_noise) * kSppMargin);
    const double next = std::clamp(std::max(predicted, 2.0 * half), 1.0, 0.5 * converge.max_spp);
    half = static_cast<int>(next);
  }
  auto mean = [](const Image& a, const Image& b) { return a.empty() ? Image() : metrics::mean_of_halves(a, b); };
  ReferenceResult& r = out.result;
  r.direct = mean(out.half_a.direct, out.half_b.direct);
  r.indirect = mean(out.half_a.indirect, out.half_b.indirect);
  r.final_image = mean(out.half_a.final_image, out.half_b.final_image);
  r.seconds = total_seconds;
  r.setup_seconds = out.half_a.setup_seconds + out.half_b.setup_seconds;
  r.rays = out.half_a.rays + out.half_b.rays;
  r.spp = out.half_a.spp + out.half_b.spp;
  r.seconds_per_sample = 0.5 * (out.half_a.seconds_per_sample + out.half_b.seconds_per_sample);
  return out;
}

}  // namespace softgi::reference
