// image_splat's rasterised splats (splatting = raster; paper 000 section 4.1, Figure 3) against the
// binned accumulations on the same device and on the CPU, from the same frame inputs: each proxy's
// sphere of influence drawn as a hull into the receiver buffer, its receivers tested and summed by
// additive blending, must give every receiver the log occlusion vector and the indirect sums the
// tile lists give it, from the same pairs. Built-in scenes at orders 3 to 6 (6 takes two draws of eight attachments), the hard
// per-pair cut, every replacement rule, no coverage oracle (every proxy over the whole buffer), and
// an eye inside spheres of influence (the hull's far side only is drawn).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "../../techniques/image_splat/image_splat_internal.hpp"
#include "../../techniques/image_splat/image_splat_vulkan.hpp"
#include "../../techniques/image_splat/image_splat_vulkan_shading.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace is = softgi::techniques::image_splat;

namespace {

using softgi::testing::compare_rows;
using softgi::testing::Compared;
using softgi::testing::kAccumulateRelTol;
using softgi::testing::kIndirectRelTol;
using softgi::testing::kOmegaRelTol;

// Display size: receiver_scale 2 gives a 36 x 27 receiver buffer. Small: the suite also runs under ASan.
constexpr int kWidth = 72, kHeight = 54;
// Splats against the CPU: the parity tests' tolerances (vulkan_test_util.hpp).
// Splats against the binned pass on the same device: the same per-pair arithmetic
// (accum_log_pair.glsl, indirect_pair.glsl) summed in the same proxy order, once by blending and
// once in a register. The only difference the two may show is where a driver fuses the register
// sum's multiply-add (acc += fl q, acc += albedo x) into an FMA, which a blend cannot: one rounding
// per term, a few ulps of the receiver's largest partial sum over the few hundred terms of a list. Relative per receiver,
// floored as compare_rows does.
constexpr double kSplatVsBinnedRelTol = 1e-5;

struct Outcome {
  std::size_t receivers = 0, proxies = 0, eye_inside = 0;
  double vs_binned = 0.0, vs_cpu = 0.0;  // log occlusion
  double draws = 0.0;
  bool indirect = false;  // accumulate_indirect compared too
  double rgb_vs_binned = 0.0, rgb_vs_cpu = 0.0, omega_vs_binned = 0.0, omega_vs_cpu = 0.0;
};

class ImageSplatSplats : public softgi::testing::ValidatedTest {
 protected:
  static render::ParamSet params(int order) {
    auto tech = is::create();
    render::ParamSet p = render::default_params(*tech);
    p.set("order", std::to_string(order));
    p.set("splatting", "raster");
    p.set("tile_size", "8");
    return p;
  }

