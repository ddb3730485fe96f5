// Per-vertex values seen through the G-buffer: barycentric interpolation reproduces any function
// that is linear in position exactly (up to float rounding), on every visible triangle.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <utility>
#include <vector>

#include "../../core/src/render/vertex_image_run.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/vertex_image.hpp"
#include "test_scene_util.hpp"

using namespace softgi;

namespace {

// f is O(1) over the scene; float interpolation of three O(1) values and the G-buffer position
// (itself interpolated in float) agree to a few ulps of the scene's extent.
constexpr float kLinearTol = 2e-5f;

glm::vec3 linear_fn(const glm::vec3& p) {
  return {0.3f + 0.1f * p.x - 0.2f * p.y + 0.05f * p.z, 1.0f - 0.25f * p.z, 0.5f * p.y + 0.125f * p.x};
}

struct Frame {
  scene::Scene scene;
  scene::PosedScene posed;
  render::GBuffer gb;
  explicit Frame(scene::Scene sc = softgi::testing::make_plane_sphere_scene()) : scene(std::move(sc)), posed(scene::evaluate(scene, 0.0)) {
    backends::CpuBackend backend;
    render::FrameResult result;
    render::ParamSet params;
    render::FrameContext ctx(scene, posed, params, scene.camera.width, scene.camera.height, result);
    result.passes.push_back(render::PassRecord{"gbuffer"});
    (*render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName))(ctx);
    gb = ctx.get<render::GBuffer>(render::kGBuffer);
  }
  std::vector<std::vector<glm::vec3>> per_vertex() const {
    std::vector<std::vector<glm::vec3>> v;
    for (const auto& o : posed.objects) {
      v.emplace_back();
      for (const auto& p : o.positions) v.back().push_back(linear_fn(p));
    }
    return v;
  }
};

}  // namespace

TEST(VertexImage, ReproducesALinearFunctionOfPosition) {
  const Frame f;
  const Image img = render::interpolate_vertex_values(f.gb, f.posed, f.per_vertex());
  ASSERT_EQ(img.width, f.gb.width);
  ASSERT_EQ(img.height, f.gb.height);
  int hits = 0, background = 0;
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    if (f.gb.hit(i)) {
      ++hits;
      const glm::vec3 want = linear_fn(f.gb.position[i]);
      EXPECT_LE(glm::length(img.rgb[i] - want), kLinearTol) << "pixel " << i << " of object " << f.gb.object[i];
    } else {
      ++background;
      EXPECT_EQ(img.rgb[i], glm::vec3(0.0f)) << "background without a BackgroundFn is black";
    }
  }
  EXPECT_GT(hits, 1000);
  EXPECT_GT(background, 100);
}

TEST(VertexImage, BackgroundIsTheEnvironmentAlongTheRay) {
  const Frame f;
  const Image img =
      render::interpolate_vertex_values(f.gb, f.posed, f.per_vertex(), render::environment_background(f.scene.environment));
  int background = 0;
  for (std::size_t i = 0; i < img.rgb.size(); ++i)
    if (!f.gb.hit(i)) {
      ++background;
      EXPECT_EQ(img.rgb[i], f.scene.environment.radiance(f.gb.view_dir[i]));
    }
  EXPECT_GT(background, 100);
}

TEST(VertexImage, MismatchedValuesNameTheObject) {
  const Frame f;
  auto v = f.per_vertex();
  v[1].resize(10);
  try {
    render::interpolate_vertex_values(f.gb, f.posed, v);
    ADD_FAILURE() << "short per-vertex array accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'sphere'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("10 per-vertex values"), std::string::npos) << e.what();
  }
  v.resize(1);
  EXPECT_THROW(render::interpolate_vertex_values(f.gb, f.posed, v), std::invalid_argument);
}

