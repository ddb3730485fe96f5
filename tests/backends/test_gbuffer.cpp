// The CPU G-buffer pass on a plane-and-sphere scene built in code, against closed forms: the plane's
// ray intersection and depth per pixel, sphere normals (p - c) / |p - c|, barycentrics reproducing
// the analytic hit point, and the camera shared with the reference renderer; with each of its
// primary-visibility methods (SOFTGI_CPU_VISIBILITY: raster, the default, and embree).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

#include "softgi/backends/cpu_backend.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "test_scene_util.hpp"

using namespace softgi;
using softgi::testing::PlaneSphere;

namespace {

// Positions are float: a few ulps of the scene's extent (about 4 units) plus Embree's own
// intersection rounding, which is of the order of 1e-6 relative to the distance travelled.
constexpr float kPositionTol = 2e-5f;
// Depth is a dot product of such positions with the unit view direction.
constexpr float kDepthTol = 2e-5f;
// Unit vectors from normalised float sums.
constexpr float kUnitTol = 1e-5f;
// Albedo: products of three float values in [0, 1].
constexpr float kAlbedoTol = 1e-5f;
// Enough pixels of each kind that the test cannot pass by not looking (the framing gives several
// hundred sphere pixels and thousands of plane pixels at 128 x 96).
constexpr int kMinPixelsOfEachKind = 200;

// Each visibility method: "" is the default (rasterised, checked by the counter).
class GBufferVisibility : public ::testing::TestWithParam<std::string> {
 protected:
  softgi::testing::ScopedVisibility visibility_{GetParam()};
};
INSTANTIATE_TEST_SUITE_P(CpuVisibility, GBufferVisibility, ::testing::Values("", "embree"),
                         [](const ::testing::TestParamInfo<std::string>& i) { return i.param.empty() ? std::string("default_raster") : i.param; });

render::GBuffer run_gbuffer(const scene::Scene& sc, render::FrameResult& result, double t = 0.0) {
  backends::CpuBackend backend;  // registers the CPU shared passes
  const render::PassFn* fn = render::find_shared_pass_impl("gbuffer", backends::cpu::kBackendName);
  EXPECT_NE(fn, nullptr);
  scene::PosedScene posed = scene::evaluate(sc, t);
  render::ParamSet params;
  render::FrameContext ctx(sc, posed, params, sc.camera.width, sc.camera.height, result);
  result.passes.push_back(render::PassRecord{"gbuffer"});
  (*fn)(ctx);
  return ctx.get<render::GBuffer>(render::kGBuffer);
}

glm::vec3 vertex(const scene::Scene& sc, const scene::PosedScene& posed, int object, int prim, int corner) {
  const glm::uvec3 tri = sc.meshes[posed.objects[object].mesh].triangles[prim];
  return posed.objects[object].positions[tri[corner]];
}

void expect_near3(const glm::vec3& a, const glm::vec3& b, float tol, const char* what, int x, int y) {
  EXPECT_LE(glm::length(a - b), tol) << what << " at pixel (" << x << ", " << y << "): (" << a.x << ", " << a.y << ", "
                                     << a.z << ") vs (" << b.x << ", " << b.y << ", " << b.z << ")";
}

}  // namespace

