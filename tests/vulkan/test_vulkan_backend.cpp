// The Vulkan backend as the CLI uses it: whole SHEXP and image_splat frames (GPU time per GPU pass,
// none for host passes, the same image as the CPU backend), every SHEXP pass implemented on both backends, and a
// scene too large for the device's buffers rejected with a message naming what is too large.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>

#include "../../techniques/shexp/shexp_passes.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "softgi/techniques/shexp.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace sx = softgi::techniques::shexp;

namespace {

// Whole frames: the per-pass tolerances of test_shexp_parity (a few 1e-4 relative at worst, per
// vertex) interpolated over pixels; the image is compared by its largest difference relative to
// its largest value.
constexpr double kFrameRelTol = 1e-3;

}  // namespace

TEST(VulkanBackend, RendersAShexpFrameLikeTheCpuBackendWithGpuTimes) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    backends::VulkanBackend vk(ctx);
    backends::CpuBackend cpu;
    EXPECT_EQ(vk.name(), "vulkan");
    EXPECT_EQ(vk.device_record().at("name"), ctx->device_info().name);
    const scene::Scene sc = scene::make_builtin("spheres");
    auto tech = sx::create();
    const render::ParamSet params = render::default_params(*tech);
    render::RenderRequest req;
    req.width = 48;
    req.height = 36;
    const render::FrameResult a = vk.render(*tech, sc, params, req);
    const render::FrameResult b = cpu.render(*tech, sc, params, req);
    EXPECT_EQ(a.backend, "vulkan");
    ASSERT_EQ(a.passes.size(), b.passes.size());
    const std::set<std::string> gpu_passes = {"gbuffer", "accumulate_log", "exponentiate", "shade"};
    for (std::size_t i = 0; i < a.passes.size(); ++i) {
      EXPECT_EQ(a.passes[i].name, b.passes[i].name);
      EXPECT_LT(b.passes[i].gpu_seconds, 0.0) << b.passes[i].name << ": the CPU backend has no GPU time";
      if (gpu_passes.count(a.passes[i].name)) {
        EXPECT_GE(a.passes[i].counters.count("gpu_submissions"), 1u) << a.passes[i].name;
        if (ctx->device_info().timestamp_valid_bits > 0) {
          EXPECT_GE(a.passes[i].gpu_seconds, 0.0) << a.passes[i].name;
        }
      } else {
        EXPECT_LT(a.passes[i].gpu_seconds, 0.0) << a.passes[i].name << " is host work";
      }
    }
    ASSERT_EQ(a.final_image.rgb.size(), b.final_image.rgb.size());
    double peak = 0.0, diff = 0.0;
    for (std::size_t i = 0; i < a.final_image.rgb.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        peak = std::max(peak, static_cast<double>(std::abs(b.final_image.rgb[i][c])));
        diff = std::max(diff, static_cast<double>(std::abs(a.final_image.rgb[i][c] - b.final_image.rgb[i][c])));
      }
    ASSERT_GT(peak, 0.0);
    EXPECT_LE(diff, kFrameRelTol * peak);
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

// A whole image_splat frame (paper 000) on both backends, on `cornell` (a spherical light: every
// pass of the graph runs, the light through shade_direct's GPU shading) and `character` (skinned,
// robust misses). The backends' G-buffers differ at silhouettes (rasterised against ray traced:
// object ids differ at up to 2 % of the pixels, tests/vulkan/test_vulkan_gbuffer.cpp), and a
// receiver-buffer sample that moves across a silhouette changes the eq. 11 taps of its
// neighbourhood; elsewhere the per-pass tolerances of the parity tests (<= 2e-3 relative, per
// receiver) hold. So: at most kSilhouetteFraction of the pixels may differ by more than
// kFrameRelTol of the image's largest value. Observed at 64x48: 1.3 % on cornell, 0 on character.
constexpr double kSilhouetteFraction = 0.03;

