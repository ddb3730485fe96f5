// image_splat (paper 000) on the Vulkan backend against the CPU backend, pass by pass: the CPU graph
// runs up to a pass, then the pass runs on both backends with the same inputs and the outputs are
// compared (and the CPU output is put back, so every pass starts from identical inputs). The GPU
// passes: accumulate_log, exponentiate (HYB, OL, PS*), upsample, shade_direct. Every built-in scene at
// SH orders 3, 4 and 6. Host passes must be mapped to one function under both names; the host-only
// mode of a GPU pass (the exact exponential) must give the CPU result bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "../../techniques/image_splat/image_splat_internal.hpp"
#include "../../techniques/image_splat/image_splat_vulkan.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/image.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace is = softgi::techniques::image_splat;

namespace {

// accumulate_log and exponentiate run SHEXP's shaders and kernels: the tolerances of SHEXP's parity
// test (kAccumulateRelTol, kExpRelTol, kFloorFraction; vulkan_test_util.hpp).
using softgi::testing::compare_rows;
using softgi::testing::Compared;
using softgi::testing::kAccumulateRelTol;
using softgi::testing::kExpRelTol;
// upsample (eq. 11 weights): float on both backends, in other orders (the GPU takes w_z as
// 1 / (1 + dz / eps) and may fuse multiply-adds). A weight is w_b w_z max(0, N_p.N_i)^32
// renormalised over <= 4 taps; the float dot product of two unit normals is off by a few ulps of 1
// (~2e-7), which the 32nd power (parameter normal_power's default) multiplies by 32: ~6e-6, plus ~20
// roundings of the products and the division. Absolute on weights in [0, 1].
constexpr double kWeightAbsTol = 2e-5;
// The miss decision compares the unnormalised sum of those weights with miss_threshold: the backends
// may disagree only where the sum lies within its float error of the threshold (relative, as above).
constexpr double kMissMeasureRelTol = 1e-4;
// The indirect field interpolated with those weights (<= 4 taps of one field): per pixel relative to
// its largest channel, floored as in compare_rows (kFloorFraction).
constexpr double kUpsampleRelTol = 1e-4;
// shade_direct: SHEXP's shade tolerance (kShadeRelTol in test_shexp_parity.cpp: one SH product and a
// dot product per channel, unfused on lavapipe) on visibility interpolated from <= 4 taps (a few
// roundings more), and without spherical lights the CPU's transfer rows (the same sum reassociated:
// common::ShadeTransfer), plus the spherical lights (cornell): both backends evaluate asin, acos, sin
// and cos by the same polynomials and the lobe axis through the basis recurrence, in their own order
// of float operations (fused or not); each moves the light's table coordinates or the lobe by a few
// float ulps, and L_H varies smoothly across table cells. Observed on lavapipe: <= 3.0e-6 (cornell,
// with its light; 4.9e-6 when the CPU called std::asin / std::acos / double sin), <= 1.2e-6 elsewhere.
constexpr double kShadeDirectRelTol = 2e-4;
// Pixels whose clamped-at-0 decision may differ: those whose most negative channel is within float
// noise of 0, a small fraction of the surface.
constexpr double kClampedPixelSlack = 1e-2;
// Display size of the parity frames: small, the suite also runs under ASan. receiver_scale 2 gives a
// 20 x 15 receiver buffer (up to 300 receivers), tile_size 8 (params_for) six tiles: six blocker lists.
constexpr int kWidth = 40, kHeight = 30;

class ImageSplatParity : public softgi::testing::ValidatedParamSuite<ImageSplatParity> {
 protected:
  static void SetUpTestSuite() {
    backends::register_cpu_backend();  // the Embree G-buffer passes
    ValidatedParamSuite::SetUpTestSuite();
    tech_ = is::create();  // one instance for all scenes: its tables are cached by order
  }
  static void TearDownTestSuite() {
    tech_.reset();
    ValidatedParamSuite::TearDownTestSuite();
  }

