// The CPU G-buffer's surface resolve (backends/cpu/surface_resolve.cpp): position, normal, depth,
// albedo and view direction of every hit pixel, computed in vector lanes across runs of pixels, must
// be the bits of the reference renderer's per-hit rule (misses those of GBuffer::set_background) (embree::triangle_surface and surface_at,
// scene::surface_albedo) applied to each pixel's object, triangle and barycentrics
// (cpu_resolve::surface_resolve_differences): on the built-in scenes from their cameras and from
// other eyes, display and receiver buffers, with every plane and with the planes image-space
// techniques read (no view_dir, so the rays stay unnormalised); and on a mesh whose vertex normals
// are zero, cancel, are not finite or are missing.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../backends/cpu/surface_resolve.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/scene/builtin.hpp"
#include "test_scene_util.hpp"

using namespace softgi;

namespace {

struct Resolved {
  render::GBuffer gb;
  std::size_t hits = 0, differences = 0;
};

// The shared G-buffer pass of the CPU backend (`visibility`: raster or embree) at w x h, the
// display buffer (scale 1) or the receiver buffer at `scale`, holding `planes`; then the resolve
// checked against the per-hit rule.
Resolved resolve(const scene::Scene& sc, const scene::PosedScene& posed, const char* visibility, int scale, int w, int h,
                 unsigned planes) {
  Resolved r;
  r.gb = softgi::testing::cpu_gbuffer(sc, posed, visibility, scale, w, h, planes);
  for (std::size_t i = 0; i < r.gb.object.size(); ++i) r.hits += r.gb.hit(i) ? 1 : 0;
  const render::PinholeCamera cam = render::make_pinhole_camera(sc, w, h, "test");
  r.differences = backends::cpu_resolve::surface_resolve_differences(cam, sc, posed, r.gb);
  return r;
}

constexpr unsigned kImageSpacePlanes = render::kGBufferSurface | render::kGBufferAlbedo;

}  // namespace

TEST(SurfaceResolve, IsTheReferenceRulePerHitOnEveryBuiltinScene) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::size_t hits = 0;
  for (const auto& info : scene::builtin_scenes()) {
    if (info.needs_assets) continue;
    scene::Scene sc = scene::make_builtin(info.name);
    const scene::PosedScene posed = scene::evaluate(sc, 0.25);
    for (int view = 0; view < 3; ++view) {
      if (view > 0) sc.camera.position = sc.camera.target + glm::vec3(3.0f * u(rng), 3.0f * u(rng), 3.0f * u(rng));
      for (const unsigned planes : {static_cast<unsigned>(render::kGBufferAll), kImageSpacePlanes})
        for (const int scale : {1, 3}) {
          SCOPED_TRACE(info.name + " view " + std::to_string(view) + " planes " + std::to_string(planes) + " scale " +
                       std::to_string(scale));
          const Resolved r = resolve(sc, posed, "raster", scale, 97, 61, planes);
          EXPECT_EQ(r.differences, 0u) << "of " << r.gb.object.size() << " pixels";
          hits += r.hits;
        }
    }
  }
  EXPECT_GT(hits, 50000u);
}

// The Embree trace hands the resolve barycentrics of its own (and hits on triangles the rasteriser
// leaves out, such as those seen edge-on): the same rule applies.
TEST(SurfaceResolve, IsTheReferenceRuleOnTheEmbreeTrace) {
  for (const char* name : {"spheres", "cornell", "crowd"}) {
    SCOPED_TRACE(name);
    const scene::Scene sc = scene::make_builtin(name);
    const Resolved r = resolve(sc, scene::evaluate(sc, 0.0), "embree", 1, 80, 64, render::kGBufferAll);
    EXPECT_EQ(r.differences, 0u) << "of " << r.gb.object.size() << " pixels";
    EXPECT_GT(r.hits, 500u);
  }
}

