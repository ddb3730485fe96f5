// The JSON scene file (docs/scene_format.md): references glTF/GLB meshes, environment maps,
// cameras, animation clips and proxy sets.
#pragma once

#include <string>

#include "softgi/io/proxy_fit.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::io {

struct LoadOptions {
  // Fit the proxy sets a scene file asks for (an object's "proxies": {"fit": N}). Off, such objects
  // get none and a notice says so (the fuzzer's setting: a fit takes seconds).
  bool fit_proxies = true;
  // Fit this many spheres to every node with a closed mesh and no proxy set after loading (the CLI's
  // --fit-proxies N, for a bare glTF/GLB that has no proxies of its own); 0: none.
  int fit_spheres = 0;
  // Where fits are cached (proxy_fit.hpp); "" caches nothing on disk.
  std::string cache_dir = proxy_cache_dir();
};

// Parses a scene file. Relative paths resolve against the file's directory. Errors are
// std::runtime_error naming the file, the JSON path of the field and the value, e.g.
//   "scene.json: objects[2].transform.translation[1]: expected a finite number, got "nan""
scene::Scene load_scene_file(const std::string& path, const LoadOptions& opt = {});
// The same from text (base_dir for relative paths); what the fuzzer drives.
scene::Scene parse_scene_json(const std::string& text, const std::string& base_dir, const std::string& name_for_errors,
                              const LoadOptions& opt = {});

// A built-in name (scene::builtin_scenes) or a path to a scene file.
// opt.fit_spheres applies to every kind of scene.
scene::Scene load_scene(const std::string& spec, const LoadOptions& opt = {});

// Writes a proxy set as JSON (the format `softgi fit-proxies -o` produces and scene files reference),
// and reads it back.
void write_proxies_json(const std::string& path, const scene::ProxySet& proxies);
scene::ProxySet read_proxies_json(const std::string& path);

}  // namespace softgi::io