TEST(VertexImage, DerivedPlanesGiveTheImageOfTheWholeGBuffer) {
  // A G-buffer of the visibility planes alone: albedo and the background's ray directions derived
  // from the scene and the camera give the image of the whole G-buffer to the bit; without them,
  // the missing planes are an error.
  const Frame f;
  render::GBuffer vis = f.gb;
  vis.planes = render::kGBufferVisibility;
  vis.position.clear();
  vis.normal.clear();
  vis.depth.clear();
  vis.albedo.clear();
  vis.view_dir.clear();
  const render::BackgroundFn bg = render::environment_background(f.scene.environment);
  const Image whole = render::interpolate_vertex_values(f.gb, f.posed, f.per_vertex(), bg, Image(), true);
  const render::PinholeCamera cam = render::make_pinhole_camera(f.scene, f.gb.width, f.gb.height, "test");
  const Image derived =
      render::interpolate_vertex_values(vis, f.posed, f.per_vertex(), bg, Image(), true, render::DerivedPlanes{&f.scene, &cam});
  ASSERT_EQ(whole.rgb.size(), derived.rgb.size());
  int background = 0;
  for (std::size_t i = 0; i < whole.rgb.size(); ++i) {
    ASSERT_EQ(whole.rgb[i], derived.rgb[i]) << "pixel " << i;
    background += f.gb.hit(i) ? 0 : 1;
  }
  EXPECT_GT(background, 100) << "the background is looked at";
  try {
    render::interpolate_vertex_values(vis, f.posed, f.per_vertex(), bg, Image(), true, render::DerivedPlanes{nullptr, &cam});
    ADD_FAILURE() << "albedo neither held nor derived";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("none is derived"), std::string::npos) << e.what();
  }
  EXPECT_THROW(render::interpolate_vertex_values(vis, f.posed, f.per_vertex(), bg), std::invalid_argument);
}

// The image is interpolated in vector lanes across runs of pixels (core/src/render/vertex_image_run.cpp):
// every surface pixel must hold the bits of the per-pixel expression the header states,
// (1 - b1 - b2) v[a] + b1 v[b] + b2 v[c], times the G-buffer's albedo or the derived one, with values
// that are not linear (so that no two rules can agree by accident) and on a mesh with vertex
// colours (albedo per pixel) as well as on uniform ones. A primitive out of range is an error that
// names the pixel.
TEST(VertexImage, EveryPixelIsThePerPixelExpressionToTheBit) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0.0f, 2.0f);
  for (const bool colours : {false, true}) {
    SCOPED_TRACE(colours ? "vertex colours" : "uniform albedo");
    scene::Scene sc = softgi::testing::make_plane_sphere_scene();
    if (colours)
      for (auto& m : sc.meshes) {
        m.colors.clear();
        for (std::size_t v = 0; v < m.positions.size(); ++v) m.colors.push_back({u(rng), u(rng), u(rng)});
      }
    const Frame f(std::move(sc));
    std::vector<std::vector<glm::vec3>> values;
    for (const auto& o : f.posed.objects) {
      values.emplace_back();
      for (std::size_t v = 0; v < o.positions.size(); ++v) values.back().push_back({u(rng), u(rng), u(rng)});
    }
    const render::PinholeCamera cam = render::make_pinhole_camera(f.scene, f.gb.width, f.gb.height, "test");
    render::GBuffer vis = f.gb;
    vis.planes = render::kGBufferVisibility;
    vis.albedo.clear();
    const Image plain = render::interpolate_vertex_values(f.gb, f.posed, values);
    const Image held = render::interpolate_vertex_values(f.gb, f.posed, values, {}, Image(), true);
    const Image derived = render::interpolate_vertex_values(vis, f.posed, values, {}, Image(), true, render::DerivedPlanes{&f.scene, &cam});
    const auto same = [](const glm::vec3& a, const glm::vec3& b) { return std::memcmp(&a, &b, sizeof(a)) == 0; };
    int hits = 0, differ = 0;
    for (std::size_t i = 0; i < f.gb.object.size(); ++i) {
      if (!f.gb.hit(i)) continue;
      ++hits;
      const scene::PosedObject& obj = f.posed.objects[f.gb.object[i]];
      const glm::uvec3 t = obj.source->triangles[f.gb.primitive[i]];
      const std::vector<glm::vec3>& v = values[f.gb.object[i]];
      const glm::vec2 b = f.gb.barycentric[i];
      const glm::vec3 e = (1.0f - b.x - b.y) * v[t.x] + b.x * v[t.y] + b.y * v[t.z];
      const glm::vec3 a = scene::surface_albedo(f.scene, obj, f.gb.primitive[i], b.x, b.y);
      differ += !same(plain.rgb[i], e) + !same(held.rgb[i], e * f.gb.albedo[i]) + !same(derived.rgb[i], e * a);
    }
    EXPECT_GT(hits, 1000);
    EXPECT_EQ(differ, 0) << "values differing in some bit, of " << 3 * hits;
    // A primitive past the end of its mesh, in the middle of a run.
    std::size_t bad = 0;
    while (!vis.hit(bad) || !vis.hit(bad + 1) || vis.object[bad] != vis.object[bad + 1]) ++bad;
    vis.primitive[bad + 1] = 1 << 30;
    try {
      render::interpolate_vertex_values(vis, f.posed, values, {}, Image(), true, render::DerivedPlanes{&f.scene, &cam});
      ADD_FAILURE() << "primitive out of range accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("pixel " + std::to_string(bad + 1) + " has primitive"), std::string::npos) << e.what();
    }
  }
}