  // Runs the frame's graph on the CPU, and accumulate_log and accumulate_indirect three ways from
  // the same receivers, tables and bins: on the CPU, binned on Vulkan, splatted on Vulkan.
  Outcome run(const scene::Scene& sc, const render::ParamSet& p, const std::string& label) {
    auto tech = is::create();
    render::RenderRequest req;
    req.width = kWidth;
    req.height = kHeight;
    render::SteppedFrame frame(*tech, sc, p, req, ctx_.get());
    render::FrameContext& ctx = frame.context();
    const is::Settings s = is::read_settings(p);
    Outcome out;
    for (const render::PassDesc* pp : frame.passes()) {
      const render::PassDesc& pass = *pp;
      if (pass.impl.empty()) {
        frame.run(pass, backends::cpu::kBackendName);
        continue;
      }
      frame.run(pass, render::kHostImpl);
      if (pass.name == "accumulate_log") {
        const std::string res = pass.writes.at(0);
        const auto cpu = ctx.get<std::shared_ptr<const is::Field>>(res);
        const auto& t = *ctx.get<std::shared_ptr<const is::ShadowTables>>(pass.reads.at(1));
        const auto& r = *ctx.get<std::shared_ptr<const is::ReceiverBuffer>>(pass.reads.at(0));
        const auto& bins = *ctx.get<std::shared_ptr<const is::ProxyBins>>(pass.reads.at(2));
        frame.result().passes.push_back(render::PassRecord{"accumulate_log@binned"});
        is::vulkan_accumulate_log(ctx, s, t, r, bins, "test.binned");
        const auto binned = ctx.get<std::shared_ptr<const is::Field>>("test.binned");
        frame.result().passes.push_back(render::PassRecord{"accumulate_log@splats"});
        softgi::testing::impl_on(pass, backends::vulkan::kBackendName)(ctx);
        const render::PassRecord& rec = frame.result().passes.back();
        EXPECT_EQ(rec.counters.count("splat_draws"), 1u) << "the Vulkan accumulate_log of splatting=raster draws splats";
        out.draws = rec.counters.count("splat_draws") ? rec.counters.at("splat_draws") : 0.0;
        const auto splats = ctx.get<std::shared_ptr<const is::Field>>(res);
        const std::size_t width = static_cast<std::size_t>(cpu->channels);
        EXPECT_EQ(splats->channels, cpu->channels);
        out.receivers = width ? cpu->v.size() / width : 0;
        const Compared a = compare_rows(binned->v, splats->v, width);
        const Compared b = compare_rows(cpu->v, splats->v, width);
        out.vs_binned = a.worst;
        out.vs_cpu = b.worst;
        EXPECT_LE(a.worst, kSplatVsBinnedRelTol) << label << ": receiver " << a.worst_index;
        EXPECT_LE(b.worst, kAccumulateRelTol) << label << ": receiver " << b.worst_index;
        // Proxies whose sphere of influence holds the eye (drawn from inside their hull).
        techniques::common::BlockerList all;
        is::flat_proxies(sc, ctx.posed, s.order, &all, nullptr);
        out.proxies = all.size();
        const glm::vec3 eye = render::make_pinhole_camera(sc, kWidth, kHeight, "test").position;
        for (std::size_t k = 0; k < all.size(); ++k)
          out.eye_inside += glm::length(glm::vec3(all.cx[k], all.cy[k], all.cz[k]) - eye) < is::influence_radius(all.r[k], t.support_alpha_shadow);
      } else if (pass.name == "accumulate_indirect") {
        const std::string res = pass.writes.at(0);
        const auto cpu = ctx.get<std::shared_ptr<const is::IndirectSums>>(res);
        const auto& r = *ctx.get<std::shared_ptr<const is::ReceiverBuffer>>(pass.reads.at(0));
        const auto& bins = *ctx.get<std::shared_ptr<const is::ProxyBins>>(pass.reads.at(1));
        const auto& ev = *ctx.get<std::shared_ptr<const is::IndirectEvaluator>>(pass.reads.at(2));
        frame.result().passes.push_back(render::PassRecord{"accumulate_indirect@binned"});
        const auto binned = is::vulkan_accumulate_indirect(ctx, r, bins, ev);
        const double binned_inside = frame.result().passes.back().counters.at("pairs_inside_influence");
        frame.result().passes.push_back(render::PassRecord{"accumulate_indirect@splats"});
        softgi::testing::impl_on(pass, backends::vulkan::kBackendName)(ctx);
        const render::PassRecord& rec = frame.result().passes.back();
        EXPECT_EQ(rec.counters.count("splat_draws"), 1u) << "the Vulkan accumulate_indirect of splatting=raster draws splats";
        const auto splats = ctx.get<std::shared_ptr<const is::IndirectSums>>(res);
        // The same pairs inside the spheres of influence as the binned lists.
        EXPECT_EQ(rec.counters.count("pairs_inside_influence") ? rec.counters.at("pairs_inside_influence") : -1.0, binned_inside) << label;
        out.indirect = true;
        out.rgb_vs_binned = compare_rows(binned->rgb, splats->rgb, 3).worst;
        out.omega_vs_binned = compare_rows(binned->omega, splats->omega, 1).worst;
        out.rgb_vs_cpu = compare_rows(cpu->rgb, splats->rgb, 3).worst;
        out.omega_vs_cpu = compare_rows(cpu->omega, splats->omega, 1).worst;
        EXPECT_LE(out.rgb_vs_binned, kSplatVsBinnedRelTol) << label;
        EXPECT_LE(out.omega_vs_binned, kSplatVsBinnedRelTol) << label;
        EXPECT_LE(out.rgb_vs_cpu, kIndirectRelTol) << label;
        EXPECT_LE(out.omega_vs_cpu, kOmegaRelTol) << label;
        break;
      }
    }
    std::printf("[splats] %-28s %4zu receivers %4zu proxies (eye inside %zu), %g draws: log worst vs binned %.3g, vs CPU %.3g",
                label.c_str(), out.receivers, out.proxies, out.eye_inside, out.draws, out.vs_binned, out.vs_cpu);
    if (out.indirect)
      std::printf("; indirect rgb %.3g, %.3g, omega %.3g, %.3g", out.rgb_vs_binned, out.rgb_vs_cpu, out.omega_vs_binned, out.omega_vs_cpu);
    std::printf("\n");
    EXPECT_GT(out.receivers, 0u) << label << ": no receivers";
    EXPECT_EQ(out.indirect, s.indirect) << label << ": accumulate_indirect compared where indirect light is on";
    return out;
  }
};

TEST_F(ImageSplatSplats, SplatsGiveEveryReceiverTheBinnedSums) {
  backends::register_cpu_backend();
  for (const char* name : {"spheres", "cornell", "character", "crowd", "bunny"}) {
    const scene::Scene sc = scene::make_builtin(name);
    for (int order : {3, 4}) {
      const Outcome o = run(sc, params(order), std::string(name) + " order " + std::to_string(order));
      EXPECT_EQ(o.draws, 1.0);
    }
  }
  // Order 5 fills seven RGBA attachments in one draw; order 6 needs nine: two draws.
  const scene::Scene sc = scene::make_builtin("character");
  for (int order : {5, 6}) {
    const Outcome o = run(sc, params(order), "character order " + std::to_string(order));
    EXPECT_EQ(o.draws, order == 5 ? 1.0 : 2.0);
  }
}

TEST_F(ImageSplatSplats, HardCutsRulesAndNoCoverageOracle) {
  backends::register_cpu_backend();
  const scene::Scene sc = scene::make_builtin("character");
  render::ParamSet hard = params(4);
  hard.set("smooth_clamp", "false");
  run(sc, hard, "character hard cut");
  // The replacement rules: the printed one (whose adjusted sphere can outgrow the proxy) takes the
  // per-pair cut; the others rely on the clamped table reading 0 outside the sphere of influence.
  for (const char* rule : {"printed", "clamped", "inside_only"}) {
    render::ParamSet p = params(4);
    p.set("replacement_rule", rule);
    run(sc, p, std::string("character rule ") + rule);
  }
  render::ParamSet off = params(4);
  off.set("coverage", "off");  // infinite spheres of influence: every proxy over the whole buffer
  run(sc, off, "character coverage off");
}

// The eye moved next to a proxy, inside its sphere of influence and those of others: pixels whose
// receivers lie inside must still get the proxy's vector (culling the hull's near side keeps its far
// side, which every pixel ray from inside meets once).
TEST_F(ImageSplatSplats, AnEyeInsideSpheresOfInfluence) {
  backends::register_cpu_backend();
  scene::Scene sc = scene::make_builtin("spheres");
  techniques::common::BlockerList all;
  is::flat_proxies(sc, scene::evaluate(sc, 0.0), 4, &all, nullptr);
  ASSERT_GT(all.size(), 0u);
  // From the first proxy towards the camera, three radii out: outside the proxy, inside eta r.
  const glm::vec3 c(all.cx[0], all.cy[0], all.cz[0]);
  const glm::vec3 dir = glm::normalize(sc.camera.position - c);
  sc.camera.position = c + 3.0f * all.r[0] * dir;
  sc.camera.target = c - dir;  // looking through the proxy at what lies behind it
  const Outcome o = run(sc, params(4), "spheres eye inside");
  EXPECT_GE(o.eye_inside, 1u) << "the case needs the eye inside a sphere of influence";
}

}  // namespace