TEST(Camera, PinholeGeometryFromFovAndAspect) {
  scene::Scene sc = softgi::testing::make_plane_sphere_scene(65, 33);
  const render::PinholeCamera cam = render::make_pinhole_camera(sc, 65, 33, "test");
  const glm::vec3 fwd = glm::normalize(sc.camera.target - sc.camera.position);
  // Odd sizes: the centre pixel's centre is the image centre, on the optical axis.
  expect_near3(cam.pixel_center_direction(32, 16), fwd, kUnitTol, "centre ray", 32, 16);
  // The top edge's midpoint is fov_y / 2 above the axis; the left edge's is atan(aspect tan(fov_y / 2)) aside.
  const double half = 0.5 * sc.camera.fov_y_deg * softgi::testing::kPi / 180.0;
  EXPECT_NEAR(std::acos(glm::dot(cam.direction(32.5f, 0.0f), fwd)), half, 1e-5);
  EXPECT_GT(glm::dot(cam.direction(32.5f, 0.0f), cam.up), 0.0f) << "row 0 must be the top row";
  EXPECT_NEAR(std::acos(glm::dot(cam.direction(0.0f, 16.5f), fwd)), std::atan(65.0 / 33.0 * std::tan(half)), 1e-5);
  EXPECT_LT(glm::dot(cam.direction(0.0f, 16.5f), cam.right), 0.0f) << "column 0 must be on the left";
  EXPECT_NEAR(cam.depth(sc.camera.position + 2.0f * fwd), 2.0f, 1e-6);

  int w = 0, h = 0;
  render::resolve_resolution(sc.camera, w, h);
  EXPECT_EQ(w, 65);
  EXPECT_EQ(h, 33);
  w = 130;
  h = 0;
  render::resolve_resolution(sc.camera, w, h);
  EXPECT_EQ(h, 66) << "one side given: the camera's aspect is kept";

  auto expect_error = [&](scene::Scene bad, int bw, int bh, const std::string& needle) {
    try {
      render::make_pinhole_camera(bad, bw, bh, "test");
      ADD_FAILURE() << needle << ": accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(sc, 0, 10, "image size 0x10");
  expect_error(sc, 10, 20000, "image size 10x20000");
  scene::Scene bad = sc;
  bad.camera.fov_y_deg = 180.0f;
  expect_error(bad, 10, 10, "camera.fov_y_deg");
  bad = sc;
  bad.camera.target = bad.camera.position;
  expect_error(bad, 10, 10, "camera position equals target");
  bad = sc;
  bad.camera.up = bad.camera.target - bad.camera.position;
  expect_error(bad, 10, 10, "camera.up is parallel");
  bad = sc;
  bad.camera.position.x = std::numeric_limits<float>::quiet_NaN();
  expect_error(bad, 10, 10, "not finite");
}

TEST(Camera, BufferRaysAreTheCamerasRaysToTheBit) {
  // Passes that go over a whole buffer take the rays from BufferRays (screen coordinates per column
  // and row); a background pixel's colour and a surface's side must be what buffer_direction gives,
  // so the two agree exactly, for every pixel, at display and receiver scales.
  scene::Scene sc = softgi::testing::make_plane_sphere_scene(65, 33);
  for (int scale : {1, 2, 3, 4}) {
    const render::PinholeCamera cam = render::make_pinhole_camera(sc, 65, 33, "test");
    const int w = (65 + scale - 1) / scale, h = (33 + scale - 1) / scale;
    const render::BufferRays rays(cam, w, h, scale);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        ASSERT_EQ(rays.direction(x, y), cam.buffer_direction(x, y, scale)) << "scale " << scale << " pixel " << x << ", " << y;
        ASSERT_EQ(rays.ray(x, y), cam.buffer_ray(x, y, scale)) << "scale " << scale << " pixel " << x << ", " << y;
      }
  }
}

TEST_P(GBufferVisibility, PlaneAndSphereMatchClosedForms) {
  const scene::Scene sc = softgi::testing::make_plane_sphere_scene();
  render::FrameResult result;
  const render::GBuffer gb = run_gbuffer(sc, result);
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::PinholeCamera cam = render::make_pinhole_camera(sc, sc.camera.width, sc.camera.height, "test");
  ASSERT_EQ(gb.width, sc.camera.width);
  ASSERT_EQ(gb.height, sc.camera.height);
  const std::size_t n = static_cast<std::size_t>(gb.width) * gb.height;
  for (auto size : {gb.position.size(), gb.normal.size(), gb.depth.size(), gb.albedo.size(), gb.object.size(),
                    gb.primitive.size(), gb.barycentric.size(), gb.view_dir.size()})
    ASSERT_EQ(size, n);

  const glm::vec3 c = PlaneSphere::center();
  const float r = PlaneSphere::kRadius;
  const float r_inner = r * static_cast<float>(1.0 - PlaneSphere::sagitta());
  int plane_px = 0, sphere_px = 0, background_px = 0, hits = 0;
  for (int y = 0; y < gb.height; ++y)
    for (int x = 0; x < gb.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * gb.width + x;
      hits += gb.hit(i) ? 1 : 0;
      const glm::vec3 e = sc.camera.position, d = cam.pixel_center_direction(x, y);
      const float b = softgi::testing::ray_center_distance(e, d);
      const auto tp = softgi::testing::hit_plane(e, d);
      if (b > r && !tp) {  // misses both: background
        ++background_px;
        EXPECT_EQ(gb.object[i], -1) << x << "," << y;
        EXPECT_EQ(gb.primitive[i], -1);
        EXPECT_TRUE(std::isinf(gb.depth[i]) && gb.depth[i] > 0);
        expect_near3(gb.view_dir[i], d, kUnitTol, "background view_dir (the ray direction)", x, y);
      } else if (b > r) {  // misses the true sphere, so its inscribed tessellation too: the plane
        ++plane_px;
        ASSERT_EQ(gb.object[i], 0) << "pixel (" << x << ", " << y << ") should see the plane";
        const glm::vec3 p = e + *tp * d;
        expect_near3(gb.position[i], p, kPositionTol, "plane position", x, y);
        EXPECT_NEAR(gb.depth[i], *tp * glm::dot(d, cam.forward), kDepthTol) << x << "," << y;
        // The barycentrics, applied to the triangle's posed vertices, land on the analytic point.
        const glm::vec2 bc = gb.barycentric[i];
        const int t = gb.primitive[i];
        ASSERT_TRUE(t == 0 || t == 1);
        const glm::vec3 q = (1.0f - bc.x - bc.y) * vertex(sc, posed, 0, t, 0) + bc.x * vertex(sc, posed, 0, t, 1) +
                            bc.y * vertex(sc, posed, 0, t, 2);
        expect_near3(q, p, kPositionTol, "barycentric reconstruction", x, y);
        EXPECT_GE(bc.x, 0.0f);
        EXPECT_GE(bc.y, 0.0f);
        EXPECT_LE(bc.x + bc.y, 1.0f + kUnitTol);
        expect_near3(gb.normal[i], glm::vec3(0, 1, 0), kUnitTol, "plane normal", x, y);
        expect_near3(gb.albedo[i], PlaneSphere::plane_albedo() * PlaneSphere::plane_color(p), kAlbedoTol, "plane albedo",
                     x, y);
        expect_near3(gb.view_dir[i], -d, kUnitTol, "view_dir", x, y);
      } else if (b < r_inner) {  // certainly through the tessellated sphere, which lies above the plane
        ++sphere_px;
        ASSERT_EQ(gb.object[i], 1) << "pixel (" << x << ", " << y << ") should see the sphere";
        const glm::vec3 p = gb.position[i];
        // Vertex normals (v - c) / r are linear in v, so their interpolation is (p - c) / r exactly and
        // the normalised shading normal is (p - c) / |p - c|.
        expect_near3(gb.normal[i], glm::normalize(p - c), kUnitTol, "sphere normal", x, y);
        EXPECT_GE(glm::length(p - c), r_inner - kPositionTol) << x << "," << y;
        EXPECT_LE(glm::length(p - c), r + kPositionTol) << x << "," << y;
        EXPECT_GT(glm::dot(gb.normal[i], -d), 0.0f) << "front of the sphere faces the viewer";
        // On the pixel's ray, at the depth the G-buffer reports.
        EXPECT_LE(glm::length(glm::cross(p - e, d)), kPositionTol) << x << "," << y;
        EXPECT_NEAR(gb.depth[i], glm::dot(p - e, cam.forward), kDepthTol);
        const glm::vec2 bc = gb.barycentric[i];
        const int t = gb.primitive[i];
        const glm::vec3 q = (1.0f - bc.x - bc.y) * vertex(sc, posed, 1, t, 0) + bc.x * vertex(sc, posed, 1, t, 1) +
                            bc.y * vertex(sc, posed, 1, t, 2);
        expect_near3(q, p, kPositionTol, "sphere barycentric reconstruction", x, y);
        expect_near3(gb.albedo[i], PlaneSphere::sphere_albedo(), kAlbedoTol, "sphere albedo", x, y);
        expect_near3(gb.view_dir[i], -d, kUnitTol, "view_dir", x, y);
      }
    }
  EXPECT_GE(plane_px, kMinPixelsOfEachKind);
  EXPECT_GE(sphere_px, kMinPixelsOfEachKind);
  EXPECT_GE(background_px, kMinPixelsOfEachKind);

  ASSERT_EQ(result.passes.size(), 1u);
  const render::PassRecord& rec = result.passes[0];
  EXPECT_EQ(rec.counters.at("rays"), static_cast<double>(n));
  EXPECT_EQ(rec.counters.at("hits"), static_cast<double>(hits));
  EXPECT_EQ(rec.counters.at("triangles"), static_cast<double>(sc.meshes[0].triangles.size() + sc.meshes[1].triangles.size()));
  EXPECT_GE(rec.bytes, gb.bytes()) << "bytes include the G-buffer planes";
  EXPECT_EQ(rec.counters.at("raster"), GetParam() == "embree" ? 0.0 : 1.0);
}

TEST_P(GBufferVisibility, SeesWhatTheUnjitteredReferenceSees) {
  // Black surfaces under a uniform white sky: the reference's pixel is 1 exactly where its camera ray
  // escapes, so its background mask must be the G-buffer's. A camera off by a quarter pixel
  // horizontally already disagrees on 23 silhouette pixels here (measured by shifting the rays).
  scene::Scene sc = softgi::testing::make_plane_sphere_scene();
  for (auto& m : sc.materials) m.albedo = glm::vec3(0.0f);
  sc.environment.kind = scene::Environment::Kind::Sky;
  sc.environment.zenith = sc.environment.horizon = sc.environment.ground = glm::vec3(1.0f);
  sc.environment.sun_radius = 0.0f;
  reference::ReferenceOptions opt;
  opt.spp = 1;
  opt.jitter = false;
  opt.indirect = false;
  const reference::ReferenceResult ref = reference::render_reference(sc, opt);
  render::FrameResult result;
  const render::GBuffer gb = run_gbuffer(sc, result);
  ASSERT_EQ(ref.final_image.width, gb.width);
  ASSERT_EQ(ref.final_image.height, gb.height);
  // Different BVH builds (or the rasteriser's edge functions) may round a ray that grazes the
  // silhouette differently; two such pixels are tolerated, far fewer than a camera mismatch would
  // produce.
  constexpr int kMaxGrazingMismatches = 2;
  int mismatches = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    const bool ref_background = ref.final_image.rgb[i].g > 0.5f;
    mismatches += ref_background != !gb.hit(i) ? 1 : 0;
  }
  EXPECT_LE(mismatches, kMaxGrazingMismatches);
}

