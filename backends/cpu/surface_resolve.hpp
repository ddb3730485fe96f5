// The surface attributes of a run of G-buffer pixels that see one object (gbuffer_cpu.cpp's resolve):
// position, shading normal, depth and view direction from each pixel's triangle and barycentrics,
// across the pixels of the run in vector lanes. The arithmetic is that of the reference renderer's
// per-hit rule (embree::triangle_surface and surface_at in core/src/embree/embree_setup.hpp), done
// in the same order, so that every pixel gets the same bits; gbuffer_cpu.cpp's
// surface_resolve_differences checks it.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include <cstddef>

#include "softgi/render/camera.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::backends::cpu_resolve {

// One object's posed arrays. normals: null where the object has no per-vertex normals (the shading
// normal is then the geometric one).
struct ObjectArrays {
  const glm::uvec3* triangles = nullptr;
  const glm::vec3* positions = nullptr;
  const glm::vec3* normals = nullptr;
};

// Pixels t = 0 .. n-1 of one buffer row, each seeing triangle primitive[t] of `obj` at barycentrics
// barycentric[t] through the camera ray forward + sx[t] right + sy up (render::BufferRays).
// Writes position[t] (w p0 + b1 p1 + b2 p2), normal[t] (interpolated, unit, on the viewer's side
// of the geometric normal; the geometric normal where the interpolated one is degenerate or
// missing), depth[t] ((p - eye) . forward) and, where view_dir is not null, view_dir[t] (unit,
// towards the eye). Indices are not checked: the visibility pass produced them from these arrays.
void resolve_surface_run(const render::PinholeCamera& cam, const ObjectArrays& obj, const std::int32_t* primitive,
                         const glm::vec2* barycentric, const float* sx, float sy, int n, glm::vec3* position,
                         glm::vec3* normal, float* depth, glm::vec3* view_dir);

// For the tests: how many pixels of gb (a CPU G-buffer of `posed` seen by `cam` at gb.scale) differ
// in any bit, in any plane gb holds, from the reference renderer's per-hit rule
// (embree::triangle_surface, surface_at, scene::surface_albedo) applied to the pixel's visibility
// planes one at a time, or, for a miss, from GBuffer::set_background. 0: the resolve is that rule.
// Defined in gbuffer_cpu.cpp.
std::size_t surface_resolve_differences(const render::PinholeCamera& cam, const scene::Scene& sc,
                                        const scene::PosedScene& posed, const render::GBuffer& gb);

}  // namespace softgi::backends::cpu_resolve