  struct Run {
    std::size_t compared = 0;     // GPU passes compared
    std::size_t identical = 0;    // host-only passes under "vulkan" that gave the CPU result exactly
  };

  // Runs the graph for `params` on the CPU, and every pass in `gpu_passes` on Vulkan too from the
  // same inputs. Host passes: cpu and vulkan must be the same function object's copies; checked by
  // name presence (PassDesc holds std::function, which cannot be compared).
  static Run run(const std::string& scene_name, const scene::Scene& sc, const render::ParamSet& params, const std::string& label) {
    render::RenderRequest req;
    req.width = kWidth;
    req.height = kHeight;
    render::SteppedFrame frame(*tech_, sc, params, req, ctx_.get());
    render::FrameContext& ctx = frame.context();
    render::FrameResult& result = frame.result();
    Run out;
    for (const render::PassDesc* pp : frame.passes()) {
      const render::PassDesc& pass = *pp;
      if (pass.impl.empty()) {  // shared passes (G-buffers): the CPU implementation feeds both
        frame.run(pass, backends::cpu::kBackendName);
        continue;
      }
      EXPECT_TRUE(pass.impl.count(render::kHostImpl)) << "pass '" << pass.name << "' lacks a host implementation";
      if (!pass.impl.count(render::kHostImpl)) return out;
      frame.run(pass, render::kHostImpl);
      if (pass.name == "upsample") {
        compare_upsample(ctx, params, pass, result, scene_name, label);
        ++out.compared;
        continue;
      }
      if (pass.name == "shade_direct") {
        compare_direct(ctx, pass, result, scene_name, label);
        ++out.compared;
        continue;
      }
      if (pass.name != "accumulate_log" && pass.name != "exponentiate") continue;
      const std::string res = pass.writes.at(0);
      auto cpu_res = ctx.get<std::shared_ptr<const is::Field>>(res);
      result.passes.push_back(render::PassRecord{pass.name + "@vulkan"});
      softgi::testing::impl_on(pass, backends::vulkan::kBackendName)(ctx);
      auto gpu_res = ctx.get<std::shared_ptr<const is::Field>>(res);
      EXPECT_NE(cpu_res, gpu_res);
      EXPECT_EQ(cpu_res->channels, gpu_res->channels);
      const std::size_t width = static_cast<std::size_t>(cpu_res->channels);
      EXPECT_GT(cpu_res->v.size(), 0u) << pass.name << ": the parity frame has no receivers";
      const bool host_only = result.passes.back().counters.count("kernel_gpu_seconds") == 0;
      if (host_only) {
        EXPECT_EQ(cpu_res->v, gpu_res->v) << pass.name << " (" << label << "): the host-only mode must run the CPU pass";
        out.identical += cpu_res->v == gpu_res->v;
      } else {
        if (ctx_->device_info().timestamp_valid_bits > 0) {
          EXPECT_GE(result.passes.back().counters.at("kernel_gpu_seconds"), 0.0);
        }
        const double tol = pass.name == "accumulate_log" ? kAccumulateRelTol : kExpRelTol;
        const Compared c = compare_rows(cpu_res->v, gpu_res->v, width);
        EXPECT_LE(c.worst, tol) << pass.name << " (" << label << "): receiver " << c.worst_index << " differs by " << c.worst << " of its size";
        std::printf("[parity] %-9s %-22s %-15s %zu receivers, worst relative difference %.3g (GPU kernel %.3f ms)\n", scene_name.c_str(),
                    label.c_str(), pass.name.c_str(), cpu_res->v.size() / width, c.worst,
                    result.passes.back().counters.at("kernel_gpu_seconds") * 1e3);
        ++out.compared;
      }
      ctx.put<std::shared_ptr<const is::Field>>(res, cpu_res);
    }
    return out;
  }