// A grid in the plane z = 0 (jittered within it) facing the camera, whose vertex normals are unit, zero, opposite to their
// neighbours' (so that the interpolated normal vanishes or turns), huge (their squared length
// overflows), NaN or infinite; and the same grid without normals, as a second object. Every
// branch of the rule: the interpolated normal kept, flipped to the viewer's side, or replaced by the
// geometric normal.
TEST(SurfaceResolve, DegenerateAndMissingVertexNormals) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_int_distribution<int> kind(0, 6);
  constexpr int kCells = 12;
  const auto grid = [&](float x0, bool normals) {
    scene::Mesh m;
    m.name = normals ? "normals" : "no_normals";
    const float cell = 1.0f / kCells;
    for (int j = 0; j <= kCells; ++j)
      for (int i = 0; i <= kCells; ++i) {
        m.positions.push_back({x0 + cell * (i + 0.3f * u(rng)), cell * (j + 0.3f * u(rng)) - 0.5f, 0.0f});
        if (!normals) {
          m.normals.push_back({0.0f, 0.0f, 1.0f});  // dropped from the posed object below
          continue;
        }
        const float inf = std::numeric_limits<float>::infinity();
        switch (kind(rng)) {
          case 0: m.normals.push_back({0.0f, 0.0f, 0.0f}); break;
          case 1: m.normals.push_back({0.0f, 0.0f, -1.0f}); break;
          case 2: m.normals.push_back({3e19f, 1e19f, 2e19f}); break;
          case 3: m.normals.push_back({std::nanf(""), 0.0f, 1.0f}); break;
          case 4: m.normals.push_back({inf, 0.0f, 0.0f}); break;
          default: m.normals.push_back(glm::normalize(glm::vec3(0.5f * u(rng), 0.5f * u(rng), 1.0f)));
        }
      }
    const unsigned row = kCells + 1;
    for (unsigned j = 0; j < kCells; ++j)
      for (unsigned i = 0; i < kCells; ++i) {
        const unsigned a = j * row + i;
        m.triangles.push_back({a, a + 1, a + row + 1});
        m.triangles.push_back({a, a + row + 1, a + row});
      }
    return m;
  };
  scene::Scene sc;
  sc.name = "resolve_test";
  sc.source = "test";
  sc.materials.resize(1);
  sc.meshes = {grid(-1.05f, true), grid(0.05f, false)};
  for (int k = 0; k < 2; ++k) {
    sc.meshes[k].material = 0;
    scene::Node n;
    n.name = sc.meshes[k].name;
    n.mesh = k;
    sc.nodes.push_back(n);
  }
  sc.camera.position = {0.0f, 0.0f, 2.5f};
  sc.camera.target = {0.0f, 0.0f, 0.0f};
  // A scene's meshes all have normals; a posed object without them (as the resolve allows) is made
  // here.
  scene::PosedScene posed = scene::evaluate(sc, 0.0);
  posed.objects[1].normals.clear();
  for (const unsigned planes : {static_cast<unsigned>(render::kGBufferAll), kImageSpacePlanes})
    for (const char* visibility : {"raster", "embree"}) {
      SCOPED_TRACE(std::string(visibility) + " planes " + std::to_string(planes));
      const Resolved r = resolve(sc, posed, visibility, 1, 160, 90, planes);
      EXPECT_EQ(r.differences, 0u) << "of " << r.gb.object.size() << " pixels";
      // Both objects are seen; on the first, some pixels keep an interpolated normal and some take
      // the geometric normal, +z towards the camera (or interpolate three opposite normals, -z,
      // turned to +z).
      const glm::vec3 up_z(0.0f, 0.0f, 1.0f);
      std::size_t seen[2] = {0, 0}, geometric = 0, interpolated = 0;
      for (std::size_t i = 0; i < r.gb.object.size(); ++i) {
        if (!r.gb.hit(i)) continue;
        ++seen[r.gb.object[i]];
        if (r.gb.object[i] == 0) (r.gb.normal[i] == up_z ? geometric : interpolated) += 1;
      }
      EXPECT_GT(seen[0], 1000u);
      EXPECT_GT(seen[1], 1000u);
      EXPECT_GT(geometric, 100u);
      EXPECT_GT(interpolated, 100u);
    }
}
