// The passes' loop budgets where a device has no loop limit (every GPU; DeviceInfo::
// loop_iteration_limit 0), run on whatever device the tests have. Each pass hands its shaders a
// budget derived from the limit (loop_budget), and without a limit that budget is at its largest:
// a shader that adds it to an index or a count wraps around, which no frame under llvmpipe's limit
// shows. ContextOptions::assume_no_loop_limit runs a frame with those budgets; on frames small
// enough that every loop fits within the driver's real limit, the frame must be the one the
// driver's own limit gives, to the bit (the budgets only split work over dispatches, they change no
// arithmetic; the resume tests of each technique check that under tighter limits).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

struct Case {
  std::string technique, scene;
  std::map<std::string, std::string> params;
};

std::string describe(const Case& c) {
  std::string s = c.technique + " on " + c.scene;
  for (const auto& [k, v] : c.params) s += " " + k + "=" + v;
  return s;
}

// Every technique's default frame, and the variants whose passes take budgets of their own: the
// device binning and the exact indirect operator of image-space accumulation, the rays' marching
// variant and a glossy scene's gathering of the point-proxy voxels, the spherical lights with and
// without their hierarchy.
std::vector<Case> cases() {
  return {
      {"shexp", "spheres", {}},
      {"shexp", "character", {{"order", "6"}}},
      {"image_splat", "spheres", {}},
      {"image_splat", "character", {{"binning", "device"}, {"indirect_operator", "exact"}}},
      {"spherical_lights", "spheres", {}},
      {"spherical_lights", "character", {{"hierarchy", "false"}}},
      {"point_voxels", "spheres", {{"proxy_count", "6000"}}},
      {"point_voxels", "cornell_glossy", {{"proxy_count", "6000"}, {"march_lanes", "rays"}}},
  };
}

struct Frame {
  render::FrameResult result;
  std::size_t problems = 0;
  std::string summary;
};

Frame render_with(const Case& c, bool no_limit) {
  backends::vulkan::ContextOptions o;
  o.validation = 1;
  o.assume_no_loop_limit = no_limit;
  auto ctx = std::make_shared<backends::vulkan::Context>(o);
  const auto log = ctx->validation_log();
  std::unique_ptr<render::Technique> tech = render::create_technique(c.technique);
  render::ParamSet params = render::default_params(*tech);
  for (const auto& [k, v] : c.params) params.set(k, v);
  render::RenderRequest req;
  req.width = req.height = 40;
  Frame f;
  {
    backends::VulkanBackend vk(ctx);
    if (no_limit) {
      EXPECT_EQ(ctx->device_info().loop_iteration_limit, 0u) << "assume_no_loop_limit leaves the device without a limit";
    }
    ctx.reset();
    f.result = vk.render(*tech, scene::make_builtin(c.scene), params, req);
  }
  f.problems = log->problems();
  f.summary = log->summary();
  return f;
}

std::size_t differing(const Image& a, const Image& b) {
  if (a.rgb.size() != b.rgb.size()) return std::max(a.rgb.size(), b.rgb.size());
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) n += a.rgb[i] != b.rgb[i];
  return n;
}

}  // namespace

TEST(VulkanLoopLimit, FramesWithoutALimitAreTheFramesUnderTheDriversLimit) {
  for (const Case& c : cases()) {
    SCOPED_TRACE(describe(c));
    const Frame limited = render_with(c, false);
    const Frame unlimited = render_with(c, true);
    EXPECT_EQ(limited.problems, 0u) << limited.summary;
    EXPECT_EQ(unlimited.problems, 0u) << unlimited.summary;
    ASSERT_EQ(limited.result.backend, "vulkan");
    ASSERT_EQ(unlimited.result.backend, "vulkan");
    // Frames that the comparison would pass trivially: a flat image, or no indirect light where the
    // technique has some. 100 distinct colours in 1600 pixels: a shaded frame has hundreds.
    std::set<std::array<float, 3>> colours;
    for (const auto& v : limited.result.final_image.rgb) colours.insert({v.x, v.y, v.z});
    EXPECT_GE(colours.size(), 100u) << "distinct colours in the final image";
    float indirect = 0.0f;
    for (const auto& v : limited.result.indirect.rgb) indirect = std::max({indirect, v.x, v.y, v.z});
    if (c.technique != "shexp") {
      EXPECT_GT(indirect, 0.0f) << "the largest indirect value";
    }
    EXPECT_EQ(differing(limited.result.final_image, unlimited.result.final_image), 0u) << "final image pixels";
    EXPECT_EQ(differing(limited.result.direct, unlimited.result.direct), 0u) << "direct image pixels";
    EXPECT_EQ(differing(limited.result.indirect, unlimited.result.indirect), 0u) << "indirect image pixels";
    std::printf("[loop limit] %-62s %zu colours, indirect peak %g\n", describe(c).c_str(), colours.size(),
                static_cast<double>(indirect));
  }
}
