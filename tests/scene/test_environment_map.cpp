// Environment maps in the scene model: environment_sh integrates exactly the function radiance()
// looks up, at every map size (tiny maps included), and validate() keeps refusing negative pixels
// in maps built in code.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/quaternion.hpp>

#include "softgi/scene/scene.hpp"
#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"

namespace {

namespace scene = softgi::scene;
namespace sh = softgi::sh;
using glm::vec3;

// environment_sh returns float: coefficients of size ~sqrt(4 pi) c carry float rounding (6e-8
// relative) of the double result; 1e-6 of the map's scale is ten times that.
constexpr float kFloatRel = 1e-6f;
// Against a brute-force integral of radiance() itself: the lookup runs in float (angles, weights),
// so each sample is off by ~1e-6 relative; the quadrature sums them, 1e-5 of the map's scale.
constexpr double kLookupRel = 1e-5;

scene::Environment map_env(int w, int h, const std::vector<float>& rgb) {
  scene::Environment e;
  e.kind = scene::Environment::Kind::Map;
  e.map_path = "test.exr";
  e.map_width = w;
  e.map_height = h;
  e.map_rgb = rgb;
  return e;
}

scene::Environment constant_env(int w, int h, const vec3& c) {
  std::vector<float> rgb;
  for (int k = 0; k < w * h; ++k) rgb.insert(rgb.end(), {c.x, c.y, c.z});
  return map_env(w, h, rgb);
}

std::string error_of(const scene::Scene& s) {
  try {
    scene::validate(s);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

}  // namespace

// A constant map c at 1x1, 2x1, 4x2, 3x5 and 64x32, rotated or not: (2 sqrt(pi) c, 0, ...), and the
// SH radiance it reconstructs is c in every direction (tiny maps used to give values from -2.6 to 6).
TEST(EnvironmentMap, ConstantMapsProjectExactlyAtEverySize) {
  const vec3 c(1.0f, 0.5f, 2.0f);
  std::mt19937 rng(3);
  std::normal_distribution<float> g;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {2, 1}, {4, 2}, {3, 5}, {64, 32}})
    for (float rotation : {0.0f, 0.8f}) {
      scene::Environment e = constant_env(w, h, c);
      e.rotation_y = rotation;
      const auto L = scene::environment_sh(e, 8);
      for (int ch = 0; ch < 3; ++ch) {
        EXPECT_NEAR(L[0][ch], 2.0f * std::sqrt(static_cast<float>(sh::kPi)) * c[ch], kFloatRel * 4.0f * c[ch]) << w << "x" << h;
        for (int i = 1; i < 64; ++i) EXPECT_NEAR(L[i][ch], 0.0f, kFloatRel * c[ch]) << w << "x" << h << " coefficient " << i;
      }
      for (int t = 0; t < 100; ++t) {
        const vec3 d = glm::normalize(vec3(g(rng), g(rng), g(rng)));
        std::array<float, 64> y{};
        sh::eval_basis(8, sh::Vec3<float>{d.x, d.y, d.z}, y.data());
        vec3 r(0.0f);
        for (int i = 0; i < 64; ++i) r += L[i] * y[i];
        // 64 float terms of size up to ~1 each: a few float ulps of 64.
        EXPECT_LE(glm::length(r - c), 2e-5f) << w << "x" << h << " direction " << d.x << " " << d.y << " " << d.z;
      }
    }
}

// Irradiance of a constant map: pi c at every normal (paper 004 eq. 9 with L = c).
TEST(EnvironmentMap, ConstantMapIrradianceIsPiC) {
  const vec3 c(0.7f, 1.0f, 3.0f);
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {2, 1}, {4, 2}, {3, 5}, {64, 32}}) {
    const auto L = scene::environment_sh(constant_env(w, h, c), 3);
    for (int ch = 0; ch < 3; ++ch) {
      std::vector<double> l(9), e(9);
      for (int i = 0; i < 9; ++i) l[i] = L[i][ch];
      sh::irradiance_env(3, l.data(), e.data());
      for (int t = 0; t < 50; ++t) {
        const sh::Vec3<double> n = sh::normalize(sh::Vec3<double>{g(rng), g(rng), g(rng)});
        EXPECT_NEAR(sh::reconstruct(3, e.data(), n), sh::kPi * c[ch], kFloatRel * 10.0 * c[ch]) << w << "x" << h;
      }
    }
  }
}

// environment_sh against a brute-force integral of radiance() itself (the function every renderer
// and the background read): a 2D Gauss-Legendre product in world (theta, phi), panels broken at
// every half texel of the turned map, 12 nodes each; random maps, tiny and not, turned and scaled.
TEST(EnvironmentMap, ProjectionIntegratesTheRadianceLookup) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  constexpr int kOrder = 5;
  const sh::GaussLegendre& gl = sh::gauss_legendre(12);
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {2, 1}, {4, 2}, {3, 5}, {16, 8}}) {
    std::vector<float> rgb(static_cast<std::size_t>(w) * h * 3);
    for (float& x : rgb) x = u01(rng);
    scene::Environment e = map_env(w, h, rgb);
    e.rotation_y = 0.6f;
    e.intensity = 1.5f;
    const auto L = scene::environment_sh(e, kOrder);
    // Panels: whole fractions of a half texel, at most pi/16 long.
    const int nt = 2 * h * ((16 + 2 * h - 1) / (2 * h)), np = 2 * w * ((32 + 2 * w - 1) / (2 * w));
    std::vector<glm::dvec3> ref(kOrder * kOrder, glm::dvec3(0.0));
    std::array<double, 64> y{};
    for (int a = 0; a < nt; ++a)
      for (int b = 0; b < np; ++b)
        for (int i = 0; i < 12; ++i)
          for (int j = 0; j < 12; ++j) {
            const double theta = sh::kPi * (a + 0.5 * (gl.nodes[i] + 1)) / nt;
            // The content at map phi is seen at world phi + rotation_y.
            const double phi = 2.0 * sh::kPi * (b + 0.5 * (gl.nodes[j] + 1)) / np + e.rotation_y;
            const double st = std::sin(theta);
            const sh::Vec3<double> d{st * std::cos(phi), std::cos(theta), -st * std::sin(phi)};
            const double wgt = sh::kPi / nt * 2.0 * sh::kPi / np * 0.25 * gl.weights[i] * gl.weights[j] * st;
            const glm::dvec3 value = glm::dvec3(e.radiance(vec3(static_cast<float>(d.x), static_cast<float>(d.y), static_cast<float>(d.z))));
            sh::eval_basis(kOrder, d, y.data());
            for (int k = 0; k < kOrder * kOrder; ++k) ref[k] += value * (wgt * y[k]);
          }
    for (int k = 0; k < kOrder * kOrder; ++k)
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(L[k][ch], ref[k][ch], kLookupRel * e.intensity * 4.0 * sh::kPi) << w << "x" << h << " coefficient " << k << " channel " << ch;
  }
}

