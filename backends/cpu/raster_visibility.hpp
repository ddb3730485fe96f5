// Primary visibility of the CPU backend by rasterisation: for every sample of a G-buffer (pixel
// (x, y) of a buffer at 1/scale of the display resolution samples display point ((x + 0.5) scale,
// (y + 0.5) scale), gbuffer.hpp), the posed triangle that the camera ray through that point meets
// first, and the barycentrics of the meeting point. The same question the Embree trace answers
// (gbuffer_cpu.cpp), answered in image space: each triangle is tested against the sample rays of
// the screen tiles its projection overlaps.
#pragma once

#include <cstddef>
#include <cstdint>

#include "softgi/render/camera.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::backends::cpu_raster {

struct RasterStats {
  long long triangles = 0;     // triangles of the posed objects
  long long set_up = 0;        // of them, those that can meet a sample ray (in front, not degenerate, on screen)
  long long tile_entries = 0;  // (triangle, tile) pairs tested
  long long hits = 0;          // samples that see a triangle
  std::size_t held_bytes = 0;  // working memory kept for the next frame
  bool reused = false;         // the set-up of an earlier call of the same frame was reused
  double setup_seconds = 0.0, raster_seconds = 0.0;
};

// Writes gb.object, gb.primitive and gb.barycentric of every pixel of gb (width, height and scale
// set; -1 / -1 where the ray meets nothing, the other planes untouched). Throws
// std::invalid_argument, prefixed with `who` and naming the mesh, for a vertex index out of range,
// a posed vertex that is not finite, or a triangle too large for float arithmetic.
// `frame`: render::FrameContext::id of the calling frame (0: none). The triangles' set-up depends
// on the camera and the posed geometry, not on the buffer's grid, so a second call of the same
// frame with the same camera (the receiver buffer after the display buffer) reuses the first's.
void rasterise_visibility(const render::PinholeCamera& cam, const scene::PosedScene& posed, const char* who,
                          render::GBuffer& gb, RasterStats& stats, std::uint64_t frame = 0);

// The triangles' edge forms (the branch-free part of their set-up) computed by the vectorised block
// kernel rasterise_visibility uses and one triangle at a time with glm's cross and dot: how many
// triangles of `posed` differ in any bit (0: the vector code is the same arithmetic). For the tests.
std::size_t edge_form_differences(const render::PinholeCamera& cam, const scene::PosedScene& posed);

}  // namespace softgi::backends::cpu_raster
