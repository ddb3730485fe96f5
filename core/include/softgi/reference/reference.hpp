// Monte Carlo ground truth with Embree (kept inside the reference library's sources,
// core/src/reference/*.cpp).
#pragma once

#include <functional>
#include <string>

#include "softgi/image.hpp"
#include "softgi/proxies/self_shadow.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::reference {

struct ReferenceOptions {
  int spp = 64;                 // samples per pixel
  // What casts shadows. Geometry: the scene's triangles. Proxies: every proxy sphere, plus the
  // triangles of the objects no proxy set stands for (paper 004 Figure 7(b): only the blockers that
  // have sphere sets are replaced). ProxiesOnly: the problem a sphere-proxy technique solves: the
  // proxy spheres alone cast shadows, and an object without proxies (a wall, the ground) is a
  // receiver only: it shadows nothing and reflects no light onto other surfaces. Bounce points are
  // on the real triangles, of the proxied objects alone in ProxiesOnly mode.
  enum class Blockers { Geometry, Proxies, ProxiesOnly } blockers = Blockers::Geometry;
  // Proxies mode: what a sphere becomes for a receiver near it (paper 004 section 6.2), the rules
  // the accumulation techniques apply (softgi/proxies/self_shadow.hpp); printed is rejected.
  proxies::ReplacementRule replacement_rule = proxies::kDefaultReplacementRule;
  int light_sh_order = 0;       // 0: full environment; n: its order-n SH projection (paper 004 Fig. 7)
  bool indirect = true;         // one-bounce diffuse indirect
  double time = 0.0;            // animation time (seconds)
  unsigned seed = 1;            // deterministic: same seed and spp give identical images
  int width = 0, height = 0;    // 0: the scene camera's
  bool jitter = true;           // box-filter each pixel; false: every sample through the pixel centre
                                // (the visibility a one-sample-per-pixel rasteriser sees)
};
struct ReferenceResult {
  Image direct, indirect, final_image;  // final = direct + indirect, outgoing radiance
  double seconds = 0.0;                 // wall time, setup included
  double setup_seconds = 0.0;           // posing, BVH builds, environment tables
  double seconds_per_sample = 0.0;      // per spp over the whole image (sampling time / spp)
  long long rays = 0;                   // primary + shadow + indirect rays traced
  int spp = 0;                          // samples per pixel in these images
};

// Called after each progressive pass with the running estimate at spp_done samples per pixel
// (1, 2, 4, ..., then opt.spp). Sample k of a pixel depends only on (seed, pixel, k), so the running
// estimate at spp_done equals a render with spp = spp_done.
using PassCallback = std::function<void(int spp_done, const ReferenceResult& running)>;

// Renders the scene at options.time (docs/reference.md). progress(fraction) and on_pass are called
// from the calling thread. Throws std::invalid_argument naming the option or scene field for bad
// input (spp <= 0, SH order outside 1..8, absurd sizes, non-finite time, proxies requested for a
// scene without proxy sets, the printed replacement rule, degenerate camera).
ReferenceResult render_reference(const scene::Scene& scene, const ReferenceOptions& opt,
                                 const std::function<void(double)>& progress = {},
                                 const PassCallback& on_pass = {});

}  // namespace softgi::reference
