// The CPU G-buffer's rasterised primary visibility (backends/cpu/raster_visibility.cpp): against the
// Embree trace of the same sample rays on every built-in scene, display and receiver buffers; no
// cracks where sample rays pass exactly through shared edges or through an irregular mesh; ray
// precision on small, far triangles; triangles that reach behind the eye; equal depths; errors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../../backends/cpu/raster_visibility.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/scene/builtin.hpp"
#include "test_scene_util.hpp"

using namespace softgi;
using softgi::testing::silhouette;

namespace {

// The shared pass on the CPU backend with the given visibility (softgi::testing::cpu_gbuffer).
render::GBuffer run(const scene::Scene& sc, const scene::PosedScene& posed, const char* visibility, int scale, int w,
                    int h, render::PassRecord* rec = nullptr) {
  return softgi::testing::cpu_gbuffer(sc, posed, visibility, scale, w, h, render::kGBufferAll, rec);
}

render::GBuffer run(const scene::Scene& sc, const char* visibility, render::PassRecord* rec = nullptr) {
  return run(sc, scene::evaluate(sc, 0.0), visibility, 1, sc.camera.width, sc.camera.height, rec);
}

// A square grid mesh of n x n cells over [-h, h]^2 in the plane z = z0, each cell split along the
// diagonal chosen by `diag` (0: (0,0)-(1,1), 1: (1,0)-(0,1), 2: alternating); `jitter` moves the
// interior vertices within the plane by up to that fraction of a cell (shared, so the mesh stays
// connected). Vertex normals +z.
scene::Mesh grid(int n, float h, float z0, int diag, float jitter, unsigned seed) {
  scene::Mesh m;
  m.name = "grid";
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-jitter, jitter);
  const float cell = 2.0f * h / static_cast<float>(n);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      float x = -h + cell * static_cast<float>(i), y = -h + cell * static_cast<float>(j);
      if (jitter > 0.0f && i > 0 && i < n && j > 0 && j < n) {
        x += u(rng) * cell;
        y += u(rng) * cell;
      }
      m.positions.push_back({x, y, z0});
      m.normals.push_back({0.0f, 0.0f, 1.0f});
    }
  const unsigned row = static_cast<unsigned>(n + 1);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const unsigned a = static_cast<unsigned>(j) * row + static_cast<unsigned>(i), b = a + 1, c = a + row + 1, d = a + row;
      const bool main = diag == 0 || (diag == 2 && (i + j) % 2 == 0);
      if (main) {
        m.triangles.push_back({a, b, c});
        m.triangles.push_back({a, c, d});
      } else {
        m.triangles.push_back({a, b, d});
        m.triangles.push_back({b, c, d});
      }
    }
  return m;
}

scene::Scene one_mesh_scene(const scene::Mesh& mesh, int w, int h) {
  scene::Scene s;
  s.name = "raster_test";
  s.source = "test";
  s.materials.resize(1);
  s.meshes = {mesh};
  s.meshes[0].material = 0;
  scene::Node n;
  n.name = mesh.name;
  n.mesh = 0;
  s.nodes = {n};
  s.camera.width = w;
  s.camera.height = h;
  return s;
}

}  // namespace

// Which object a sample sees can differ between the two only where its ray passes within float
// rounding of a triangle's edge or where two surfaces lie at equal depth within rounding (contact
// lines, such as cornell's boxes standing on its floor, where either answer is right): both on
// silhouette pixels (a pixel whose 3x3 neighbourhood, in either buffer, holds two objects).
// Measured: 21 of 1784 silhouette pixels (1.2 %, cornell, display) and 7 of 238 (2.9 %, cornell,
// receiver buffer), 0 on every other scene, 0 off silhouettes. The bound allows about twice the
// largest share, and nothing off silhouettes.
constexpr double kMaxMismatchPerSilhouettePixel = 1.0 / 16.0;
// Where both see the same triangle, the same ray meets the same plane: positions agree to float
// rounding of the ray parameter, a few ulps of the eye distance, grown by 1 / cos of the incidence
// for surfaces seen at a grazing angle (measured at most 1.7e-6 of it, atrium; 2e-7 to 7e-7
// elsewhere).
constexpr float kPositionRelEye = 1e-5f;
// "Well inside a triangle": every barycentric of the traced hit above this. Rounding moves a sample
// across an edge only within a few ulps of it (barycentrics of order 1e-7); the margin also keeps
// off the edges of triangles seen nearly edge-on, whose barycentrics change fast across a pixel.
constexpr float kInterior = 1e-3f;
// Enough surface pixels per scene and scale that the comparison looks at something.
constexpr int kMinComparedPixels = 40;