// The loader clamps negative map pixels; a map built in code is validated as it stands.
TEST(EnvironmentMap, ValidateRefusesNegativeAndNonFinitePixels) {
  scene::Scene s;
  s.environment = constant_env(4, 2, vec3(1.0f));
  EXPECT_EQ(error_of(s), "(no exception)");
  s.environment.map_rgb[3 * 6 + 2] = -0.5f;  // pixel (2, 1) channel 2
  std::string err = error_of(s);
  EXPECT_NE(err.find("environment map 'test.exr': pixel (2, 1) channel 2 = -0.5 must be finite and non-negative"), std::string::npos) << err;
  s.environment.map_rgb[3 * 6 + 2] = INFINITY;
  err = error_of(s);
  EXPECT_NE(err.find("pixel (2, 1) channel 2 = inf"), std::string::npos) << err;
}

// EnvironmentRadiance over an array of directions (the sky in vector lanes, scene/sky_run.cpp) gives
// operator()'s bits for each: the sky with and without a sun, turned and not, scaled; a map; random
// unit directions and the edge cases (the sun's centre and rim, the horizon at +0 and -0, the
// zenith, beyond it, the nadir). Every branch is seen: sun, sky above and ground below.
TEST(EnvironmentRadiance, ManyDirectionsAtOnceAreEachDirectionToTheBit) {
  std::mt19937 rng(17);
  std::normal_distribution<float> g(0.0f, 1.0f);
  scene::Environment map;
  map.kind = scene::Environment::Kind::Map;
  map.map_width = 4;
  map.map_height = 2;
  for (int i = 0; i < 4 * 2 * 3; ++i) map.map_rgb.push_back(0.1f * static_cast<float>(i));
  map.rotation_y = 0.4f;
  std::vector<scene::Environment> envs;
  for (const float sun_radius : {0.05f, 0.0f, 0.3f})
    for (const float rotation : {0.0f, 0.7f, -2.0f}) {
      scene::Environment e;
      e.sun_radius = sun_radius;
      e.rotation_y = rotation;
      e.intensity = 1.3f;
      envs.push_back(e);
    }
  envs.push_back(map);
  for (const scene::Environment& env : envs) {
    SCOPED_TRACE("sun radius " + std::to_string(env.sun_radius) + " rotation " + std::to_string(env.rotation_y) +
                 (env.kind == scene::Environment::Kind::Map ? " map" : " sky"));
    const scene::EnvironmentRadiance eval(env);
    // The sun's centre as the sky sees it: the world direction that the rotation turns onto it.
    const float c = std::cos(env.rotation_y), s = std::sin(env.rotation_y);
    const vec3 sun = glm::normalize(env.sun_direction);
    const vec3 sun_world(c * sun.x + s * sun.z, sun.y, -s * sun.x + c * sun.z);
    std::vector<vec3> dirs = {sun_world, vec3(1.0f, 0.0f, 0.0f), vec3(1.0f, -0.0f, 0.0f), vec3(0.0f, 1.0f, 0.0f),
                              vec3(0.0f, 2.0f, 0.0f), vec3(0.0f, -1.0f, 0.0f)};
    // The rim: directions at the sun's angular radius, just inside and outside.
    const vec3 side = glm::normalize(glm::cross(sun_world, vec3(0.0f, 0.0f, 1.0f)));
    for (const float a : {0.999f, 1.0f, 1.001f})
      dirs.push_back(std::cos(a * env.sun_radius) * sun_world + std::sin(a * env.sun_radius) * side);
    for (int i = 0; i < 5000; ++i) dirs.push_back(glm::normalize(vec3(g(rng), g(rng), g(rng))));
    for (int i = 0; i < 500; ++i) dirs.push_back(glm::normalize(sun_world + 0.1f * vec3(g(rng), g(rng), g(rng))));
    std::vector<vec3> out(dirs.size());
    eval(dirs.data(), dirs.size(), out.data());
    std::size_t differ = 0, in_sun = 0, below = 0;
    for (std::size_t k = 0; k < dirs.size(); ++k) {
      const vec3 want = eval(dirs[k]);
      differ += std::memcmp(&out[k], &want, sizeof(want)) != 0;
      in_sun += want == env.intensity * env.sun_radiance;
      below += want == env.intensity * env.ground;
    }
    EXPECT_EQ(differ, 0u) << "of " << dirs.size() << " directions";
    if (env.kind == scene::Environment::Kind::Sky) {
      EXPECT_EQ(in_sun > 0, env.sun_radius > 0.0f);
      EXPECT_GT(below, 1000u);
    }
  }
}
