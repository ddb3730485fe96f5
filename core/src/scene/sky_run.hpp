// The analytic sky of scene::EnvironmentRadiance for many directions at once (scene.cpp's
// EnvironmentRadiance::operator() over arrays). Not installed.
#pragma once

#include <cstddef>

namespace softgi::scene::detail {

// What the sky's radiance depends on besides the direction: EnvironmentRadiance's prepared values
// (rotation, unit sun direction, cosine of the sun's radius) and the Environment's colours.
struct SkyParams {
  bool rotated = false;
  float cos_r = 1.0f, sin_r = 0.0f;  // of -rotation_y
  bool sun = false;                  // sun_radius > 0
  float sun_x = 0.0f, sun_y = 1.0f, sun_z = 0.0f, cos_sun = 1.0f;
  float intensity = 1.0f;
  float zenith[3] = {}, horizon[3] = {}, ground[3] = {}, sun_radiance[3] = {};
};

// out[3 t + c] for the directions dir[3 t .. 3 t + 2], t < n: EnvironmentRadiance::operator()'s sky
// branch, the same operations in the same order.
void sky_run(const SkyParams& p, const float* dir, std::size_t n, float* out);

}  // namespace softgi::scene::detail