TEST(RasterVisibility, MatchesTheEmbreeTraceOnEveryBuiltinScene) {
  constexpr int kWidth = 96;
  for (const auto& info : scene::builtin_scenes()) {
    if (info.needs_assets) continue;  // the asset-free scenes cover the geometry kinds
    const scene::Scene sc = scene::make_builtin(info.name);
    int w = kWidth, h = 0;
    render::resolve_resolution(sc.camera, w, h);
    const scene::PosedScene posed = scene::evaluate(sc, 0.5);
    for (int scale : {1, 4}) {
      SCOPED_TRACE(info.name + " at scale " + std::to_string(scale));
      render::PassRecord rr, re;
      const render::GBuffer r = run(sc, posed, "raster", scale, w, h, &rr);
      const render::GBuffer e = run(sc, posed, "embree", scale, w, h, &re);
      ASSERT_EQ(r.width, e.width);
      ASSERT_EQ(r.height, e.height);
      EXPECT_EQ(rr.counters.at("raster"), 1.0);
      EXPECT_EQ(re.counters.at("raster"), 0.0);
      EXPECT_EQ(rr.counters.at("triangles"), re.counters.at("triangles"));
      int silhouette_px = 0, mismatches = 0, off_silhouette = 0, compared = 0, interior = 0, interior_mismatches = 0;
      float max_rel = 0.0f;
      const glm::vec3 eye = sc.camera.position;
      for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * r.width + x;
          const bool sil = silhouette(r, x, y) || silhouette(e, x, y);
          silhouette_px += sil ? 1 : 0;
          // A sample whose ray meets the traced triangle well inside it (every barycentric above
          // kInterior) lies off every edge by far more than rounding: the rasteriser must find the
          // same triangle there, whatever the silhouettes.
          const glm::vec2 b = e.barycentric[i];
          if (e.hit(i) && b.x > kInterior && b.y > kInterior && 1.0f - b.x - b.y > kInterior) {
            ++interior;
            interior_mismatches += r.object[i] != e.object[i] || r.primitive[i] != e.primitive[i] ? 1 : 0;
          }
          if (r.object[i] != e.object[i]) {
            ++mismatches;
            off_silhouette += sil ? 0 : 1;
            continue;
          }
          if (!r.hit(i) || r.primitive[i] != e.primitive[i]) continue;
          ++compared;
          max_rel = std::max(max_rel, glm::length(r.position[i] - e.position[i]) / glm::length(e.position[i] - eye));
          EXPECT_LE(std::fabs(r.depth[i] - e.depth[i]), kPositionRelEye * glm::length(e.position[i] - eye));
        }
      EXPECT_GE(compared, kMinComparedPixels);
      EXPECT_LE(mismatches, kMaxMismatchPerSilhouettePixel * silhouette_px) << silhouette_px << " silhouette pixels";
      EXPECT_EQ(off_silhouette, 0);
      EXPECT_EQ(interior_mismatches, 0) << "of " << interior << " samples well inside a triangle";
      EXPECT_GE(interior, kMinComparedPixels);
      EXPECT_LE(max_rel, kPositionRelEye);
    }
  }
}