// The background's derived rays, a row at a time in vector lanes (detail::ray_directions), are
// render::BufferRays::direction to the bit: every pixel of buffers at scales 1 and 3 of cameras that
// look along and across the axes.
TEST(VertexImage, DerivedRayDirectionsAreTheBufferRaysToTheBit) {
  scene::Scene sc = softgi::testing::make_plane_sphere_scene();
  std::size_t compared = 0, differ = 0;
  for (const glm::vec3 eye : {glm::vec3(0.0f, 1.0f, 5.0f), glm::vec3(3.0f, -2.0f, 0.5f), glm::vec3(-0.3f, 7.0f, -4.0f)}) {
    sc.camera.position = eye;
    for (const int scale : {1, 3}) {
      const int w = 131, h = 77;
      const render::PinholeCamera cam = render::make_pinhole_camera(sc, w * scale, h * scale, "test");
      const render::BufferRays rays(cam, w, h, scale);
      std::vector<glm::vec3> dirs(w);
      for (int y = 0; y < h; ++y) {
        render::detail::ray_directions(cam.forward, cam.right, cam.up, rays.sx.data(), rays.sy[y], w, dirs.data());
        for (int x = 0; x < w; ++x) {
          const glm::vec3 want = rays.direction(x, y);
          differ += std::memcmp(&dirs[x], &want, sizeof(want)) != 0;
          ++compared;
        }
      }
    }
  }
  EXPECT_EQ(differ, 0u) << "of " << compared << " rays";
}

// render::object_run_end (the runs the G-buffer resolve, the per-vertex image and image-space's
// background fill walk): the first pixel after x whose object differs, against the rule written out,
// for rows of runs of every length from 1 to 40 (across and inside its 16-pixel steps), background
// (-1) included, starting at every pixel of the row.
TEST(VertexImage, ObjectRunsEndWhereTheObjectChanges) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> length(1, 40), id(-1, 3);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<std::int32_t> row;
    int prev = -2;
    while (row.size() < 300) {
      int o = id(rng);
      if (o == prev) o = o == 3 ? -1 : o + 1;  // each run a different object from the one before
      row.insert(row.end(), static_cast<std::size_t>(length(rng)), o);
      prev = o;
    }
    const int width = static_cast<int>(row.size());
    for (int x = 0; x < width; ++x) {
      int expected = x + 1;
      while (expected < width && row[static_cast<std::size_t>(expected)] == row[static_cast<std::size_t>(x)]) ++expected;
      ASSERT_EQ(render::object_run_end(row.data(), x, width), expected) << "trial " << trial << " x " << x;
    }
  }
}
