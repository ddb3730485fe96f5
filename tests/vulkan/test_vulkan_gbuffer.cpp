// The Vulkan G-buffer (rasterisation, backends/vulkan/gbuffer_raster.cpp) against the CPU G-buffer
// (Embree ray casting through the same pixel centres) on every built-in scene, display buffer
// (scale 1) and receiver buffer (scale 4): which object each pixel sees, and on pixels where both
// see the same triangle, position, normal, depth, barycentrics, albedo and view direction. Every
// test runs under the validation layer (a message fails it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "softgi/techniques/shexp.hpp"
#include "../backends/test_scene_util.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
using softgi::testing::silhouette;
using softgi::testing::ValidatedTest;

namespace {

// Display width of the parity runs (height from the scene camera's aspect): small, so that the
// suite stays fast under ASan, yet every scene covers a few hundred surface pixels.
constexpr int kWidth = 96;
constexpr int kReceiverScale = 4;

// Which object a pixel centre sees differs between rasteriser and ray caster only (a) where the
// centre lies within the rasteriser's vertex snapping (1/2^subPixelPrecisionBits of a pixel: 1/256
// on lavapipe and desktop GPUs, at least 1/16 by the Vulkan spec) plus float rounding of an edge,
// and (b) along contact lines where two objects meet at equal depth (cornell's boxes on the floor:
// the depth test compares interpolated n / z, the ray caster exact distances, so either may win).
// Both happen on silhouette pixels only (a pixel whose 3x3 neighbourhood, in either buffer, holds
// two objects). For centres spread uniformly across a pixel, a 1/16-pixel band on either side of an
// edge catches about 1/8 of the silhouette pixels: the bound holds for a spec-minimum device.
// Measured on lavapipe: 42 of 1791 (2.3%) at 96x96 and 12 of 243 (4.9%) at 24x24 on cornell and
// cornell_glossy, 0-1 elsewhere.
constexpr double kMaxMismatchPerSilhouettePixel = 1.0 / 8.0;
// Object mismatches away from any silhouette cannot come from (a) or (b); measured 0 everywhere.
constexpr int kMaxMismatchesOffSilhouette = 0;
// On pixels with the same object and triangle both backends evaluate the same triangle at
// barycentrics that differ by float rounding and by the snapping above: a point on the triangle
// moves by at most (snap / cos(incidence)) pixel footprints (footprint: eye depth x
// 2 tan(fov/2) s / H). 1/64 of a footprint covers a 1/256-pixel snap up to 76 degrees of incidence
// (measured max 3.5e-4 footprints, character at scale 1).
constexpr float kPositionFootprints = 1.0f / 64.0f;
// Depth is the eye-space projection of the position: the same bound (measured max 2.0e-4).
constexpr float kDepthFootprints = 1.0f / 64.0f;
// Unit shading normals: float rounding of the normalised interpolated normal (~1e-6), plus the
// snapping's barycentric shift on sub-pixel triangles (up to ~1e-2, seen as barycentrics that far
// outside the triangle) times the vertex-normal difference across such a triangle (a few 1e-2).
// Measured: 99th percentile 1.1e-5, mean 3.6e-7, max 1.1e-4 (crowd, character).
constexpr float kNormalP99 = 1e-3f;
constexpr float kNormalMean = 1e-4f;
// Albedo: the same host function of (object, triangle, barycentrics); textures and vertex colours
// vary by far less than their range over such barycentric shifts (measured 99th percentile 6e-8).
constexpr float kAlbedoP99 = 1e-3f;
// Internal consistency of a Vulkan pixel: its position is w p0 + b1 p1 + b2 p2 of its own
// barycentrics and its depth (p - e) . E: float rounding of a few operations on coordinates of
// the scene's size (relative to the eye distance).
constexpr float kConsistencyRel = 1e-5f;
// The scenes must be looked at: at least this many pixels compared per scene and scale.
constexpr int kMinComparedPixels = 40;

float percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0.0f;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

class VulkanGBuffer : public ValidatedTest {
 protected:
  void SetUp() override {
    ValidatedTest::SetUp();
    cpu_ = std::make_unique<backends::CpuBackend>();
    vulkan_ = std::make_unique<backends::VulkanBackend>(ctx_);
  }
  void TearDown() override {
    vulkan_.reset();
    cpu_.reset();
    ValidatedTest::TearDown();
  }

  // Runs the shared pass on `backend`: "gbuffer" at scale 1, else "receiver_gbuffer" at `scale`
  // (without a display G-buffer in the frame, so that it is rasterised / traced, not copied).
  render::GBuffer run(const scene::Scene& sc, const scene::PosedScene& posed, const std::string& backend, int scale,
                      int w, int h, render::PassRecord* rec = nullptr) {
    const std::string pass = scale == 1 ? "gbuffer" : "receiver_gbuffer";
    const render::PassFn* fn = render::find_shared_pass_impl(pass, backend);
    if (!fn) throw std::logic_error("no " + pass + " for " + backend);
    render::ParamSet params({render::ParamDesc::integer("receiver_scale", 1, 1, 64, "receiver buffer scale")});
    params.set("receiver_scale", std::to_string(scale));
    render::FrameResult result;
    render::FrameContext fc(sc, posed, params, w, h, result, ctx_.get());
    result.passes.push_back(render::PassRecord{pass});
    (*fn)(fc);
    if (rec) *rec = result.passes.back();
    return fc.get<render::GBuffer>(scale == 1 ? render::kGBuffer : render::kReceiverGBuffer);
  }