TEST_P(GBufferVisibility, BadGeometryIsAnErrorNamingTheMesh) {
  scene::Scene sc = softgi::testing::make_plane_sphere_scene(16, 16);
  sc.meshes[0].triangles.push_back({0, 1, 99});
  render::FrameResult result;
  try {
    run_gbuffer(sc, result);
    ADD_FAILURE() << "out-of-range vertex index accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("mesh 'plane'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("99"), std::string::npos) << e.what();
  }
}

TEST(GBuffer, KeptSceneRefitsAndMatchesAFreshBuild) {
  const softgi::testing::ScopedVisibility embree("embree");
  // The Embree scene persists across frames: the same pose reuses it, a moved sphere refits it, a
  // different topology rebuilds it. A refitted scene must see what a fresh build of that pose sees.
  const scene::Scene moving = softgi::testing::animated(softgi::testing::make_plane_sphere_scene());
  scene::Scene other = softgi::testing::make_plane_sphere_scene();
  other.meshes[0].triangles.pop_back();  // another topology
  auto counter = [](const render::FrameResult& r, const char* k) { return r.passes.at(0).counters.at(k); };

  render::FrameResult r0, r1, r2, r3, r4;
  run_gbuffer(other, r0);
  EXPECT_EQ(counter(r0, "bvh_rebuilt"), 1.0);
  run_gbuffer(moving, r1, 0.0);
  EXPECT_EQ(counter(r1, "bvh_rebuilt"), 1.0) << "topology changed";
  const render::GBuffer g_same = run_gbuffer(moving, r2, 0.0);
  EXPECT_EQ(counter(r2, "bvh_rebuilt") + counter(r2, "bvh_refit"), 0.0) << "nothing moved: reused as is";
  const render::GBuffer g_refit = run_gbuffer(moving, r3, 0.75);
  EXPECT_EQ(counter(r3, "bvh_refit"), 1.0);
  EXPECT_EQ(counter(r3, "bvh_rebuilt"), 0.0);
  run_gbuffer(other, r0);
  const render::GBuffer g_fresh = run_gbuffer(moving, r4, 0.75);
  EXPECT_EQ(counter(r4, "bvh_rebuilt"), 1.0);

  // The sphere moved by 0.225 (more than 5 pixels on screen): the frames differ, refitted and fresh agree.
  int moved = 0, mismatches = 0;
  for (std::size_t i = 0; i < g_refit.object.size(); ++i) {
    moved += g_same.object[i] != g_refit.object[i] ? 1 : 0;
    if (g_refit.object[i] != g_fresh.object[i] || g_refit.primitive[i] != g_fresh.primitive[i]) {
      ++mismatches;
      continue;
    }
    if (g_refit.hit(i)) {
      EXPECT_LE(glm::length(g_refit.position[i] - g_fresh.position[i]), kPositionTol) << i;
    }
  }
  EXPECT_GT(moved, 50);
  constexpr int kMaxGrazingMismatches = 2;  // as in SeesWhatTheUnjitteredReferenceSees
  EXPECT_LE(mismatches, kMaxGrazingMismatches);
}