  static is::PlaneView plane(const render::GBuffer& gb) {
    is::PlaneView v;
    v.width = gb.width;
    v.height = gb.height;
    v.scale = gb.scale;
    v.depth = gb.depth.data();
    v.normal = gb.normal.data();
    return v;
  }

  // upsample on both backends: the taps and weights of every pixel neither marks a miss, the miss
  // decisions (equal except within kMissMeasureRelTol of the threshold), the interpolated indirect
  // field, and the host parts (surface list, coarse O_p) exactly.
  static void compare_upsample(render::FrameContext& ctx, const render::ParamSet& params, const render::PassDesc& pass,
                               render::FrameResult& result, const std::string& scene_name, const std::string& label) {
    const std::string res = pass.writes.at(0);
    auto cpu = ctx.get<std::shared_ptr<const is::Upsampled>>(res);
    result.passes.push_back(render::PassRecord{pass.name + "@vulkan"});
    softgi::testing::impl_on(pass, backends::vulkan::kBackendName)(ctx);
    auto gpu = ctx.get<std::shared_ptr<const is::Upsampled>>(res);
    ASSERT_NE(cpu, gpu);
    EXPECT_EQ(cpu->surface, gpu->surface);
    EXPECT_EQ(cpu->coarse_visibility, gpu->coarse_visibility);
    ASSERT_EQ(cpu->w.index.size(), gpu->w.index.size());
    // The GPU's own miss measure, for the pixels where the decisions differ.
    const is::Settings st = is::read_settings(params);
    std::vector<float> measure;
    softgi::techniques::common::vulkan_upsample_weights(ctx, plane(ctx.get<render::GBuffer>(render::kReceiverGBuffer)), plane(ctx.get<render::GBuffer>(render::kGBuffer)),
                                st.upsample, &measure);
    const double thr = st.upsample.miss_threshold;
    double worst_w = 0.0;
    std::size_t flips = 0, compared_pixels = 0;
    for (std::size_t p = 0; p < cpu->w.index.size(); ++p) {
      if (cpu->w.miss[p] != gpu->w.miss[p]) {
        ++flips;
        EXPECT_LE(std::abs(measure[p] - thr), kMissMeasureRelTol * thr) << "pixel " << p << ": miss decisions differ away from the threshold";
        continue;
      }
      if (cpu->w.miss[p]) continue;
      ++compared_pixels;
      // Tap maps (index -> weight), a tap missing on one side counting as weight 0.
      const auto weight_of = [](const is::UpsampleWeights& w, std::size_t px, std::int32_t idx) {
        for (int k = 0; k < 4; ++k)
          if (w.index[px][k] == idx) return static_cast<double>(w.weight[px][k]);
        return 0.0;
      };
      for (const is::UpsampleWeights* w : {&cpu->w, &gpu->w})
        for (int k = 0; k < 4 && w->index[p][k] >= 0; ++k) {
          const std::int32_t idx = w->index[p][k];
          worst_w = std::max(worst_w, std::abs(weight_of(cpu->w, p, idx) - weight_of(gpu->w, p, idx)));
        }
    }
    EXPECT_LE(worst_w, kWeightAbsTol) << "upsample (" << label << ") weights";
    double worst_i = 0.0;
    if (!cpu->indirect.empty()) {
      ASSERT_EQ(cpu->indirect.size(), gpu->indirect.size());
      std::vector<float> a, b;  // the pixels neither backend marks a miss
      for (std::size_t p = 0; p < cpu->w.miss.size(); ++p)
        if (!cpu->w.miss[p] && !gpu->w.miss[p])
          for (int c = 0; c < 3; ++c) {
            a.push_back(cpu->indirect[3 * p + c]);
            b.push_back(gpu->indirect[3 * p + c]);
          }
      worst_i = compare_rows(a, b, 3).worst;
      EXPECT_LE(worst_i, kUpsampleRelTol) << "upsample (" << label << ") indirect field";
    }
    EXPECT_GT(compared_pixels, 0u);
    // The bilinear mode (no technique's default) from the same planes: its weights depend on the
    // pixel positions alone (kWeightAbsTol covers them), its misses (no hit among the taps) on the
    // depths' hit flags, equal on both backends.
    {
      is::UpsampleOptions bl = st.upsample;
      bl.mode = is::UpsampleMode::Bilinear;
      const auto coarse = plane(ctx.get<render::GBuffer>(render::kReceiverGBuffer)), fine = plane(ctx.get<render::GBuffer>(render::kGBuffer));
      const is::UpsampleWeights c = softgi::techniques::common::upsample_weights(coarse, fine, bl);
      const is::UpsampleWeights g = softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, bl);
      ASSERT_EQ(c.index.size(), g.index.size());
      double worst_b = 0.0;
      std::size_t taps = 0;
      for (std::size_t p = 0; p < c.index.size(); ++p) {
        ASSERT_EQ(c.miss[p], g.miss[p]) << "bilinear: pixel " << p;
        for (int k = 0; k < 4; ++k) {
          ASSERT_EQ(c.index[p][k], g.index[p][k]) << "bilinear: pixel " << p << " tap " << k;
          if (c.index[p][k] < 0) continue;
          ++taps;
          worst_b = std::max(worst_b, std::abs(static_cast<double>(c.weight[p][k]) - g.weight[p][k]));
        }
      }
      EXPECT_GT(taps, 0u);
      EXPECT_LE(worst_b, kWeightAbsTol) << "upsample (" << label << ") bilinear weights";
    }
    std::printf("[parity] %-9s %-22s upsample        %zu pixels, worst weight difference %.3g, indirect %.3g, %zu of %zu misses flipped\n",
                scene_name.c_str(), label.c_str(), compared_pixels, worst_w, worst_i, flips, cpu->w.misses);
    ctx.put<std::shared_ptr<const is::Upsampled>>(res, cpu);
  }

