// Monte Carlo ground truth with Embree (the only translation units that include Embree:
// core/src/reference/*.cpp).
#pragma once

#include <functional>
#include <string>

#include "softgi/image.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::reference {

struct ReferenceOptions {
  int spp = 64;                 // samples per pixel
  enum class Blockers { Geometry, Proxies } blockers = Blockers::Geometry;  // what casts shadows
  int light_sh_order = 0;       // 0: full environment; n: its order-n SH projection (paper 004 Fig. 7)
  bool indirect = true;         // one-bounce diffuse indirect
  double time = 0.0;            // animation time (seconds)
  unsigned seed = 1;            // deterministic: same seed and spp give identical images
  int width = 0, height = 0;    // 0: the scene camera's
};
struct ReferenceResult {
  Image direct, indirect, final_image;  // final = direct + indirect, outgoing radiance
  double seconds = 0.0;
  double seconds_per_sample = 0.0;      // per spp over the whole image
  long long rays = 0;
};

// Renders the scene at options.time. progress(fraction) is called from the calling thread.
ReferenceResult render_reference(const scene::Scene& scene, const ReferenceOptions& opt,
                                 const std::function<void(double)>& progress = {});

}  // namespace softgi::reference
