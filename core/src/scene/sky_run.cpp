// sky_run (sky_run.hpp): the sky's radiance over arrays of directions, every array a restrict
// parameter of its own and the branches written as selects, so that GCC vectorises the loop;
// compiled for AVX-512, AVX2 and the baseline (target_clones), without FMA contraction and with
// non-trapping math (core/CMakeLists.txt), so that every version gives the bits of
// EnvironmentRadiance::operator() and sky_gradient (scene.cpp), whose operations it repeats in order.
#include "sky_run.hpp"

namespace softgi::scene::detail {

namespace {

// The loop, for a sky turned about +y or not (a select on a loop-invariant condition in the loop
// keeps GCC from vectorising it; the unturned sky reads the direction as it is, as operator() does).
template <bool Rotated>
[[gnu::always_inline]] inline void body(float cos_r, float sin_r, bool sun_on, float sx, float sy, float sz, float cos_sun,
                                         float intensity, const float* zen, const float* hor, const float* gro,
                                         const float* sun, const float* __restrict dir, int n, float* __restrict out) {
  // sun_radius > 0 && d . sun >= cos_sun: a comparison with NaN is false, so NaN switches the sun off.
  const float sun_cos = sun_on ? cos_sun : __builtin_nanf("");
  const float neg_sin_r = -sin_r;
  const float zr = zen[0], zg = zen[1], zb = zen[2], hr = hor[0], hg = hor[1], hb = hor[2];
  const float gr = gro[0], gg = gro[1], gb = gro[2], ur = sun[0], ug = sun[1], ub = sun[2];
  for (int t = 0; t < n; ++t) {
    const float x = dir[3 * t], y = dir[3 * t + 1], z = dir[3 * t + 2];
    // The content at R^-1 d for a sky turned by rotation_y about +y.
    const float dx = Rotated ? cos_r * x + sin_r * z : x;
    const float dz = Rotated ? neg_sin_r * x + cos_r * z : z;
    const bool in_sun = dx * sx + y * sy + dz * sz >= sun_cos;
    // sky_gradient: ground below the horizon, else horizon to zenith by smoothstep(min(y, 1)).
    const bool below = y < 0.0f;
    const float yc = 1.0f < y ? 1.0f : y;
    const float s = yc * yc * (3.0f - 2.0f * yc);
    const float sky_r = hr + (zr - hr) * s, sky_g = hg + (zg - hg) * s, sky_b = hb + (zb - hb) * s;
    const float lo_r = below ? gr : sky_r, lo_g = below ? gg : sky_g, lo_b = below ? gb : sky_b;
    out[3 * t] = intensity * (in_sun ? ur : lo_r);
    out[3 * t + 1] = intensity * (in_sun ? ug : lo_g);
    out[3 * t + 2] = intensity * (in_sun ? ub : lo_b);
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void run_plain(
    bool sun_on, float sx, float sy, float sz, float cos_sun, float intensity, const float* zen, const float* hor,
    const float* gro, const float* sun, const float* __restrict dir, int n, float* __restrict out) {
  body<false>(1.0f, 0.0f, sun_on, sx, sy, sz, cos_sun, intensity, zen, hor, gro, sun, dir, n, out);
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void run_rotated(
    float cos_r, float sin_r, bool sun_on, float sx, float sy, float sz, float cos_sun, float intensity, const float* zen,
    const float* hor, const float* gro, const float* sun, const float* __restrict dir, int n, float* __restrict out) {
  body<true>(cos_r, sin_r, sun_on, sx, sy, sz, cos_sun, intensity, zen, hor, gro, sun, dir, n, out);
}

}  // namespace

void sky_run(const SkyParams& p, const float* dir, std::size_t n, float* out) {
  // In pieces that an int counts.
  constexpr std::size_t kPiece = std::size_t{1} << 24;
  for (std::size_t first = 0; first < n; first += kPiece) {
    const int m = static_cast<int>(n - first < kPiece ? n - first : kPiece);
    const float* d = dir + 3 * first;
    float* o = out + 3 * first;
    if (p.rotated)
      run_rotated(p.cos_r, p.sin_r, p.sun, p.sun_x, p.sun_y, p.sun_z, p.cos_sun, p.intensity, p.zenith, p.horizon, p.ground,
                  p.sun_radiance, d, m, o);
    else
      run_plain(p.sun, p.sun_x, p.sun_y, p.sun_z, p.cos_sun, p.intensity, p.zenith, p.horizon, p.ground, p.sun_radiance, d, m, o);
  }
}

}  // namespace softgi::scene::detail