  // shade_direct on both backends: the direct image (eq. 10's first term with the spherical lights,
  // times the albedo; background: the SH light along the ray) per pixel, and the count of clamped
  // pixels (equal up to the pixels whose sum lies within float noise of 0).
  static void compare_direct(render::FrameContext& ctx, const render::PassDesc& pass, render::FrameResult& result,
                             const std::string& scene_name, const std::string& label) {
    const std::string res = pass.writes.at(0);
    const Image cpu = ctx.get<Image>(res);
    const double cpu_clamped = result.passes.back().counters.at("pixels_clamped");
    result.passes.push_back(render::PassRecord{pass.name + "@vulkan"});
    softgi::testing::impl_on(pass, backends::vulkan::kBackendName)(ctx);
    const Image& gpu = ctx.get<Image>(res);
    ASSERT_EQ(cpu.rgb.size(), gpu.rgb.size());
    const auto flat = [](const Image& im) {
      std::vector<float> v;
      for (const auto& c : im.rgb) v.insert(v.end(), {c.x, c.y, c.z});
      return v;
    };
    const Compared c = compare_rows(flat(cpu), flat(gpu), 3);
    auto& counters = result.passes.back().counters;
    EXPECT_LE(c.worst, kShadeDirectRelTol) << "shade_direct (" << label << "): pixel " << c.worst_index << " differs by " << c.worst << " of its size";
    EXPECT_LE(std::abs(counters.at("pixels_clamped") - cpu_clamped), kClampedPixelSlack * std::max(1.0, counters.at("surface_pixels")))
        << "shade_direct (" << label << "): clamped pixels";
    if (ctx_->device_info().timestamp_valid_bits > 0) {
      EXPECT_GE(counters.at("kernel_gpu_seconds"), 0.0);
    }
    std::printf("[parity] %-9s %-22s shade_direct    %zu pixels, worst relative difference %.3g, clamped %g / %g (GPU kernel %.3f ms)\n",
                scene_name.c_str(), label.c_str(), cpu.rgb.size(), c.worst, cpu_clamped, counters.at("pixels_clamped"),
                counters.at("kernel_gpu_seconds") * 1e3);
    ctx.put<Image>(res, cpu);
  }

