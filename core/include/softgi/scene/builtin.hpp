// Built-in scenes: no files needed (bunny needs the asset set, see scripts/fetch-assets.sh).
#pragma once

#include <string>
#include <vector>

#include "softgi/scene/scene.hpp"

namespace softgi::scene {

struct BuiltinInfo {
  std::string name, description;
  bool needs_assets = false;
};
std::vector<BuiltinInfo> builtin_scenes();  // spheres, cornell, character, crowd, sphere_plane, box1, box8, bend, assembly, bunny

// Throws std::invalid_argument naming the unknown scene and listing the known ones; throws
// std::runtime_error naming the missing file when assets are needed and absent.
Scene make_builtin(const std::string& name);

// Directory holding the decoded assets: $SOFTGI_ASSETS if set, else <source tree>/assets.
std::string assets_dir();

}  // namespace softgi::scene