TEST(VulkanBackend, RendersAnImageSplatFrameLikeTheCpuBackend) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    backends::VulkanBackend vk(ctx);
    backends::CpuBackend cpu;
    auto tech = techniques::image_splat::create();
    const render::ParamSet params = render::default_params(*tech);
    const std::set<std::string> gpu_passes = {"gbuffer",     "receiver_gbuffer",    "accumulate_log", "exponentiate",
                                              "upsample",    "accumulate_indirect", "shade_direct"};
    for (const std::string name : {"cornell", "character"}) {
      SCOPED_TRACE(name);
      const scene::Scene sc = scene::make_builtin(name);
      render::RenderRequest req;
      req.width = 64;
      req.height = 48;
      const render::FrameResult a = vk.render(*tech, sc, params, req);
      const render::FrameResult b = cpu.render(*tech, sc, params, req);
      ASSERT_EQ(a.passes.size(), b.passes.size());
      std::set<std::string> timed;
      for (std::size_t i = 0; i < a.passes.size(); ++i) {
        EXPECT_EQ(a.passes[i].name, b.passes[i].name);
        const bool gpu = a.passes[i].counters.count("gpu_submissions") && a.passes[i].counters.at("gpu_submissions") > 0;
        EXPECT_EQ(gpu, gpu_passes.count(a.passes[i].name) == 1) << a.passes[i].name << (gpu ? " submitted GPU work" : " ran on the host");
        if (gpu) timed.insert(a.passes[i].name);
      }
      if (name == "cornell") {
        EXPECT_EQ(timed, gpu_passes) << "every GPU pass ran";
      }
      ASSERT_EQ(a.final_image.rgb.size(), b.final_image.rgb.size());
      double peak = 0.0;
      for (const auto& c : b.final_image.rgb) peak = std::max({peak, static_cast<double>(c.x), static_cast<double>(c.y), static_cast<double>(c.z)});
      ASSERT_GT(peak, 0.0);
      std::size_t off = 0;
      for (std::size_t i = 0; i < a.final_image.rgb.size(); ++i) {
        const glm::vec3 d = glm::abs(a.final_image.rgb[i] - b.final_image.rgb[i]);
        off += std::max({d.x, d.y, d.z}) > kFrameRelTol * peak;
      }
      const double fraction = static_cast<double>(off) / static_cast<double>(a.final_image.rgb.size());
      EXPECT_LE(fraction, kSilhouetteFraction);
      std::printf("[frame] image_splat %-9s %zu of %zu pixels differ by more than %g of the peak\n", name.c_str(), off,
                  a.final_image.rgb.size(), kFrameRelTol);
    }
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

TEST(VulkanBackend, EveryShexpPassHasBothImplementationsInEveryMode) {
  auto tech = sx::create();
  const scene::Scene sc = scene::make_builtin("cornell");  // has a spherical light: every pass present
  for (const char* exp : {"hyb", "ol", "ps*", "ps", "exact", "product", "projected"}) {
    render::ParamSet params = render::default_params(*tech);
    params.set("exp", exp);
    std::set<std::string> empty;
    const render::PassGraph g = tech->plan(sc, params, empty);
    for (const auto& p : g.passes()) {
      if (p.name == "gbuffer") continue;  // shared: registered by the backend libraries
      EXPECT_TRUE(p.impl.count("cpu") && p.impl.count("vulkan")) << "exp=" << exp << ": pass '" << p.name << "'";
    }
  }
}

TEST(VulkanBackend, MoreBlockersThanTheDeviceBufferHoldsIsAClearError) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    const scene::Scene sc = scene::make_builtin("cornell");
    const scene::PosedScene posed = scene::evaluate(sc, 0.0);
    auto tech = sx::create();
    render::ParamSet params = render::default_params(*tech);
    params.set("order", "3");
    std::set<std::string> empty;
    const render::PassGraph graph = tech->plan(sc, params, empty);
    const render::CompiledGraph cg = graph.compile({"shexp.cuts"}, empty);
    render::FrameResult result;
    render::FrameContext fc(sc, posed, params, 8, 8, result);
    fc.put<std::shared_ptr<backends::vulkan::Context>>(backends::vulkan::kFrameContextResource, ctx);
    for (int idx : cg.order) {
      result.passes.push_back(render::PassRecord{graph.passes()[idx].name});
      graph.passes()[idx].impl.at("cpu")(fc);
    }
    // One cut holding more spheres (16 bytes each on the device) than maxStorageBufferRange allows.
    const std::size_t n = ctx->device_info().limits.maxStorageBufferRange / 16 + 1;
    auto cuts = std::make_shared<sx::Cuts>();
    sx::BlockerList big;
    big.order = 3;
    big.cx.assign(n, 0.0f);
    big.cy.assign(n, 0.0f);
    big.cz.assign(n, 0.0f);
    big.r.assign(n, 0.1f);
    big.w.assign(n * 3, 1.0f);
    cuts->lists.push_back(std::move(big));
    const auto& rec = *fc.get<std::shared_ptr<const sx::Receivers>>("shexp.receivers");
    cuts->list_of_cluster.assign(rec.clusters.size(), 0);
    fc.put<std::shared_ptr<const sx::Cuts>>("shexp.cuts", cuts);
    const render::PassDesc* acc = nullptr;
    for (const auto& p : graph.passes())
      if (p.name == "accumulate_log") acc = &p;
    ASSERT_NE(acc, nullptr);
    result.passes.push_back(render::PassRecord{"accumulate_log"});
    try {
      acc->impl.at("vulkan")(fc);
      ADD_FAILURE() << "no error for " << n << " blockers";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::to_string(n) + " blocker spheres"), std::string::npos) << what;
      EXPECT_NE(what.find("maxStorageBufferRange"), std::string::npos) << what;
    }
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

TEST(VulkanBackend, UnknownDeviceListsTheDevices) {
  backends::VulkanBackendOptions o;
  o.device = "no-such-gpu";
  o.validation = 1;
  try {
    backends::VulkanBackend b(o);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-gpu"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("0: "), std::string::npos) << e.what();
  }
}