  static render::ParamSet params_for(int order) {
    render::ParamSet p = render::default_params(*tech_);
    p.set("order", std::to_string(order));
    p.set("tile_size", "8");  // several tiles (several blocker lists) even in a small frame
    return p;
  }

  static std::unique_ptr<render::Technique> tech_;
};
std::unique_ptr<render::Technique> ImageSplatParity::tech_;

TEST_P(ImageSplatParity, GpuPassesMatchTheCpuPasses) {
  const std::string name = GetParam();
  const scene::Scene sc = scene::make_builtin(name);
  std::size_t compared = 0;
  for (int order : {3, 4, 6}) {
    SCOPED_TRACE(name + " at order " + std::to_string(order));
    compared += run(name, sc, params_for(order), "order " + std::to_string(order) + " hyb").compared;
  }
  // OL (no squarings) at order 4, with indirect order 4 (the averaged operator allows it).
  render::ParamSet p = params_for(4);
  p.set("exp", "ol");
  p.set("indirect_operator", "averaged");
  p.set("indirect_order", "4");
  compared += run(name, sc, p, "order 4 ol").compared;
  EXPECT_EQ(compared, 16u) << "accumulate_log, exponentiate, upsample and shade_direct at orders 3, 4, 6 (HYB) and 4 (OL)";
}

INSTANTIATE_TEST_SUITE_P(BuiltinScenes, ImageSplatParity, ::testing::Values("spheres", "cornell", "character", "crowd", "bunny"));

// The per-pair cut of accumulate_log_range (a hard cut at eta r with smooth_clamp off; the printed
// rule with a sphere of influence) and the PS* exponential run on the GPU too; the exact exponential
// (eq. 28, the reference) is the only host-only mode left, and gives the CPU result bit for bit.
TEST_F(ImageSplatParity, PerPairCutsAndEveryExponentialRunOnBothBackends) {
  const scene::Scene sc = scene::make_builtin("character");
  render::ParamSet hard = params_for(4);
  hard.set("smooth_clamp", "false");
  hard.set("exp", "ps*");
  hard.set("indirect", "false");
  const Run a = run("character", sc, hard, "hard cut, ps*");
  EXPECT_EQ(a.compared, 4u) << "accumulate_log, exponentiate, upsample and shade_direct";
  EXPECT_EQ(a.identical, 0u);
  render::ParamSet printed = params_for(4);
  printed.set("replacement_rule", "printed");
  printed.set("indirect", "false");
  const Run b = run("character", sc, printed, "printed rule");
  EXPECT_EQ(b.compared, 4u) << "accumulate_log, exponentiate, upsample and shade_direct";
  render::ParamSet inside = params_for(4);
  inside.set("replacement_rule", "inside_only");
  inside.set("indirect", "false");
  const Run d = run("character", sc, inside, "inside-only rule");
  EXPECT_EQ(d.compared, 4u) << "accumulate_log, exponentiate, upsample and shade_direct";
  render::ParamSet exact = params_for(3);
  exact.set("exp", "exact");
  exact.set("indirect", "false");
  const Run c = run("character", sc, exact, "exact exp");
  EXPECT_EQ(c.identical, 1u) << "exponentiate on the host";
  EXPECT_EQ(c.compared, 3u) << "accumulate_log, upsample and shade_direct on the GPU";
}

