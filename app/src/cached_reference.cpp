// Reference renders through the disk cache (cached_reference.hpp).
#include "cached_reference.hpp"

#include <iostream>
#include <sstream>

#include "frame_output.hpp"
#include "softgi/io/reference_cache.hpp"
#include "softgi/proxies/self_shadow.hpp"

namespace softgi::app {

reference::ReferenceResult cached_reference(const scene::Scene& scene, const reference::ReferenceOptions& opt,
                                            const std::function<void(double)>& progress, bool& cached) {
  std::ostringstream settings;
  settings.precision(17);
  settings << "renderer " << kReferenceRendererVersion << " softgi " << softgi_version() << " spp " << opt.spp << " blockers "
           << static_cast<int>(opt.blockers) << " rule " << static_cast<int>(opt.replacement_rule) << " light_sh_order "
           << opt.light_sh_order << " indirect " << opt.indirect << " time " << opt.time << " seed " << opt.seed << " size "
           << opt.width << "x" << opt.height << " jitter " << opt.jitter;
  const std::string key = io::reference_cache_key(io::scene_content_hash(scene), settings.str());
  std::string why;
  if (auto hit = io::read_cached_reference(key, why)) {
    cached = true;
    reference::ReferenceResult r;
    r.direct = std::move(hit->direct);
    r.indirect = std::move(hit->indirect);
    r.final_image = std::move(hit->final_image);
    r.seconds = hit->seconds;
    r.rays = hit->rays;
    r.spp = hit->spp;
    if (progress) progress(1.0);
    return r;
  }
  if (!why.empty()) std::cerr << "softgi: " << why << "; rendering it again\n";
  cached = false;
  reference::ReferenceResult r = reference::render_reference(scene, opt, progress);
  io::CachedReference c{r.direct, r.indirect, r.final_image, r.seconds, r.rays, r.spp};
  try {
    io::write_cached_reference(key, c, "scene '" + scene.name + "', " + settings.str());
  } catch (const std::exception& e) {
    std::cerr << "softgi: the reference was rendered but not cached: " << e.what() << "\n";
  }
  return r;
}

}  // namespace softgi::app
