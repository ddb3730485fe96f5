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
// and texture), textures, nodes, skins and animations to `scene`. Throws std::runtime_error naming
// the file and what is wrong (missing file, parse error, JSON nested deeper than 64 levels,
// unsupported primitive mode, bad accessor, node transform out of range, ...); a failed load leaves
// `scene` as it was. What the load assumed goes to Scene::notices, naming the file and primitive:
// a primitive without NORMAL gets flat normals (glTF 2.0 section 3.7.2.1; its vertices are split,
// three per triangle), and one without TEXCOORD_0 whose material has a base colour texture gets a
// copy of that material without the texture.
//
// Node numbering: the nodes are appended depth first from the roots of the file's default scene
// (children in their listed order), then one child node per primitive after a mesh's first. The
// proxy file's `node` is an index in this numbering, counted from the first node load_gltf adds
// (so it is the scene node index when the file is loaded alone, as `softgi fit-proxies` does); it
// is not the index into the file's own `nodes` array.
GltfImport load_gltf(const std::string& path, scene::Scene& scene);

}  // namespace softgi::io