  std::unique_ptr<backends::CpuBackend> cpu_;
  std::unique_ptr<backends::VulkanBackend> vulkan_;
};

}  // namespace

TEST_F(VulkanGBuffer, MatchesTheRayCastGBufferOnEveryBuiltinScene) {
  for (const scene::BuiltinInfo& info : scene::builtin_scenes()) {
    const scene::Scene sc = scene::make_builtin(info.name);
    int w = kWidth, h = 0;
    render::resolve_resolution(sc.camera, w, h);
    const render::PinholeCamera cam = render::make_pinhole_camera(sc, w, h, "test");
    const scene::PosedScene posed = scene::evaluate(sc, 0.0);
    for (const int scale : {1, kReceiverScale}) {
      SCOPED_TRACE(info.name + " at scale " + std::to_string(scale));
      render::PassRecord rec;
      const render::GBuffer ref = run(sc, posed, backends::cpu::kBackendName, scale, w, h);
      const render::GBuffer gb = run(sc, posed, backends::vulkan::kBackendName, scale, w, h, &rec);
      ASSERT_EQ(gb.width, (w + scale - 1) / scale);
      ASSERT_EQ(gb.height, (h + scale - 1) / scale);
      ASSERT_EQ(gb.width, ref.width);
      ASSERT_EQ(gb.height, ref.height);
      EXPECT_EQ(gb.scale, scale);
      const std::size_t n = static_cast<std::size_t>(gb.width) * gb.height;
      ASSERT_EQ(gb.object.size(), n);

      int mismatches = 0, off_silhouette = 0, silhouette_px = 0, compared = 0, hits = 0;
      float max_pos = 0.0f, max_depth = 0.0f, max_consistency = 0.0f;
      std::vector<float> normal_err, albedo_err;
      const float footprint_per_depth = 2.0f * cam.tan_half_fov_y * static_cast<float>(scale) / static_cast<float>(h);
      for (int y = 0; y < gb.height; ++y)
        for (int x = 0; x < gb.width; ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * gb.width + x;
          const bool sil = silhouette(ref, x, y) || silhouette(gb, x, y);
          silhouette_px += sil ? 1 : 0;
          hits += gb.hit(i) ? 1 : 0;
          // The view direction is a function of the pixel alone: the same float operations.
          const glm::vec3 dv = gb.view_dir[i] - (gb.hit(i) == ref.hit(i) ? ref.view_dir[i] : -ref.view_dir[i]);
          EXPECT_EQ(glm::length(dv), 0.0f) << "view_dir at (" << x << ", " << y << ")";
          if (gb.object[i] != ref.object[i]) {
            ++mismatches;
            off_silhouette += sil ? 0 : 1;
            continue;
          }
          if (!gb.hit(i)) {
            EXPECT_TRUE(std::isinf(gb.depth[i]) && gb.depth[i] > 0.0f);
            EXPECT_EQ(gb.primitive[i], -1);
            continue;
          }
          // Internal consistency: the plane values of a Vulkan pixel follow from its own triangle and
          // barycentrics, with the CPU's convention (b1, b2 weight corners 1 and 2).
          const scene::PosedObject& o = posed.objects[gb.object[i]];
          const glm::uvec3 tri = o.source->triangles[gb.primitive[i]];
          const float b1 = gb.barycentric[i].x, b2 = gb.barycentric[i].y, b0 = 1.0f - b1 - b2;
          const glm::vec3 p = b0 * o.positions[tri.x] + b1 * o.positions[tri.y] + b2 * o.positions[tri.z];
          const float dist = glm::length(p - cam.position);
          max_consistency = std::max(max_consistency, glm::length(gb.position[i] - p) / dist);
          max_consistency = std::max(max_consistency, std::abs(gb.depth[i] - cam.depth(p)) / dist);
          EXPECT_NEAR(glm::length(gb.normal[i]), 1.0f, 1e-5f);
          if (gb.primitive[i] != ref.primitive[i]) continue;
          ++compared;
          const float footprint = ref.depth[i] * footprint_per_depth;
          max_pos = std::max(max_pos, glm::length(gb.position[i] - ref.position[i]) / footprint);
          max_depth = std::max(max_depth, std::abs(gb.depth[i] - ref.depth[i]) / footprint);
          normal_err.push_back(glm::length(gb.normal[i] - ref.normal[i]));
          albedo_err.push_back(glm::length(gb.albedo[i] - ref.albedo[i]));
        }
      float normal_mean = 0.0f;
      for (float e : normal_err) normal_mean += e / static_cast<float>(std::max<std::size_t>(1, normal_err.size()));
      std::printf("%-10s s=%d  %dx%d  hits %d  silhouette %d  mismatches %d (off silhouette %d)  compared %d  "
                  "pos %.3g fp  depth %.3g fp  normal p99 %.3g mean %.3g max %.3g  albedo p99 %.3g  consistency %.3g\n",
                  info.name.c_str(), scale, gb.width, gb.height, hits, silhouette_px, mismatches, off_silhouette, compared,
                  max_pos, max_depth, percentile(normal_err, 0.99), normal_mean, percentile(normal_err, 1.0),
                  percentile(albedo_err, 0.99), max_consistency);
      EXPECT_GE(compared, kMinComparedPixels);
      EXPECT_LE(mismatches, kMaxMismatchPerSilhouettePixel * silhouette_px);
      EXPECT_LE(off_silhouette, kMaxMismatchesOffSilhouette);
      EXPECT_LE(max_pos, kPositionFootprints);
      EXPECT_LE(max_depth, kDepthFootprints);
      EXPECT_LE(percentile(normal_err, 0.99), kNormalP99);
      EXPECT_LE(normal_mean, kNormalMean);
      EXPECT_LE(percentile(albedo_err, 0.99), kAlbedoP99);
      EXPECT_LE(max_consistency, kConsistencyRel);
      EXPECT_EQ(rec.counters.at("rays"), static_cast<double>(n));
      EXPECT_EQ(rec.counters.at("hits"), static_cast<double>(hits));
      EXPECT_GE(rec.bytes, gb.bytes());
      if (ctx().device_info().timestamp_valid_bits > 0) {
        EXPECT_GT(rec.counters.at("raster_gpu_seconds"), 0.0) << "the rasterisation's GPU timer";
      }
    }
  }
}