TEST(RasterVisibility, NoCrackWhereSampleRaysPassExactlyThroughSharedEdges) {
  // The eye looks down -z at a grid in z = -1 that fills the view. With an odd square image, the
  // centre column's and centre row's rays have sx = 0 or sy = 0 exactly and the anti-diagonal's
  // sx = -sy exactly: they meet the grid lines x = 0, y = 0 and the diagonals x = -y exactly, where
  // every edge function of the triangles that share those edges is exactly 0. A test that counted
  // such a sample for neither triangle would leave whole lines of holes.
  constexpr int kSide = 65;
  for (int diag : {0, 1, 2}) {
    SCOPED_TRACE("diagonals " + std::to_string(diag));
    scene::Scene sc = one_mesh_scene(grid(16, 2.0f, -1.0f, diag, 0.0f, 1), kSide, kSide);
    sc.camera.position = {0.0f, 0.0f, 0.0f};
    sc.camera.target = {0.0f, 0.0f, -1.0f};
    sc.camera.up = {0.0f, 1.0f, 0.0f};
    sc.camera.fov_y_deg = 90.0f;  // the view's half-width at z = -1 is 1, inside the grid's 2
    const render::GBuffer g = run(sc, "raster");
    int holes = 0;
    for (std::size_t i = 0; i < g.object.size(); ++i) holes += g.hit(i) ? 0 : 1;
    EXPECT_EQ(holes, 0);
  }
}

TEST(RasterVisibility, NoCrackInAnIrregularMeshFromManyViews) {
  // A jittered grid (no edge aligned with anything) seen from random eyes: every sample whose ray
  // meets the grid's square away from its border (by a thousandth of its size) must see the grid.
  constexpr float kHalf = 1.0f;
  constexpr float kBorder = 1e-3f;
  const scene::Mesh mesh = grid(24, kHalf, 0.0f, 2, 0.35f, 7);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int checked = 0;
  for (int view = 0; view < 12; ++view) {
    scene::Scene sc = one_mesh_scene(mesh, 80, 60);
    sc.camera.position = {0.8f * u(rng), 0.8f * u(rng), view % 2 ? 1.5f + u(rng) : -1.5f - u(rng)};  // both sides
    sc.camera.target = {0.3f * u(rng), 0.3f * u(rng), 0.0f};
    sc.camera.up = {0.0f, 1.0f, 0.0f};
    sc.camera.fov_y_deg = 70.0f;
    const render::GBuffer g = run(sc, "raster");
    const render::PinholeCamera cam = render::make_pinhole_camera(sc, 80, 60, "test");
    for (int y = 0; y < g.height; ++y)
      for (int x = 0; x < g.width; ++x) {
        const glm::vec3 d = cam.pixel_center_direction(x, y);
        if (d.z == 0.0f) continue;
        const float t = -cam.position.z / d.z;
        if (!(t > 0.0f)) continue;
        const glm::vec3 p = cam.position + t * d;
        if (std::fabs(p.x) > kHalf - kBorder || std::fabs(p.y) > kHalf - kBorder) continue;
        ++checked;
        EXPECT_TRUE(g.hit(static_cast<std::size_t>(y) * g.width + x)) << "view " << view << " pixel (" << x << ", " << y << ")";
      }
  }
  EXPECT_GT(checked, 10000);
}

TEST(RasterVisibility, SmallFarTrianglesKeepTheRayTracersPrecision) {
  // Triangles 1 cm across, 100 m away, seen obliquely from an eye off every axis: the edge
  // functions are formed from the edge vectors, not from products of eye-relative positions, so
  // the meeting point's error stays at float rounding of the eye distance (as a ray tracer's), not
  // that times distance / size (1e4 here).
  scene::Scene sc = one_mesh_scene(grid(8, 0.04f, 0.0f, 2, 0.3f, 3), 64, 64);
  sc.camera.position = {61.0f, 47.0f, 63.7f};
  sc.camera.target = {0.0f, 0.0f, 0.0f};
  sc.camera.up = {0.0f, 1.0f, 0.0f};
  sc.camera.fov_y_deg = 0.04f;  // the grid (8 cm, foreshortened) fills much of the view
  const render::GBuffer g = run(sc, "raster");
  const render::PinholeCamera cam = render::make_pinhole_camera(sc, 64, 64, "test");
  // Float rounding of the ray parameter and of positions 100 m from the origin of the eye: a few
  // ulps of 100 (ulp 7.6e-6).
  constexpr float kTol = 5e-5f;
  int hits = 0;
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * g.width + x;
      if (!g.hit(i)) continue;
      ++hits;
      const glm::vec3 d = cam.pixel_center_direction(x, y);
      const glm::vec3 exact = cam.position + (-cam.position.z / d.z) * d;
      EXPECT_LE(glm::length(g.position[i] - exact), kTol) << x << "," << y;
    }
  EXPECT_GT(hits, 1500);
}