// The fallbacks of section 4.2 around the GPU shading: "shaded" shades the coarse receivers on the
// GPU and interpolates them for the misses, "none" keeps the eq. 11 result, "robust" (the default,
// above) shades the misses from the full proxy list. Each is compared pass by pass.
TEST_F(ImageSplatParity, ShadeDirectFallbacksMatchTheCpu) {
  for (const std::string scene_name : {"character", "cornell"}) {
    const scene::Scene sc = scene::make_builtin(scene_name);
    for (const std::string fallback : {"shaded", "none"}) {
      render::ParamSet p = params_for(4);
      p.set("fallback", fallback);
      const Run r = run(scene_name, sc, p, "fallback " + fallback);
      EXPECT_EQ(r.compared, 4u) << "accumulate_log, exponentiate, upsample and shade_direct";
    }
  }
}

}  // namespace

namespace {

// Bad input to the GPU upsampling gets upsample.cpp's messages (naming the pixel or the sizes), and
// the context stays usable (validation clean: checked by the fixture at teardown).
TEST_F(ImageSplatParity, UpsampleOnVulkanRejectsBadInput) {
  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params = params_for(4);
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, 4, 4, result, ctx_.get());
  result.passes.push_back(render::PassRecord{"upsample"});
  // A 4x4 display buffer over a 2x2 receiver buffer, all facing the camera at depth 2.
  std::vector<float> fdepth(16, 2.0f), cdepth(4, 2.0f);
  std::vector<glm::vec3> fnormal(16, glm::vec3(0, 0, 1)), cnormal(4, glm::vec3(0, 0, 1));
  is::PlaneView fine{4, 4, 1, fdepth.data(), fnormal.data()}, coarse{2, 2, 2, cdepth.data(), cnormal.data()};
  const is::UpsampleOptions opt;
  const is::UpsampleWeights ok = softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, opt);
  EXPECT_EQ(ok.misses, 0u);
  const auto expect_error = [&](const std::string& needle) {
    try {
      softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, opt);
      ADD_FAILURE() << "no error; expected one mentioning '" << needle << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  fdepth[6] = std::nanf("");
  expect_error("fine depth at pixel (2, 1)");
  fdepth[6] = 2.0f;
  cnormal[3] = glm::vec3(std::numeric_limits<float>::infinity(), 0, 0);
  expect_error("coarse normal at pixel (1, 1)");
  cnormal[3] = glm::vec3(0, 0, 1);
  fine.width = 7;  // 7 display pixels do not fit 2 receiver pixels of scale 2
  expect_error("do not cover the same display area");
  fine.width = 4;
  EXPECT_EQ(softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, opt).misses, 0u) << "the context is usable after the errors";
}

// The host checks the samples in blocks on every core: with bad samples in two blocks, the error
// names the first in pixel order, as one loop over the pixels would (the later block may finish
// first).
TEST_F(ImageSplatParity, UpsampleOnVulkanNamesTheFirstBadSample) {
  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params = params_for(4);
  render::FrameResult result;
  constexpr int kW = 256, kH = 200;  // 51200 display pixels: four blocks of the host's checks
  render::FrameContext ctx(sc, posed, params, kW, kH, result, ctx_.get());
  result.passes.push_back(render::PassRecord{"upsample"});
  std::vector<float> fdepth(kW * kH, 2.0f), cdepth((kW / 2) * (kH / 2), 2.0f);
  std::vector<glm::vec3> fnormal(kW * kH, glm::vec3(0, 0, 1)), cnormal((kW / 2) * (kH / 2), glm::vec3(0, 0, 1));
  const is::PlaneView fine{kW, kH, 1, fdepth.data(), fnormal.data()}, coarse{kW / 2, kH / 2, 2, cdepth.data(), cnormal.data()};
  fdepth[190 * kW + 3] = -1.0f;                                            // block 2
  fnormal[100 * kW + 7] = glm::vec3(std::nanf(""), 0.0f, 1.0f);            // block 1: the first
  try {
    softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, is::UpsampleOptions{});
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fine normal at pixel (7, 100)"), std::string::npos) << e.what();
  }
  fnormal[100 * kW + 7] = glm::vec3(0, 0, 1);
  try {
    softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, is::UpsampleOptions{});
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fine depth at pixel (3, 190)"), std::string::npos) << e.what();
  }
}

