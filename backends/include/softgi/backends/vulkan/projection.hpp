// The Vulkan clip-space projection of a render::PinholeCamera onto a buffer that samples its display
// points, shared by every rasterising pass (the G-buffer, image_splat's splats) so that a buffer
// pixel sees exactly the ray render::PinholeCamera::buffer_direction gives it.
//
// Pixel (x, y) of a buffer of scale s (ceil(W/s) x ceil(H/s) pixels) must see the display camera's
// ray through display point ((x + 0.5) s, (y + 0.5) s). In camera coordinates u = R.(p - e),
// v = U.(p - e), z = E.(p - e), that ray has u/z = (2 (x + 0.5) s / W - 1) t a and
// v/z = (1 - 2 (y + 0.5) s / H) t (t = tan(fov_y / 2), a = W / H: PinholeCamera::direction). The
// rasteriser's pixel centre x + 0.5 is NDC x_n = 2 (x + 0.5) / W' - 1 (W' = ceil(W/s), Vulkan's y
// axis points down), so with k_x = W' s / W and k_y = H' s / H (both 1 at s = 1):
//   x_c = u / (k_x t a) - (k_x - 1) / k_x z,   y_c = -v / (k_y t) - (k_y - 1) / k_y z,   w_c = z.
// Depth: reverse Z with an infinite far plane, z_c = n (depth n / z in (0, 1], compare GREATER,
// cleared to 0): float depth keeps the same relative resolution (2^-24) at every distance, so the
// near plane n can be tiny and clips nothing the ray caster (tnear = 0) would see in practice.
// Seen from outside, a surface wound counter-clockwise about its outward normal (right-handed) is
// counter-clockwise on screen: front-facing under VK_FRONT_FACE_COUNTER_CLOCKWISE.
#pragma once

#include <glm/glm.hpp>

#include "softgi/render/camera.hpp"

namespace softgi::backends::vulkan {

// clip_from_world for a buffer of bw x bh pixels sampling display points ((x + 0.5) s, (y + 0.5) s)
// of camera `cam`, near plane `near_plane` (> 0). glm matrices are column-major: m[col][row].
glm::mat4 clip_from_world(const render::PinholeCamera& cam, int bw, int bh, int scale, float near_plane);

}  // namespace softgi::backends::vulkan