TEST(RasterVisibility, TrianglesThatReachBehindTheEye) {
  // A floor of two triangles 2 km across under an eye 1 m above it, looking at the horizon: every
  // triangle has corners behind the eye. Each sample sees the floor exactly when its ray points down.
  scene::Mesh floor;
  floor.name = "floor";
  const float k = 1000.0f;
  floor.positions = {{-k, 0, -k}, {-k, 0, k}, {k, 0, k}, {k, 0, -k}};
  floor.normals.assign(4, glm::vec3(0, 1, 0));
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  scene::Scene sc = one_mesh_scene(floor, 64, 48);
  sc.camera.position = {0.3f, 1.0f, 0.2f};
  sc.camera.target = {0.5f, 0.9f, -5.0f};
  sc.camera.up = {0.0f, 1.0f, 0.0f};
  sc.camera.fov_y_deg = 60.0f;
  const render::GBuffer g = run(sc, "raster");
  const render::PinholeCamera cam = render::make_pinhole_camera(sc, 64, 48, "test");
  int floor_px = 0, sky_px = 0;
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) {
      const glm::vec3 d = cam.pixel_center_direction(x, y);
      // Rays that meet y = 0 within the floor's extent (all downward rays here but the most
      // grazing, which reach more than 1 km).
      const float t = d.y < 0.0f ? -cam.position.y / d.y : -1.0f;
      const glm::vec3 p = cam.position + t * d;
      const bool down = t > 0.0f && std::fabs(p.x) < 0.99f * k && std::fabs(p.z) < 0.99f * k;
      const bool up = d.y > 0.0f;
      if (!down && !up) continue;
      const std::size_t i = static_cast<std::size_t>(y) * g.width + x;
      EXPECT_EQ(g.hit(i), down) << x << "," << y;
      floor_px += down ? 1 : 0;
      sky_px += up ? 1 : 0;
    }
  EXPECT_GT(floor_px, 500);
  EXPECT_GT(sky_px, 500);
}

TEST(RasterVisibility, EqualDepthsGoToTheFirstObject) {
  // Two objects with the same triangles: every sample is a tie, kept by the first object whichever
  // thread bins or tests what.
  scene::Scene sc = one_mesh_scene(grid(8, 1.0f, 0.0f, 2, 0.2f, 5), 64, 64);
  scene::Node second = sc.nodes[0];
  second.name = "copy";
  sc.nodes.push_back(second);
  sc.camera.position = {0.2f, -0.3f, 3.0f};
  sc.camera.target = {0.0f, 0.0f, 0.0f};
  sc.camera.up = {0.0f, 1.0f, 0.0f};
  sc.camera.fov_y_deg = 40.0f;
  const render::GBuffer g = run(sc, "raster");
  int hits = 0;
  for (std::size_t i = 0; i < g.object.size(); ++i) {
    if (!g.hit(i)) continue;
    ++hits;
    EXPECT_EQ(g.object[i], 0) << i;
  }
  EXPECT_GT(hits, 1000);
}

