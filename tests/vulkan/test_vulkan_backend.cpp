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

#include "../../techniques/common/accumulation_vulkan.hpp"
#include "../../techniques/image_splat/image_splat_internal.hpp"
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
#include "softgi_shared.h"  // the exponentiate status words

using namespace softgi;
namespace sx = softgi::techniques::shexp;
namespace is = softgi::techniques::image_splat;

namespace {

// Whole frames: the per-pass tolerances of test_shexp_parity (a few 1e-4 relative at worst, per
// vertex) interpolated over pixels; the image is compared by its largest difference relative to
// its largest value.
constexpr double kFrameRelTol = 1e-3;

// Non-finite values in an image (std::max and > comparisons skip NaN, so the image comparisons
// below check this first).
std::size_t non_finite(const Image& im) {
  std::size_t n = 0;
  for (const auto& c : im.rgb) n += !(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z));
  return n;
}

}  // namespace

TEST(VulkanBackend, RendersAShexpFrameLikeTheCpuBackendWithGpuTimes) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    backends::VulkanBackend vk(ctx);
    backends::CpuBackend cpu;
    EXPECT_EQ(vk.name(), backends::vulkan::kBackendName);
    EXPECT_EQ(vk.device_record().at("name"), ctx->device_info().name);
    const scene::Scene sc = scene::make_builtin("spheres");
    auto tech = sx::create();
    const render::ParamSet params = render::default_params(*tech);
    render::RenderRequest req;
    req.width = 48;
    req.height = 36;
    const render::FrameResult a = vk.render(*tech, sc, params, req);
    const render::FrameResult b = cpu.render(*tech, sc, params, req);
    EXPECT_EQ(a.backend, backends::vulkan::kBackendName);
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
    EXPECT_EQ(non_finite(a.final_image), 0u);
    EXPECT_EQ(non_finite(b.final_image), 0u);
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

// Device-resident frames: on Vulkan, SHEXP's log vectors and visibility stay in device memory from
// accumulate_log through exponentiate to shade (no pass downloads them), inputs that did not change
// since the last frame are not uploaded again, and an intermediate asked for explicitly is read back
// after the last pass and matches the CPU backend's.
TEST(VulkanBackend, ShexpIntermediatesStayOnTheDeviceUnlessRequested) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    backends::VulkanBackend vk(ctx);
    backends::CpuBackend cpu;
    const scene::Scene sc = scene::make_builtin("spheres");  // static: nothing moves between frames
    auto tech = sx::create();
    const render::ParamSet params = render::default_params(*tech);
    render::RenderRequest req;
    req.width = 48;
    req.height = 36;
    vk.render(*tech, sc, params, req);  // uploads tables, receivers and blockers
    const render::FrameResult second = vk.render(*tech, sc, params, req);
    std::map<std::string, render::TransferBytes> by_pass;
    render::TransferBytes sum;
    for (const auto& p : second.passes) {
      by_pass[p.name] = p.transfer;
      sum += p.transfer;
    }
    ASSERT_TRUE(by_pass.count("accumulate_log") && by_pass.count("exponentiate") && by_pass.count("shade"));
    const auto& rec = second.passes;
    std::size_t receivers = 0;
    for (const auto& p : rec)
      if (p.name == "shade") receivers = static_cast<std::size_t>(p.counters.at("receivers"));
    ASSERT_GT(receivers, 0u);
    const std::size_t field_bytes = receivers * 16 * sizeof(float);  // one order-4 SH vector per receiver
    // Nothing of the accumulation crosses the bus: the receivers, cuts and tables are on the device
    // already, and the log vectors stay there.
    EXPECT_EQ(by_pass["accumulate_log"].upload, 0u);
    EXPECT_EQ(by_pass["accumulate_log"].download, 0u);
    // exponentiate reads only its status words back, never the visibility.
    EXPECT_EQ(by_pass["exponentiate"].download, gpu::kExpStatusWords * sizeof(std::uint32_t));
    // shade reads back its result (4 floats per receiver) and its clamp count, not the visibility.
    EXPECT_LT(by_pass["shade"].download, field_bytes);
    EXPECT_EQ(second.transfer.upload, sum.upload);
    EXPECT_EQ(second.transfer.download, sum.download);

    // The visibility asked for explicitly: read back once, after the last pass.
    render::RenderRequest with_vis = req;
    with_vis.outputs = {"final", "shexp.visibility"};
    const render::FrameResult v = vk.render(*tech, sc, params, with_vis);
    const render::FrameResult c = cpu.render(*tech, sc, params, with_vis);
    render::TransferBytes vsum;
    for (const auto& p : v.passes) vsum += p.transfer;
    EXPECT_EQ(v.transfer.download - vsum.download, field_bytes) << "the requested visibility is read back after the passes";
    ASSERT_TRUE(v.resources.count("shexp.visibility") && c.resources.count("shexp.visibility"));
    const auto& gv = *std::any_cast<std::shared_ptr<const sx::Field>>(v.resources.at("shexp.visibility"));
    const auto& cv = *std::any_cast<std::shared_ptr<const sx::Field>>(c.resources.at("shexp.visibility"));
    ASSERT_EQ(gv.v.size(), cv.v.size());
    ASSERT_EQ(gv.v.size(), receivers * 16);
    // The per-pass parity tolerances of accumulate_log and exponentiate (vulkan_test_util.hpp) added, per
    // receiver: both ran on the device one after the other, so their differences add.
    const softgi::testing::Compared cmp = softgi::testing::compare_rows(cv.v, gv.v, 16);
    EXPECT_LE(cmp.worst, softgi::testing::kAccumulateRelTol + softgi::testing::kExpRelTol) << "receiver " << cmp.worst_index;
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

