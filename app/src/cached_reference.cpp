// Reference renders through the disk cache (cached_reference.hpp).
#include "cached_reference.hpp"

#include <algorithm>
#include <cstdint>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <sstream>

#include "frame_output.hpp"
#include "softgi/io/reference_cache.hpp"
#include "softgi/metrics/reference_noise.hpp"
#include "softgi/proxies/self_shadow.hpp"

namespace softgi::app {

namespace {

std::string settings_text(const reference::ReferenceOptions& opt) {
  std::ostringstream settings;
  settings.precision(17);
  settings << "renderer " << kReferenceRendererVersion << " softgi " << softgi_version() << " spp " << opt.spp << " blockers "
           << static_cast<int>(opt.blockers) << " rule " << static_cast<int>(opt.replacement_rule) << " light_sh_order "
           << opt.light_sh_order << " indirect " << opt.indirect << " time " << opt.time << " seed " << opt.seed << " size "
           << opt.width << "x" << opt.height << " jitter " << opt.jitter;
  return settings.str();
}

reference::ReferenceResult from_cache(io::CachedReference&& hit) {
  reference::ReferenceResult r;
  r.direct = std::move(hit.direct);
  r.indirect = std::move(hit.indirect);
  r.final_image = std::move(hit.final_image);
  r.seconds = hit.seconds;
  r.rays = hit.rays;
  r.spp = hit.spp;
  return r;
}

}  // namespace

reference::ReferenceResult cached_reference(const scene::Scene& scene, const reference::ReferenceOptions& opt,
                                            const std::function<void(double)>& progress, bool& cached) {
  const std::string settings = settings_text(opt);
  const std::string key = io::reference_cache_key(io::scene_content_hash(scene), settings);
  std::string why;
  if (auto hit = io::read_cached_reference(key, why)) {
    cached = true;
    if (progress) progress(1.0);
    return from_cache(std::move(*hit));
  }
  if (!why.empty()) std::cerr << "softgi: " << why << "; rendering it again\n";
  cached = false;
  reference::ReferenceResult r = reference::render_reference(scene, opt, progress);
  io::CachedReference c{r.direct, r.indirect, r.final_image, r.seconds, r.rays, r.spp};
  try {
    io::write_cached_reference(key, c, "scene '" + scene.name + "', " + settings);
  } catch (const std::exception& e) {
    std::cerr << "softgi: the reference was rendered but not cached: " << e.what() << "\n";
  }
  return r;
}

reference::ConvergedReference cached_converged_reference(
    const scene::Scene& scene, const reference::ReferenceOptions& opt, const reference::ConvergeOptions& converge,
    const std::function<void(int round, int spp, double fraction)>& progress, bool& cached) {
  reference::ReferenceOptions base = opt;
  base.spp = 0;  // the rounds choose it
  std::ostringstream conv;
  conv.precision(17);
  conv << " converged target " << converge.target_noise << " first " << converge.min_spp << " cap " << converge.max_spp
       << " epsilon " << converge.relmse_epsilon;
  // The pixels the noise is measured over decide when the rounds stop: a masked convergence is keyed
  // by the mask's content.
  if (!converge.mask.on.empty())
    conv << " mask " << converge.mask.width << "x" << converge.mask.height << " "
         << io::reference_cache_key(0, std::string(converge.mask.on.begin(), converge.mask.on.end()));
  const std::string settings = settings_text(base) + conv.str();
  const std::uint64_t hash = io::scene_content_hash(scene);
  const std::string key_a = io::reference_cache_key(hash, settings + " half a");
  const std::string key_b = io::reference_cache_key(hash, settings + " half b");
  std::string why_a, why_b;
  auto a = io::read_cached_reference(key_a, why_a);
  auto b = a ? io::read_cached_reference(key_b, why_b) : std::nullopt;
  if (a && b) {
    cached = true;
    reference::ConvergedReference c;
    c.half_a = from_cache(std::move(*a));
    c.half_b = from_cache(std::move(*b));
    c.result.final_image = metrics::mean_of_halves(c.half_a.final_image, c.half_b.final_image);
    c.result.direct = metrics::mean_of_halves(c.half_a.direct, c.half_b.direct);
    c.result.indirect = metrics::mean_of_halves(c.half_a.indirect, c.half_b.indirect);
    c.result.spp = c.half_a.spp + c.half_b.spp;
    c.result.seconds = c.half_a.seconds;  // written as the whole render's time (below)
    c.result.rays = c.half_a.rays + c.half_b.rays;
    // The noise over the pixels the convergence measured it on: the mask, or those lit in either half.
    const Mask lit = converge.mask.on.empty() ? reference::lit_pixels(c.half_a.final_image, c.half_b.final_image) : converge.mask;
    if (std::any_of(lit.on.begin(), lit.on.end(), [](std::uint8_t v) { return v != 0; })) {
      const metrics::NoiseCorrectedError e = metrics::noise_corrected_relmse(
          c.result.final_image, c.half_a.final_image, c.half_b.final_image, lit, converge.relmse_epsilon);
      c.noise = e.noise;
      c.pixels = e.pixels;
    }
    c.converged = c.noise <= converge.target_noise;
    return c;
  }
  for (const std::string& why : {why_a, why_b})
    if (!why.empty()) std::cerr << "softgi: " << why << "; rendering it again\n";
  cached = false;
  reference::ConvergedReference c = reference::render_converged_reference(scene, opt, converge, progress);
  try {
    const std::string what = "scene '" + scene.name + "', " + settings;
    io::write_cached_reference(key_a, {c.half_a.direct, c.half_a.indirect, c.half_a.final_image, c.result.seconds, c.half_a.rays,
                                       c.half_a.spp},
                               what + " half a");
    io::write_cached_reference(key_b, {c.half_b.direct, c.half_b.indirect, c.half_b.final_image, c.result.seconds, c.half_b.rays,
                                       c.half_b.spp},
                               what + " half b");
  } catch (const std::exception& e) {
    std::cerr << "softgi: the converged reference was rendered but not cached: " << e.what() << "\n";
  }
  return c;
}

}  // namespace softgi::app
