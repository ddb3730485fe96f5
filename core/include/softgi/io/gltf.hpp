// glTF 2.0 / GLB through tinygltf, including skins, animations and KHR_draco_mesh_compression
// (the only translation units that include tinygltf and draco: core/src/io/gltf*.cpp).
#pragma once

#include <string>
#include <vector>

#include "softgi/scene/scene.hpp"

namespace softgi::io {

struct GltfImport {
  std::vector<int> root_nodes;  // nodes added to the scene without parent
  std::vector<int> clips;       // clips added
  int meshes_added = 0;
};

// Appends the file's meshes (one Mesh per primitive, triangles only), materials (base colour factor
// and texture), textures, nodes, skins and animations to `scene`. Normals are required: a primitive
// without NORMAL is an error (flat normals are not invented). Throws std::runtime_error naming the
// file and what is wrong (missing file, parse error, unsupported primitive mode, bad accessor, ...).
GltfImport load_gltf(const std::string& path, scene::Scene& scene);

}  // namespace softgi::io
