// A disk cache of rendered references (ground-truth images), keyed by the content of what they
// depend on, so that compare and experiments render a reference once per scene, frame and settings.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "softgi/image.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::io {

// 64-bit FNV-1a over everything a rendering of `scene` can depend on: meshes (positions, normals,
// uvs, colours, triangles, material, skin joints and weights), materials, textures, nodes, skins,
// animation clips and the active one, proxy sets, camera, environment (the map's pixels included)
// and lights. Names, the source path and notices are not part of it: two scenes that differ only
// there render the same images.
std::uint64_t scene_content_hash(const scene::Scene& scene);

// The entry key: the scene hash and an FNV-1a of `settings` (every option of the render and the
// renderer's version, as text), both in hex.
std::string reference_cache_key(std::uint64_t scene_hash, const std::string& settings);

struct CachedReference {
  Image direct, indirect, final_image;
  double seconds = 0.0;  // the render's own wall time, when it was made
  long long rays = 0;
  int spp = 0;
};

// The folder of the entry `key` (hex digits) under proxy_cache_dir()/references, or "" when caching
// is off (SOFTGI_CACHE_DIR=off or no cache folder).
std::string reference_cache_entry(const std::string& key);

// The entry's images when it is complete and readable (its meta.json is written last, so a render
// interrupted while writing leaves no entry); nullopt otherwise, with `why` saying what was missing
// or unreadable ("" when there is simply no entry).
std::optional<CachedReference> read_cached_reference(const std::string& key, std::string& why);
// Writes the entry (each file atomically, meta.json last); `description` is kept in meta.json so a
// person can tell what an entry holds. Does nothing when caching is off; a failure to write is an
// exception naming the folder.
void write_cached_reference(const std::string& key, const CachedReference& ref, const std::string& description);

}  // namespace softgi::io