// The GPU application of eq. 11 weights: pixels with taps get the CPU's upsample_apply values (to
// kUpsampleRelTol), pixels without a tap (background) keep whatever the output held, as upsample.cpp
// documents; both with the weights resident on the device and uploaded from the host.
TEST_F(ImageSplatParity, UpsampleApplyOnVulkanLeavesPixelsWithoutTaps) {
  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params = params_for(4);
  render::FrameResult result;
  constexpr int kW = 16, kH = 12, kC = 3;
  render::FrameContext ctx(sc, posed, params, kW, kH, result, ctx_.get());
  result.passes.push_back(render::PassRecord{"upsample"});
  // Display pixels in columns 0-3 see the background; the rest a surface at depths that vary.
  std::vector<float> fdepth(kW * kH), cdepth((kW / 2) * (kH / 2));
  std::vector<glm::vec3> fnormal(fdepth.size(), glm::vec3(0, 0, 1)), cnormal(cdepth.size(), glm::vec3(0, 0, 1));
  const float inf = std::numeric_limits<float>::infinity();
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) fdepth[static_cast<std::size_t>(y * kW + x)] = x < 4 ? inf : 2.0f + 0.05f * static_cast<float>(x + y);
  for (int y = 0; y < kH / 2; ++y)
    for (int x = 0; x < kW / 2; ++x) cdepth[static_cast<std::size_t>(y * (kW / 2) + x)] = x < 2 ? inf : 2.0f + 0.1f * static_cast<float>(2 * x + 2 * y);
  const is::PlaneView fine{kW, kH, 1, fdepth.data(), fnormal.data()}, coarse{kW / 2, kH / 2, 2, cdepth.data(), cnormal.data()};
  const is::UpsampleOptions opt;
  const is::UpsampleWeights gw = softgi::techniques::common::vulkan_upsample_weights(ctx, coarse, fine, opt);
  const is::UpsampleWeights cw = softgi::techniques::common::upsample_weights(coarse, fine, opt);
  std::vector<float> in(cdepth.size() * kC);
  for (std::size_t i = 0; i < in.size(); ++i) in[i] = 0.5f + 0.25f * static_cast<float>(i % 7);
  const float kSentinel = -123.0f;
  std::vector<float> expect(fdepth.size() * kC, kSentinel);
  softgi::techniques::common::upsample_apply(cw, in.data(), kC, expect.data());
  for (const bool resident : {true, false}) {
    is::UpsampleWeights copy;
    if (!resident) copy = gw;  // other host vectors: uploaded again
    const is::UpsampleWeights& w = resident ? gw : copy;
    std::vector<float> out(fdepth.size() * kC, kSentinel);
    softgi::techniques::common::vulkan_upsample_apply(ctx, w, in.data(), kC, out.data());
    int tapped = 0, kept = 0;
    for (std::size_t p = 0; p < fdepth.size(); ++p) {
      const bool has_tap = w.index[p][0] >= 0;
      tapped += has_tap;
      for (int c = 0; c < kC; ++c) {
        const float g = out[p * kC + c], e = expect[p * kC + c];
        if (!has_tap) {
          kept += g == kSentinel;
          EXPECT_EQ(g, kSentinel) << "pixel " << p << " has no tap";
        } else {
          EXPECT_NEAR(g, e, kUpsampleRelTol * std::max(1.0f, std::fabs(e))) << "pixel " << p << " channel " << c;
        }
      }
    }
    EXPECT_EQ(tapped, (kW - 4) * kH) << "every surface pixel has taps";
    EXPECT_EQ(kept, 4 * kH * kC);
  }
}

}  // namespace
