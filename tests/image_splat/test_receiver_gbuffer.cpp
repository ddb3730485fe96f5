// The shared "receiver_gbuffer" pass on the CPU backend (paper 000 section 4, receiver setup): at
// scale 1 a copy of the display G-buffer, at scale s the display camera's rays through display points
// ((x + 0.5) s, (y + 0.5) s), checked against the plane's closed-form intersection; bad scales named.
#include <array>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "../backends/test_scene_util.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"

using namespace softgi;

namespace {

// Float positions of a scene about 4 units across, plus Embree's intersection rounding (the
// tolerance of tests/backends/test_gbuffer.cpp).
constexpr float kPositionTol = 2e-5f;
constexpr float kDepthTol = 2e-5f;

struct Frame {
  scene::Scene sc;
  scene::PosedScene posed;
  render::ParamSet params;
  render::FrameResult result;
  std::unique_ptr<render::FrameContext> ctx;
  Frame(int w, int h, int scale) : sc(softgi::testing::make_plane_sphere_scene(w, h)), posed(scene::evaluate(sc, 0.0)) {
    params = render::ParamSet({render::ParamDesc::integer("receiver_scale", scale, 1, 64, "test")});
    ctx = std::make_unique<render::FrameContext>(sc, posed, params, w, h, result);
  }
  void run(const char* pass) {
    backends::CpuBackend backend;  // registers the CPU shared passes
    const render::PassFn* fn = render::find_shared_pass_impl(pass, backends::cpu::kBackendName);
    ASSERT_NE(fn, nullptr) << pass;
    result.passes.push_back(render::PassRecord{pass});
    (*fn)(*ctx);
  }
};

}  // namespace

TEST(ReceiverGBuffer, ScaleOneCopiesTheDisplayGBuffer) {
  Frame f(40, 30, 1);
  f.run("gbuffer");
  f.run("receiver_gbuffer");
  const auto& gb = f.ctx->get<render::GBuffer>(render::kGBuffer);
  const auto& rb = f.ctx->get<render::GBuffer>(render::kReceiverGBuffer);
  EXPECT_EQ(rb.scale, 1);
  ASSERT_EQ(rb.width, gb.width);
  ASSERT_EQ(rb.height, gb.height);
  EXPECT_EQ(rb.position, gb.position);
  EXPECT_EQ(rb.depth, gb.depth);
  EXPECT_EQ(rb.object, gb.object);
  EXPECT_EQ(f.result.passes.back().counters.at("copied"), 1.0);
  // Without a display G-buffer in the frame it traces, and sees the same.
  Frame g(40, 30, 1);
  g.run("receiver_gbuffer");
  const auto& tb = g.ctx->get<render::GBuffer>(render::kReceiverGBuffer);
  EXPECT_EQ(g.result.passes.back().counters.at("copied"), 0.0);
  EXPECT_EQ(tb.object, gb.object);
  for (std::size_t i = 0; i < tb.depth.size(); ++i)
    if (gb.hit(i)) { EXPECT_NEAR(tb.depth[i], gb.depth[i], kDepthTol) << i; }
}

TEST(ReceiverGBuffer, CoarsePixelsSampleEveryScaleThDisplayPoint) {
  for (int s : {2, 3, 4, 8}) {
    // 45 x 31 is not a multiple of any scale: the last row and column sample past the display edge.
    Frame f(45, 31, s);
    f.run("receiver_gbuffer");
    const auto& rb = f.ctx->get<render::GBuffer>(render::kReceiverGBuffer);
    EXPECT_EQ(rb.scale, s);
    EXPECT_EQ(rb.width, (45 + s - 1) / s);
    EXPECT_EQ(rb.height, (31 + s - 1) / s);
    EXPECT_EQ(f.result.passes.back().counters.at("rays"), static_cast<double>(rb.width) * rb.height);
    const render::PinholeCamera cam = render::make_pinhole_camera(f.sc, 45, 31, "test");
    int plane_pixels = 0;
    for (int y = 0; y < rb.height; ++y)
      for (int x = 0; x < rb.width; ++x) {
        const glm::vec3 d = cam.direction((x + 0.5f) * s, (y + 0.5f) * s);
        const std::size_t i = static_cast<std::size_t>(y) * rb.width + x;
        const auto t = softgi::testing::hit_plane(cam.position, d);
        // Pixels whose ray passes the sphere at a safe distance see the plane (or nothing).
        if (softgi::testing::ray_center_distance(cam.position, d) < 1.05f * softgi::testing::PlaneSphere::kRadius) continue;
        if (!t) {
          EXPECT_FALSE(rb.hit(i)) << "scale " << s << " pixel " << x << "," << y;
          continue;
        }
        ASSERT_TRUE(rb.hit(i)) << "scale " << s << " pixel " << x << "," << y;
        const glm::vec3 p = cam.position + *t * d;
        EXPECT_LE(glm::length(rb.position[i] - p), kPositionTol);
        EXPECT_NEAR(rb.depth[i], cam.depth(p), kDepthTol);
        ++plane_pixels;
      }
    EXPECT_GT(plane_pixels, rb.width * rb.height / 4) << "scale " << s;
  }
}

// A scale larger than the frame is halved until a receiver pixel fits (a 1x1 frame at the default
// scale 2 renders at scale 1), and the frame says so.
TEST(ReceiverGBuffer, ScaleLargerThanTheFrameIsReducedWithAWarning) {
  for (auto [w, h, s, want] : {std::array<int, 4>{1, 1, 2, 1}, {45, 31, 46, 23}, {3, 2, 8, 2}, {45, 31, 8, 8}}) {
    Frame f(w, h, 1);
    f.params = render::ParamSet({render::ParamDesc::integer("receiver_scale", 1, -5, 100, "test")});
    f.params.set("receiver_scale", std::to_string(s));
    f.run("receiver_gbuffer");
    EXPECT_EQ(f.ctx->get<render::GBuffer>(render::kReceiverGBuffer).scale, want) << w << "x" << h << " at " << s;
    EXPECT_EQ(f.result.warnings.size(), want == s ? 0u : 1u) << w << "x" << h << " at " << s;
    if (want != s && !f.result.warnings.empty()) {
      EXPECT_NE(f.result.warnings[0].find("receiver_scale " + std::to_string(s)), std::string::npos) << f.result.warnings[0];
    }
  }
}

TEST(ReceiverGBuffer, BadScalesAreNamed) {
  for (int s : {0, -3}) {
    Frame f(45, 31, 1);
    f.params = render::ParamSet({render::ParamDesc::integer("receiver_scale", 1, -5, 100, "test")});
    f.params.set("receiver_scale", std::to_string(s));
    try {
      f.run("receiver_gbuffer");
      ADD_FAILURE() << "scale " << s << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("receiver_scale"), std::string::npos) << e.what();
    }
  }
  Frame g(10, 10, 1);
  g.params = render::ParamSet();
  try {
    g.run("receiver_gbuffer");
    ADD_FAILURE() << "missing parameter accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("receiver_scale"), std::string::npos) << e.what();
  }
}