TEST(RasterVisibility, BadInputIsAnErrorNamingIt) {
  scene::Scene sc = one_mesh_scene(grid(2, 1.0f, 0.0f, 0, 0.0f, 1), 16, 16);
  sc.camera.position = {0.0f, 0.0f, 3.0f};
  sc.camera.target = {0.0f, 0.0f, 0.0f};
  auto expect_error = [&](const scene::Scene& bad, const char* visibility, const std::string& what) {
    try {
      run(bad, visibility);
      ADD_FAILURE() << "accepted; expected an error naming " << what;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  expect_error(sc, "sometimes", "SOFTGI_CPU_VISIBILITY is 'sometimes'");
  scene::Scene bad = sc;
  bad.meshes[0].positions[4].y = std::numeric_limits<float>::quiet_NaN();
  expect_error(bad, "raster", "mesh 'grid': posed vertex 4 is not finite");
  bad = sc;
  bad.meshes[0].triangles.push_back({0, 1, 42});
  expect_error(bad, "raster", "mesh 'grid': triangle 8 has vertex index 42");
  bad = sc;
  bad.meshes[0].positions[4] = {3e37f, -3e37f, 0.0f};  // finite, but its edge products overflow
  expect_error(bad, "raster", "is too large for float arithmetic");
}

TEST(RasterVisibility, AFramesReceiverBufferReusesItsDisplayBuffersSetUp) {
  // The set-up depends on the camera and the posed geometry only: within one frame the receiver
  // buffer reuses the display buffer's and gives what a frame of its own gives, to the bit; the
  // next frame (the character moved) sets up again.
  backends::register_cpu_backend();
  const scene::Scene sc = scene::make_builtin("character");
  int w = 120, h = 0;
  render::resolve_resolution(sc.camera, w, h);
  render::ParamSet params({render::ParamDesc::integer("receiver_scale", 1, 1, 64, "receiver buffer scale")});
  params.set("receiver_scale", "3");
  auto pass = [](const char* name) { return render::find_shared_pass_impl(name, backends::cpu::kBackendName); };
  softgi::testing::ScopedVisibility raster("raster");
  auto frame = [&](double t, bool display, render::GBuffer& out) {
    const scene::PosedScene posed = scene::evaluate(sc, t);
    render::FrameResult result;
    render::FrameContext ctx(sc, posed, params, w, h, result);
    if (display) {
      result.passes.push_back(render::PassRecord{"gbuffer"});
      (*pass("gbuffer"))(ctx);
      EXPECT_EQ(result.passes.back().counters.at("raster_setup_reused"), 0.0);
    }
    result.passes.push_back(render::PassRecord{"receiver_gbuffer"});
    (*pass("receiver_gbuffer"))(ctx);
    out = ctx.get<render::GBuffer>(render::kReceiverGBuffer);
    return result.passes.back().counters.at("raster_setup_reused");
  };
  render::GBuffer shared, alone, later;
  EXPECT_EQ(frame(0.0, true, shared), 1.0);
  EXPECT_EQ(frame(0.0, false, alone), 0.0);
  EXPECT_EQ(frame(0.5, false, later), 0.0);
  ASSERT_EQ(shared.object.size(), alone.object.size());
  int hits = 0, moved = 0;
  for (std::size_t i = 0; i < shared.object.size(); ++i) {
    ASSERT_EQ(shared.object[i], alone.object[i]) << i;
    ASSERT_EQ(shared.primitive[i], alone.primitive[i]) << i;
    ASSERT_EQ(shared.barycentric[i], alone.barycentric[i]) << i;
    hits += shared.hit(i) ? 1 : 0;
    moved += shared.primitive[i] != later.primitive[i] ? 1 : 0;
  }
  EXPECT_GT(hits, 100);
  EXPECT_GT(moved, 10) << "the later frame sees the character elsewhere";
}

TEST(RasterVisibility, ReceiverSamplesBeyondTheDisplayImageSeeTheGeometryThere) {
  // 100 x 60 at scale 7: the receiver buffer is 15 x 9 and its last column and row sample display
  // points 101.5 and 59.5 + 3.5 beyond the image's edge. A fine grid reaching well past the view
  // covers every such sample: none may be culled as off screen, whether or not the frame's display
  // buffer was set up first.
  backends::register_cpu_backend();
  scene::Scene sc = one_mesh_scene(grid(64, 2.0f, 0.0f, 2, 0.2f, 9), 100, 60);
  sc.camera.position = {0.0f, 0.0f, 3.0f};
  sc.camera.target = {0.0f, 0.0f, 0.0f};
  sc.camera.up = {0.0f, 1.0f, 0.0f};
  sc.camera.fov_y_deg = 40.0f;
  ASSERT_GT(((15 - 1) + 0.5f) * 7.0f, 100.0f) << "the last receiver column lies beyond the display image";
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  render::ParamSet params({render::ParamDesc::integer("receiver_scale", 1, 1, 64, "receiver buffer scale")});
  params.set("receiver_scale", "7");
  softgi::testing::ScopedVisibility raster("raster");
  for (bool display_first : {false, true}) {
    render::FrameResult result;
    render::FrameContext ctx(sc, posed, params, 100, 60, result);
    if (display_first) {
      result.passes.push_back(render::PassRecord{"gbuffer"});
      (*render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName))(ctx);
    }
    result.passes.push_back(render::PassRecord{"receiver_gbuffer"});
    (*render::find_shared_pass_impl("receiver_gbuffer", backends::cpu::kBackendName))(ctx);
    const render::GBuffer& r = ctx.get<render::GBuffer>(render::kReceiverGBuffer);
    ASSERT_EQ(r.width, 15);
    ASSERT_EQ(r.height, 9);
    for (int y = 0; y < r.height; ++y)
      for (int x = 0; x < r.width; ++x)
        EXPECT_TRUE(r.hit(static_cast<std::size_t>(y) * r.width + x))
            << "receiver sample (" << x << ", " << y << ")" << (display_first ? " after the display buffer" : "");
  }
}

// The set-up's edge forms (edge normals with their lexicographic selects, geometric normal, det and
// the twelve dot products) come from a kernel vectorised across triangles; it must give the bits of
// the same arithmetic done one triangle at a time with glm (the set-up before it was vectorised):
// every triangle of every asset-free built-in scene from its camera and from random eyes, and random
// triangles spanning float's range (tiny, huge, denormal, shared coordinates that exercise the
// lexicographic ties, eyes inside the triangle's plane).
TEST(RasterVisibility, TheVectorisedSetUpIsTheScalarArithmetic) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::size_t triangles = 0;
  for (const auto& info : scene::builtin_scenes()) {
    if (info.needs_assets) continue;
    scene::Scene sc = scene::make_builtin(info.name);
    const scene::PosedScene posed = scene::evaluate(sc, 0.5);
    for (int view = 0; view < 3; ++view) {
      SCOPED_TRACE(info.name + " view " + std::to_string(view));
      if (view > 0) sc.camera.position = sc.camera.target + glm::vec3(4.0f * u(rng), 4.0f * u(rng), 4.0f * u(rng));
      const render::PinholeCamera cam = render::make_pinhole_camera(sc, 64, 48, "test");
      EXPECT_EQ(backends::cpu_raster::edge_form_differences(cam, posed), 0u);
      for (const auto& o : posed.objects) triangles += o.source ? o.source->triangles.size() : 0;
    }
  }
  EXPECT_GT(triangles, 10000u);
  // Random triangles: coordinates from a few shared values (ties in every coordinate) and from a
  // log-uniform spread over float's range.
  std::uniform_int_distribution<int> pick(0, 5), expo(-40, 30);
  const float shared[6] = {0.0f, -0.0f, 1.0f, -1.0f, 1e-42f, 3.5f};
  scene::Mesh m;
  m.name = "random";
  for (int t = 0; t < 3000; ++t) {
    for (int v = 0; v < 3; ++v) {
      glm::vec3 p;
      for (int c = 0; c < 3; ++c)
        p[c] = t % 3 == 0 ? shared[pick(rng)] : u(rng) * std::ldexp(1.0f, t % 3 == 1 ? expo(rng) : 0);
      m.positions.push_back(p);
      m.normals.push_back({0.0f, 0.0f, 1.0f});
    }
    const unsigned b = static_cast<unsigned>(3 * t);
    m.triangles.push_back({b, b + 1, b + 2});
  }
  scene::Scene sc = one_mesh_scene(m, 32, 32);
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  for (const glm::vec3 eye : {glm::vec3(0.0f, 0.0f, 5.0f), glm::vec3(0.0f), glm::vec3(1.0f, 1.0f, 1.0f), glm::vec3(1e-30f, 2e20f, -3.0f)}) {
    sc.camera.position = eye;
    sc.camera.target = eye + glm::vec3(0.3f, -0.2f, -1.0f);
    const render::PinholeCamera cam = render::make_pinhole_camera(sc, 32, 32, "test");
    EXPECT_EQ(backends::cpu_raster::edge_form_differences(cam, posed), 0u) << "eye " << eye.x << ", " << eye.y << ", " << eye.z;
  }
}