// The same for image_splat (paper 000): the log occlusion stays on the device between
// accumulate_log and exponentiate, and a static frame uploads none of the accumulation's inputs again.
TEST(VulkanBackend, ImageSplatLogOcclusionStaysOnTheDevice) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    backends::VulkanBackend vk(ctx);
    const scene::Scene sc = scene::make_builtin("spheres");
    auto tech = render::create_technique("image_splat");
    const render::ParamSet params = render::default_params(*tech);
    render::RenderRequest req;
    req.width = 48;
    req.height = 36;
    vk.render(*tech, sc, params, req);
    const render::FrameResult second = vk.render(*tech, sc, params, req);
    std::map<std::string, render::TransferBytes> by_pass;
    for (const auto& p : second.passes) by_pass[p.name] = p.transfer;
    ASSERT_TRUE(by_pass.count("accumulate_log") && by_pass.count("exponentiate"));
    EXPECT_EQ(by_pass["accumulate_log"].upload, 0u);
    EXPECT_EQ(by_pass["accumulate_log"].download, 0u);
    EXPECT_EQ(by_pass["exponentiate"].download, gpu::kExpStatusWords * sizeof(std::uint32_t));  // the status words only
    // shade_direct binds the eq. 11 taps and weights upsample left on the device (32 bytes a display
    // pixel) and O_p in place: it uploads its surface receivers (24 bytes each), their pixels (4), the
    // coarse pixels' receivers (at most 4 bytes a display pixel) and a few KB of constants.
    double surface = 0.0;
    for (const auto& p : second.passes)
      if (p.name == "shade_direct") surface = p.counters.at("surface_pixels");
    EXPECT_GT(surface, 0.0);
    EXPECT_LE(by_pass["shade_direct"].upload, static_cast<std::size_t>(28 * surface) + 4 * 48 * 36 + 4096);
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

