// The JSON scene file (docs/scene_format.md): references glTF/GLB meshes, environment maps,
// cameras, animation clips and proxy sets.
#pragma once

#include <string>

#include "softgi/scene/scene.hpp"

namespace softgi::io {

// Parses a scene file. Relative paths resolve against the file's directory. Errors are
// std::runtime_error naming the file, the JSON path of the field and the value, e.g.
//   "scene.json: objects[2].transform.translation[1]: expected a finite number, got "nan""
scene::Scene load_scene_file(const std::string& path);
// The same from text (base_dir for relative paths); what the fuzzer drives.
scene::Scene parse_scene_json(const std::string& text, const std::string& base_dir, const std::string& name_for_errors);

// A built-in name (scene::builtin_scenes) or a path to a scene file.
scene::Scene load_scene(const std::string& spec);

// Writes a proxy set as JSON (the format `softgi fit-proxies -o` produces and scene files reference),
// and reads it back.
void write_proxies_json(const std::string& path, const scene::ProxySet& proxies);
scene::ProxySet read_proxies_json(const std::string& path);

}  // namespace softgi::io
