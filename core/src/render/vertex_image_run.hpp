// The vector kernel of interpolate_vertex_values (vertex_image.cpp): a run of pixels that see one
// object, in vector lanes. Not installed.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

namespace softgi::render::detail {

// Pixels t = 0 .. n-1, each seeing triangle primitive[t] of a mesh with triangles `tri` at
// barycentrics barycentric[t]: out[t] = (1 - b1 - b2) v[a] + b1 v[b] + b2 v[c] with v = values (one
// per vertex), then times albedo[t] where `albedo` is not null, else times `uniform` where
// `times_uniform`. False, with nothing written, where a primitive lies outside [0, triangles): the
// caller names it.
bool interpolate_run(const glm::uvec3* tri, int triangles, const glm::vec3* values, const std::int32_t* primitive,
                     const glm::vec2* barycentric, int n, const glm::vec3* albedo, bool times_uniform,
                     const glm::vec3& uniform, glm::vec3* out);

// The unit camera rays of pixels t = 0 .. n-1 of one buffer row: out[t] = glm::normalize(forward +
// sx[t] right + sy up) (render::BufferRays::direction, to the bit).
void ray_directions(const glm::vec3& forward, const glm::vec3& right, const glm::vec3& up, const float* sx, float sy, int n,
                    glm::vec3* out);

}  // namespace softgi::render::detail