// O_p (paper 000 eq. 4) never leaves the device in a frame whose passes run on Vulkan: normalize_indirect
// reads back its DC coefficient only (4 bytes per receiver, for xi_p of eq. 12), upsample leaves it
// where it is, and shade_direct's eq. 11 gather reads it there through the coarse pixels'
// receivers. The frame's images are the CPU backend's (RendersAnImageSplatFrameLikeTheCpuBackend).
TEST(VulkanBackend, ImageSplatOcclusionStaysOnTheDevice) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    const scene::Scene sc = scene::make_builtin("character");
    auto tech = render::create_technique("image_splat");
    const render::ParamSet params = render::default_params(*tech);
    render::RenderRequest req;
    req.width = 64;
    req.height = 48;
    render::SteppedFrame frame(*tech, sc, params, req, ctx.get());
    for (const render::PassDesc* p : frame.passes()) frame.run(*p, backends::vulkan::kBackendName);
    EXPECT_TRUE(frame.context().is_deferred("image_splat.occlusion")) << "O_p was read back";
    bool normalized = false;
    for (const auto& p : frame.result().passes)
      if (p.name == "normalize_indirect") {
        normalized = true;
        EXPECT_EQ(p.counters.at("dc_download_bytes"), p.counters.at("receivers") * sizeof(float));
      }
    EXPECT_TRUE(normalized);
    const Image& img = frame.context().get<Image>(render::kFinal);
    float peak = 0.0f;
    for (const auto& c : img.rgb) peak = std::max({peak, c.x, c.y, c.z});
    EXPECT_GT(peak, 0.0f);
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

// The display G-buffer stays on the device after the Vulkan "gbuffer" pass (vulkan::DeviceGBuffer):
// upsample reads the display normals and depths there, and shade_direct the surface pixels'
// positions and normals. Given a copy of the G-buffer instead (other host planes: nothing resident),
// the same passes pack and upload the planes; both ways give the same weights and image, bit for
// bit, and the resident way uploads neither plane (16 bytes a display pixel for the weights, 24 a
// surface pixel for the shading).
TEST(VulkanBackend, ImageSplatReadsTheDisplayGBufferWhereItsPassLeftIt) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  // character: skinned, shadows only; cornell: a spherical light, which reads the positions too.
  for (const std::string name : {"character", "cornell"}) {
    SCOPED_TRACE(name);
    const scene::Scene sc = scene::make_builtin(name);
    auto tech = render::create_technique("image_splat");
    const render::ParamSet params = render::default_params(*tech);
    render::RenderRequest req;
    req.width = 64;
    req.height = 48;
    render::SteppedFrame frame(*tech, sc, params, req, ctx.get());
    render::FrameContext& fc = frame.context();
    const render::PassDesc *upsample = nullptr, *shade = nullptr;
    // Bytes uploaded by a pass (the context's count: SteppedFrame records no transfers).
    const auto run_counting = [&](const render::PassDesc& p) {
      const std::size_t before = ctx->transfer_bytes().upload;
      frame.run(p, backends::vulkan::kBackendName);
      return ctx->transfer_bytes().upload - before;
    };
    for (const render::PassDesc* p : frame.passes()) {
      frame.run(*p, backends::vulkan::kBackendName);
      if (p->name == "upsample") upsample = p;
      if (p->name == "shade_direct") {
        shade = p;
        break;
      }
    }
    ASSERT_TRUE(upsample && shade);
    // Again, so that neither count holds the tables uploaded once (upload_if_changed).
    const std::size_t up_a_bytes = run_counting(*upsample), shade_a_bytes = run_counting(*shade);
    const auto counters_of = [&](const std::string& pass) {
      for (auto it = frame.result().passes.rbegin(); it != frame.result().passes.rend(); ++it)
        if (it->name == pass) return *it;
      ADD_FAILURE() << "no record of " << pass;
      return render::PassRecord{};
    };
    const std::string up_res = upsample->writes.at(0), direct = shade->writes.at(0);
    const auto resident_up = fc.get<std::shared_ptr<const is::Upsampled>>(up_res);
    const Image resident_img = fc.get<Image>(direct);
    const render::PassRecord up_a = counters_of("upsample"), shade_a = counters_of("shade_direct");
    EXPECT_EQ(up_a.counters.at("fine_planes_resident"), 1.0);
    EXPECT_EQ(shade_a.counters.at("receivers_resident"), 1.0);
    const double pixels = req.width * req.height, surface = shade_a.counters.at("surface_pixels");
    ASSERT_GT(surface, 0.0);
    // The same passes from a copy of the G-buffer: put() drops the device copy.
    render::GBuffer copy = fc.get<render::GBuffer>(render::kGBuffer);
    fc.put<render::GBuffer>(render::kGBuffer, std::move(copy));
    const std::size_t up_b_bytes = run_counting(*upsample), shade_b_bytes = run_counting(*shade);
    const auto uploaded_up = fc.get<std::shared_ptr<const is::Upsampled>>(up_res);
    const render::PassRecord up_b = counters_of("upsample"), shade_b = counters_of("shade_direct");
    EXPECT_EQ(up_b.counters.at("fine_planes_resident"), 0.0);
    EXPECT_EQ(shade_b.counters.at("receivers_resident"), 0.0);
    ASSERT_NE(resident_up, uploaded_up);
    EXPECT_TRUE(resident_up->w.index == uploaded_up->w.index) << "eq. 11 taps";
    EXPECT_TRUE(resident_up->w.weight == uploaded_up->w.weight) << "eq. 11 weights";
    EXPECT_TRUE(resident_up->w.miss == uploaded_up->w.miss) << "misses";
    const Image& uploaded_img = fc.get<Image>(direct);
    ASSERT_EQ(resident_img.rgb.size(), uploaded_img.rgb.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < resident_img.rgb.size(); ++i) differ += resident_img.rgb[i] != uploaded_img.rgb[i];
    EXPECT_EQ(differ, 0u) << "direct image pixels";
    EXPECT_GE(up_b_bytes, up_a_bytes + static_cast<std::size_t>(16 * pixels));
    EXPECT_GE(shade_b_bytes, shade_a_bytes + static_cast<std::size_t>(24 * surface));
    std::printf("[resident] %-9s upsample uploads %zu bytes resident, %zu from the host planes; shade_direct %zu and %zu\n",
                name.c_str(), up_a_bytes, up_b_bytes, shade_a_bytes, shade_b_bytes);
  }
  ctx.reset();
  EXPECT_EQ(log->problems(), 0u) << log->summary();
}

