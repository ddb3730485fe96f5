// Proxies that follow animation (paper 004 section 6.2, Animation): sphere centres expressed as
// weights of the rest-pose mesh (mean value coordinates), premultiplied by the vertices' bone
// weights so each centre is a combination of a few bones.
#pragma once

#include <vector>

#include "softgi/scene/scene.hpp"

namespace softgi::proxies {

// Mean value coordinates of point x with respect to a closed triangle mesh (Ju, Schaefer, Warren
// 2005 / Floater et al. 2005): weights per vertex, summing to 1, reproducing x exactly.
std::vector<double> mean_value_coordinates(const glm::vec3& x, const std::vector<glm::vec3>& positions,
                                           const std::vector<glm::uvec3>& triangles);

// Fills proxies.joints / proxies.weights for a skinned mesh: MVC weights times the vertices' bone
// weights, reduced to the 4 largest bones and renormalised. The rest-pose centre is reproduced
// exactly before the reduction; the reduction error is reported (max distance, in mesh units).
double bind_to_skin(scene::ProxySet& proxies, const scene::Mesh& mesh);

}  // namespace softgi::proxies