TEST_F(VulkanGBuffer, BadGeometryIsAnErrorNamingTheMesh) {
  scene::Scene sc = scene::make_builtin("spheres");
  ASSERT_FALSE(sc.meshes.empty());
  const std::string mesh = sc.meshes[0].name;
  {
    scene::PosedScene posed = scene::evaluate(sc, 0.0);
    int k = -1;
    for (std::size_t i = 0; i < posed.objects.size(); ++i)
      if (posed.objects[i].source == &sc.meshes[0]) k = static_cast<int>(i);
    ASSERT_GE(k, 0);
    posed.objects[k].positions[1].y = std::numeric_limits<float>::quiet_NaN();
    try {
      run(sc, posed, backends::vulkan::kBackendName, 1, 32, 24);
      ADD_FAILURE() << "non-finite vertex accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("mesh '" + mesh + "'"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("not finite"), std::string::npos) << e.what();
    }
  }
  sc.meshes[0].triangles.push_back({0, 1, 999999});
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  try {
    run(sc, posed, backends::vulkan::kBackendName, kReceiverScale, 32, 24);
    ADD_FAILURE() << "out-of-range vertex index accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("mesh '" + mesh + "'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("999999"), std::string::npos) << e.what();
  }
}

// A camera with every surface behind it: the Vulkan G-buffer draws nothing and fills the background
// itself, for a frame that holds only the visibility planes (SHEXP, which derives the background
// rays) as well as for one that holds every plane (image_splat). Both frames are the CPU backend's
// background, and nothing is written to a plane the frame does not hold (this crashed).
TEST_F(VulkanGBuffer, ACameraFacingAwayFromEverySurfaceSeesTheBackground) {
  scene::Scene sc = scene::make_builtin("spheres");
  sc.camera.target = sc.camera.position + glm::vec3(1e-3f, 1.0f, 0.0f);  // straight up: the floor is below the eye
  sc.camera.up = {0.0f, 0.0f, 1.0f};
  render::RenderRequest req;
  req.width = 32;
  req.height = 24;
  std::vector<std::unique_ptr<render::Technique>> techs;
  techs.push_back(techniques::shexp::create());
  techs.push_back(techniques::image_splat::create());
  for (const auto& tech : techs) {
    SCOPED_TRACE(tech->name());
    const render::ParamSet params = render::default_params(*tech);
    const render::FrameResult a = vulkan_->render(*tech, sc, params, req);
    const render::FrameResult b = cpu_->render(*tech, sc, params, req);
    ASSERT_EQ(a.final_image.rgb.size(), b.final_image.rgb.size());
    float peak = 0.0f, diff = 0.0f;
    for (std::size_t i = 0; i < a.final_image.rgb.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(a.final_image.rgb[i][c]));
        peak = std::max(peak, std::abs(b.final_image.rgb[i][c]));
        diff = std::max(diff, std::abs(a.final_image.rgb[i][c] - b.final_image.rgb[i][c]));
      }
    EXPECT_GT(peak, 0.0f) << "the sky is lit";
    // The same host function of the same rays on both backends.
    EXPECT_EQ(diff, 0.0f);
  }
}
