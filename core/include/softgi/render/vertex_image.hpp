// Per-vertex results seen through the G-buffer: a technique that shades vertices (SHEXP) gets its
// display-resolution image by interpolating the three vertex values of the visible triangle with the
// G-buffer's barycentrics, the way a rasteriser's Gouraud interpolation would.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/image.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::render {

// Radiance of a background pixel (no surface hit) from its G-buffer view_dir, which for background
// pixels is the camera ray's direction, pointing away from the eye.
using BackgroundFn = std::function<glm::vec3(const glm::vec3& ray_dir)>;

// Pixel i with object o, triangle t = (a, b, c) of posed.objects[o].source->triangles and
// barycentrics (b1, b2) gets (1 - b1 - b2) * v[o][a] + b1 * v[o][b] + b2 * v[o][c], where
// v = per_vertex (one vector per posed object, one value per vertex of its mesh). Background pixels
// get background(view_dir), or black when `background` is empty.
//
// Convention: techniques leave the indirect image's background black and put background_radiance
// (the environment as the camera sees it) into the direct image's background, the function the
// reference renderer calls for its background pixels, whatever light model shades the surfaces
// (full environment or its SH projection), so that technique and reference images show the same
// sky; `softgi compare` measures error on surface pixels only, so the background never enters the
// error numbers.
//
// Throws std::invalid_argument naming the object when per_vertex does not match the posed scene (an
// object seen by a pixel without per-vertex values, or with fewer values than vertices), or when a
// G-buffer primitive index is out of range.
Image interpolate_vertex_values(const GBuffer& gbuffer, const scene::PosedScene& posed,
                                const std::vector<std::vector<glm::vec3>>& per_vertex,
                                const BackgroundFn& background = {});
// The same, written into `storage`'s buffer (resized, every pixel overwritten): a pass hands in
// FramePool::image_for_overwrite so that last frame's image is reused. times_albedo: surface pixels
// are multiplied by the G-buffer's albedo in the same pass (vertex-rate irradiance, pixel-rate
// albedo, so that textures keep their detail).
Image interpolate_vertex_values(const GBuffer& gbuffer, const scene::PosedScene& posed,
                                const std::vector<std::vector<glm::vec3>>& per_vertex, const BackgroundFn& background,
                                Image storage, bool times_albedo);

// What the pass derives itself where the G-buffer leaves a plane out (GBuffer::planes), so that a
// technique whose G-buffer is the visibility planes alone reads each pixel once: the albedo by
// scene::surface_albedo from `scene` (the G-buffer's own rule, so the value is the same to the
// bit), the background ray direction from `camera` (the G-buffer's rays:
// camera.direction((x + 0.5) s, (y + 0.5) s) at the buffer's scale s).
struct DerivedPlanes {
  const scene::Scene* scene = nullptr;
  const PinholeCamera* camera = nullptr;
};
// The same with planes derived: throws std::invalid_argument when a plane the pass needs is neither
// in the G-buffer nor derivable (albedo without `scene`, view_dir without `camera`).
Image interpolate_vertex_values(const GBuffer& gbuffer, const scene::PosedScene& posed,
                                const std::vector<std::vector<glm::vec3>>& per_vertex, const BackgroundFn& background,
                                Image storage, bool times_albedo, const DerivedPlanes& derive);

// The background of every image, techniques' and reference's alike: the environment's radiance
// along the camera ray, Environment::radiance(ray_dir).
glm::vec3 background_radiance(const scene::Environment& env, const glm::vec3& ray_dir);
// background_radiance as a BackgroundFn (env must outlive it).
BackgroundFn environment_background(const scene::Environment& env);

// background(rays.direction(x, y)) for the n pixels x = x0 .. x0 + n - 1 of row y of the buffer
// `rays` describes (camera.buffer_direction to the bit), into out[0 .. n): the rays of the run worked
// out together in vector lanes, `scratch` holding them.
void background_run(const BackgroundFn& background, const PinholeCamera& camera, const BufferRays& rays, int x0, int y, int n,
                    glm::vec3* out, std::vector<glm::vec3>& scratch);

// The end of the run of a buffer row's pixels from x that see the object pixel x sees (object: the
// row's object ids, -1 for background; width its length; x < width): the first x1 > x whose id
// differs, or width. Sixteen pixels are compared at a time.
int object_run_end(const std::int32_t* object, int x, int width);

}  // namespace softgi::render
