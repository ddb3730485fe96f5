// Per-vertex values seen through the G-buffer: barycentric interpolation reproduces any function
// that is linear in position exactly (up to float rounding), on every visible triangle.
#include <gtest/gtest.h>

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
  scene::Scene scene = softgi::testing::make_plane_sphere_scene();
  scene::PosedScene posed = scene::evaluate(scene, 0.0);
  render::GBuffer gb;
  Frame() {
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