// A device whose buffers the host cannot map (a discrete GPU) takes other paths: uploads and
// downloads through staging buffers, the G-buffer's resolved planes read back through host copies.
// lavapipe runs them with ContextOptions::unmapped_device_memory; every technique's frame must be
// the mapped context's, bit for bit, except point_voxels': some of its shaders sum with atomics, in
// an order that varies from run to run on one context too (observed: up to 1.2e-7 between two
// renders, in 14-45 of 1200 pixels), so its frames are held to kAtomicOrderTol of the peak.
constexpr double kAtomicOrderTol = 1e-5;
TEST(VulkanBackend, UnmappedDeviceMemoryGivesTheSameFrames) {
  backends::vulkan::ContextOptions o;
  o.validation = 1;
  o.unmapped_device_memory = 0;  // mapped where the device allows, whatever SOFTGI_VULKAN_UNMAPPED_DEVICE_MEMORY says
  auto mapped = std::make_shared<backends::vulkan::Context>(o);
  o.unmapped_device_memory = 1;
  auto unmapped = std::make_shared<backends::vulkan::Context>(o);
  ASSERT_FALSE(unmapped->device_buffers_mapped());
  if (!mapped->device_buffers_mapped())
    std::printf("[unmapped] %s: its device memory is not the host's; both contexts take the unmapped paths\n",
                mapped->device_info().name.c_str());
  auto log_a = mapped->validation_log(), log_b = unmapped->validation_log();
  {
    backends::VulkanBackend a(mapped), b(unmapped);
    const scene::Scene sc = scene::make_builtin("cornell");  // a spherical light: every pass of each graph
    render::RenderRequest req;
    req.width = 40;
    req.height = 30;
    for (const std::string name : {"shexp", "image_splat", "spherical_lights", "point_voxels"}) {
      SCOPED_TRACE(name);
      auto tech = render::create_technique(name);
      const render::ParamSet params = render::default_params(*tech);
      const render::FrameResult fa = a.render(*tech, sc, params, req);
      const render::FrameResult fb = b.render(*tech, sc, params, req);
      ASSERT_EQ(fa.final_image.rgb.size(), fb.final_image.rgb.size());
      std::size_t differ = 0;
      double peak = 0.0, worst = 0.0;
      for (std::size_t i = 0; i < fa.final_image.rgb.size(); ++i) {
        const glm::vec3 d = glm::abs(fa.final_image.rgb[i] - fb.final_image.rgb[i]);
        differ += fa.final_image.rgb[i] != fb.final_image.rgb[i];
        worst = std::max({worst, static_cast<double>(d.x), static_cast<double>(d.y), static_cast<double>(d.z)});
        peak = std::max({peak, static_cast<double>(fa.final_image.rgb[i].x), static_cast<double>(fa.final_image.rgb[i].y),
                         static_cast<double>(fa.final_image.rgb[i].z)});
      }
      ASSERT_GT(peak, 0.0);
      if (name == "point_voxels")
        EXPECT_LE(worst, kAtomicOrderTol * peak) << differ << " pixels differ";
      else
        EXPECT_EQ(differ, 0u) << "pixels";
      EXPECT_EQ(non_finite(fb.final_image), 0u);
      EXPECT_GT(fb.transfer.upload, 0u);
    }
  }
  mapped.reset();
  unmapped.reset();
  EXPECT_EQ(log_a->problems(), 0u) << log_a->summary();
  EXPECT_EQ(log_b->problems(), 0u) << log_b->summary();
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
    const std::set<std::string> gpu_passes = {"gbuffer",  "receiver_gbuffer",    "accumulate_log",     "exponentiate",
                                              "upsample", "accumulate_indirect", "normalize_indirect", "shade_direct"};
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
      EXPECT_EQ(non_finite(a.final_image), 0u) << name;
      EXPECT_EQ(non_finite(b.final_image), 0u) << name;
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

// Every pass runs on Vulkan: its own implementation for the GPU passes (accumulate_log, the
// exponentials the shader has, shade), the host one for the rest; the shared G-buffer is the
// backend's.
TEST(VulkanBackend, EveryShexpPassHasAnImplementationOnVulkanInEveryMode) {
  auto tech = sx::create();
  const scene::Scene sc = scene::make_builtin("cornell");  // has a spherical light: every pass present
  const std::string vk = backends::vulkan::kBackendName;
  for (const char* exp : {"hyb", "ol", "ps*", "ps", "exact", "product", "projected"}) {
    render::ParamSet params = render::default_params(*tech);
    params.set("exp", exp);
    std::set<std::string> empty;
    const render::PassGraph g = tech->plan(sc, params, empty);
    const std::string e = exp;
    const std::set<std::string> gpu = {"accumulate_log", "shade"};
    for (const auto& p : g.passes()) {
      if (p.name == "gbuffer") {
        EXPECT_NE(render::find_shared_pass_impl(p.name, vk), nullptr);
        continue;
      }
      EXPECT_TRUE(p.impl.count(render::kHostImpl)) << "exp=" << exp << ": pass '" << p.name << "' has no host implementation";
      const bool device = gpu.count(p.name) || (p.name == "exponentiate" && e != "exact");
      EXPECT_EQ(p.impl.count(vk), device ? 1u : 0u) << "exp=" << exp << ": pass '" << p.name << "'";
    }
  }
}

TEST(VulkanBackend, MoreBlockersThanTheDeviceBufferHoldsIsAClearError) {
  auto ctx = softgi::testing::validated_context();
  auto log = ctx->validation_log();
  {
    const scene::Scene sc = scene::make_builtin("cornell");
    auto tech = sx::create();
    render::ParamSet params = render::default_params(*tech);
    params.set("order", "3");
    render::RenderRequest req;
    req.width = req.height = 8;
    req.outputs = {"shexp.log_visibility"};
    render::SteppedFrame frame(*tech, sc, params, req, ctx.get());
    render::FrameContext& fc = frame.context();
    for (const render::PassDesc* p : frame.passes()) {
      if (p->name == "accumulate_log") break;
      frame.run(*p, render::kHostImpl);
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
    try {
      frame.run(frame.pass("accumulate_log"), backends::vulkan::kBackendName);
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

// llvmpipe ends every loop of a shader invocation after 65535 iterations of all its loops together.
// Under a limit of 4000 (set for the test, so that it runs on every driver; loop_budget leaves half
// of a limit that small) an exponential that needs more (order 6, PS-30: the products are written
// out, but each of the 31 series steps still copies and sums 36 coefficients in loops, 2428
// iterations by exponentiate.comp's count) is an error that names the limit, never a silently
// truncated series; under llvmpipe's own limit the same frame renders.
// accumulate_log's loops over a receiver's blockers count against a driver's loop-iteration limit
// (llvmpipe: 65535 per invocation, every loop of the blocker's body included); one list of 8000
// blockers was cut short there, silently, past about 2800 blockers at order 3 (two thirds of the sum
// missing) while the basis steps were loops. The host sums long lists in chunks, one dispatch each.
// The list here, 70000 blockers, is longer than that limit allows one invocation whatever the
// blocker's body costs (at least one iteration), so one dispatch would lose its tail: the chunks
// give the CPU's log visibility at orders 3 and 6, and under a tighter limit (20000: more chunks)
// the sums are the same to the bit (the same float additions in the same order). Only the receivers
// of cluster 0 read the long list (the others an empty one), which keeps the test short. The
// blockers lie on a shell around the scene, each a small cap, so that every one adds to the sum
// of some receivers. Tolerance: the parity tests' accumulate bound, on the largest value.
TEST(VulkanBackend, LongBlockerListsAreSummedInChunksUnderTheLoopLimit) {
  const scene::Scene sc = scene::make_builtin("cornell");  // its 6092 vertices keep the test short
  auto tech = sx::create();
  const std::size_t n = 70000;
  auto run = [&](backends::vulkan::Context* ctx, const std::string& backend, int order, double* chunks) {
    render::ParamSet params = render::default_params(*tech);
    params.set("order", std::to_string(order));
    render::RenderRequest req;
    req.width = req.height = 8;
    req.outputs = {"shexp.log_visibility"};
    render::SteppedFrame frame(*tech, sc, params, req, ctx);
    render::FrameContext& fc = frame.context();
    for (const render::PassDesc* p : frame.passes()) {
      if (p->name == "accumulate_log") break;
      frame.run(*p, render::kHostImpl);
    }
    auto cuts = std::make_shared<sx::Cuts>();
    sx::BlockerList big;
    big.order = order;
    for (std::size_t j = 0; j < n; ++j) {
      // Fibonacci sphere, its points taken in a stride (7919 is prime to n) so that any tail of the
      // list is spread over the whole shell, some of it above every receiver's horizon.
      const std::size_t i = (j * 7919) % n;
      const double z = 1.0 - (2.0 * i + 1.0) / n, ph = 2.399963229728653 * i;
      const double rr = std::sqrt(1.0 - z * z);
      big.cx.push_back(static_cast<float>(6.0 * rr * std::cos(ph)));
      big.cy.push_back(static_cast<float>(6.0 * z + 0.5));
      big.cz.push_back(static_cast<float>(6.0 * rr * std::sin(ph)));
      big.r.push_back(0.02f);
    }
    big.w.assign(n * order, 1.0f);
    cuts->lists.push_back(std::move(big));
    sx::BlockerList none;
    none.order = order;
    cuts->lists.push_back(std::move(none));
    const auto& rec = *fc.get<std::shared_ptr<const sx::Receivers>>("shexp.receivers");
    cuts->list_of_cluster.assign(rec.clusters.size(), 1);
    cuts->list_of_cluster.at(0) = 0;
    fc.put<std::shared_ptr<const sx::Cuts>>("shexp.cuts", cuts);
    frame.run(frame.pass("accumulate_log"), backend);
    if (chunks) *chunks = fc.record().counters.at("blocker_chunks");
    return fc.get<std::shared_ptr<const sx::Field>>("shexp.log_visibility")->v;
  };
  backends::register_cpu_backend();
  for (int order : {3, 6}) {
    const std::vector<float> cpu = run(nullptr, render::kHostImpl, order, nullptr);
    auto ctx = softgi::testing::validated_context();
    const auto log = ctx->validation_log();
    double chunks = 0.0;
    const std::vector<float> gpu = run(ctx.get(), backends::vulkan::kBackendName, order, &chunks);
    ASSERT_EQ(cpu.size(), gpu.size());
    double worst = 0.0, peak = 0.0;
    for (std::size_t i = 0; i < cpu.size(); ++i) {
      peak = std::max(peak, static_cast<double>(std::abs(cpu[i])));
      worst = std::max(worst, static_cast<double>(std::abs(cpu[i] - gpu[i])));
    }
    std::printf("order %d: %g chunks, worst %g of peak %g\n", order, chunks, worst, peak);
    EXPECT_GT(peak, 0.05);
    EXPECT_LE(worst, softgi::testing::kAccumulateRelTol * peak) << "order " << order;
    if (ctx->device_info().loop_iteration_limit > 0) {
      EXPECT_GT(chunks, 1.0);
    }
    if (order == 3) {
      backends::vulkan::ContextOptions o;
      o.validation = 1;
      o.loop_iteration_limit = 20000;
      auto tight = std::make_shared<backends::vulkan::Context>(o);
      double more = 0.0;
      const std::vector<float> split = run(tight.get(), backends::vulkan::kBackendName, order, &more);
      EXPECT_GT(more, chunks);
      EXPECT_EQ(split, gpu);
    }
    ctx.reset();
    EXPECT_EQ(log->problems(), 0u) << log->summary();
  }
}

TEST(VulkanBackend, ExponentialBeyondTheLoopLimitIsAnError) {
  const scene::Scene sc = scene::make_builtin("spheres");
  auto tech = sx::create();
  render::ParamSet params = render::default_params(*tech);
  params.set("order", "6");
  params.set("exp", "ps");
  params.set("ps_degree", "30");
  render::RenderRequest req;
  req.width = 16;
  req.height = 12;
  backends::vulkan::ContextOptions o;
  o.validation = 1;
  o.loop_iteration_limit = 4000;
  {
    backends::VulkanBackend vk(std::make_shared<backends::vulkan::Context>(o));
    std::string what;
    try {
      vk.render(*tech, sc, params, req);
    } catch (const std::exception& e) {
      what = e.what();
    }
    EXPECT_NE(what.find("exponentiate: receiver"), std::string::npos) << what;
    EXPECT_NE(what.find("loop iterations"), std::string::npos) << what;
  }
  o.loop_iteration_limit = 65535;
  backends::VulkanBackend vk(std::make_shared<backends::vulkan::Context>(o));
  EXPECT_NO_THROW(vk.render(*tech, sc, params, req));
}

// content_hash decides whether a device buffer is uploaded again: a byte that changed and hashes the
// same leaves a stale buffer. Every single-bit change of every byte, in ranges that end inside and
// past the 32-byte blocks of its four streams and in the 8-byte words and bytes after them, must
// change the hash; where the bytes lie in memory must not.
TEST(ContentHash, EveryChangedBitChangesTheHash) {
  using softgi::techniques::common::gpu_passes::content_hash;
  std::vector<unsigned char> buf(8 + 100);
  for (std::size_t k = 0; k < buf.size(); ++k) buf[k] = static_cast<unsigned char>(k * 37 + 11);
  int compared = 0;
  for (std::size_t size = 0; size <= 100; ++size) {
    unsigned char* a = buf.data() + 8;
    const std::uint64_t h = content_hash(a, size);
    // The same bytes at another address (unaligned), and another seed.
    std::vector<unsigned char> moved(size + 3);
    std::copy(a, a + size, moved.begin() + 3);
    EXPECT_EQ(content_hash(moved.data() + 3, size), h) << size << " bytes";
    EXPECT_NE(content_hash(a, size, 12345u), h) << size << " bytes";
    for (std::size_t i = 0; i < size; ++i)
      for (int bit = 0; bit < 8; ++bit) {
        a[i] ^= static_cast<unsigned char>(1u << bit);
        EXPECT_NE(content_hash(a, size), h) << size << " bytes, byte " << i << " bit " << bit;
        a[i] ^= static_cast<unsigned char>(1u << bit);
        ++compared;
      }
    // A longer range with the same prefix.
    if (size < 100) {
      EXPECT_NE(content_hash(a, size + 1), h) << size << " bytes";
    }
  }
  EXPECT_EQ(compared, 8 * 100 * 101 / 2);
}
