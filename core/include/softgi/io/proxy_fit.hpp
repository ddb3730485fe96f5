// Proxy sphere sets fitted on demand (paper 004 section 6.2) for scenes that ask for them (a scene
// file's `"proxies": {"fit": N}`, a bare glTF with --fit-proxies N, the built-in bunny), with a disk
// cache keyed by everything the fit's result depends on.
#pragma once

#include <cstdint>
#include <string>

#include "softgi/proxies/sphere_fit.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::io {

// The version of the fitting code's result: part of every cache key, so a change to the fit
// (proxies::fit_sphere_set), the skin binding or the albedo average that alters what is produced
// must increase it, and stale cache entries are then never read.
inline constexpr int kProxyFitVersion = 1;

// What a fit is asked for; the same fields a scene file's `"proxies": {"fit": N, ...}` and
// `softgi fit-proxies` take.
struct ProxyFitSpec {
  int spheres = 32;
  unsigned seed = 1;
  int iterations = 60;
  int grid = 32;
  proxies::FitOptions options() const;
};

// The cache folder for fitted proxy sets: $SOFTGI_CACHE_DIR, else $XDG_CACHE_HOME/softgi, else
// $HOME/.cache/softgi; "" (no caching) when SOFTGI_CACHE_DIR is "off" or no folder can be named.
std::string proxy_cache_dir();

// 64-bit FNV-1a over everything the fit of node `node` depends on: the mesh (positions, triangles,
// skin joints and weights, uvs, colours), its material and albedo texture, the spec and
// kProxyFitVersion. Node transforms are not part of it: proxies live in the mesh's space.
std::uint64_t proxy_fit_key(const scene::Scene& scene, int node, const ProxyFitSpec& spec);

// The surface albedo of each sphere of `set`: the area-weighted average of the mesh's albedo (base
// colour x texture x vertex colour, as the renderers shade it) over the triangles the sphere bounds
// (its segment: the sphere whose surface a triangle's centroid lies deepest inside), with enough
// samples per triangle to cover the texels it spans. Fills set.sphere_albedo and sets set.albedo to
// the average over the whole surface. A sphere that bounds no triangle takes that average.
void average_surface_albedo(const scene::Scene& scene, int node, scene::ProxySet& set);

struct ProxyFitOutcome {
  scene::ProxySet set;
  bool from_cache = false;
  std::string cache_file;  // "" without a cache
  double seconds = 0.0;    // fit time (0 when read from the cache)
  double E = 0.0;          // outside-volume ratio of the fit (paper 004 eq. 35 / V(T))
};

// The proxy set of node `node`'s mesh: read from `cache_dir` when an entry for proxy_fit_key is
// there and readable, else fitted (proxies::fit_sphere_set), bound to the skin when the mesh is
// skinned (proxies::bind_to_skin), given surface albedos (average_surface_albedo) and stored there
// (through a temporary file, so concurrent runs never read half an entry). A corrupt entry is
// refitted and replaced. Throws std::invalid_argument naming the node when its mesh is not closed.
ProxyFitOutcome fit_node_proxies(const scene::Scene& scene, int node, const ProxyFitSpec& spec, const std::string& cache_dir);

// Gives every node with a closed mesh and no proxy set yet a fitted set (fit_node_proxies) and adds
// a Scene::notices line for each fit (fitted or cached, spheres, E, seconds) and for each mesh node
// left without one (open surfaces such as ground planes, which bound no volume). Returns the number
// of sets added.
int fit_missing_proxies(scene::Scene& scene, const ProxyFitSpec& spec, const std::string& cache_dir);

}  // namespace softgi::io
