// SHEXP on the Vulkan backend against the CPU backend, pass by pass: the CPU graph runs up to a
// pass, then the pass runs on both backends with the same inputs and their outputs are compared.
// Every built-in scene, SH orders 3, 4 and 6. Host passes (tables, receivers, hierarchy, cuts,
// to_image, compose) run the same function on both backends; the test checks that they are mapped
// to it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "../../techniques/shexp/shexp_passes.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/shexp.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace sx = softgi::techniques::shexp;

namespace {

// kAccumulateRelTol, kExpRelTol, kFloorFraction and compare_rows: vulkan_test_util.hpp.
// shade: one SH product (up to ~400 triple-product terms at order 6) and a dot product of n^2 <= 36
// terms per channel whose partial sums cancel on dim receivers (the clamped cosine's negative
// lobes against shadowed visibility). Observed: <= 4e-5 (crowd, order 6).
constexpr double kShadeRelTol = 2e-4;
using softgi::testing::compare_rows;
using softgi::testing::Compared;
using softgi::testing::kAccumulateRelTol;
using softgi::testing::kExpRelTol;

std::vector<float> flatten(const std::vector<std::vector<glm::vec3>>& v) {
  std::vector<float> out;
  for (const auto& o : v)
    for (const auto& x : o) out.insert(out.end(), {x.x, x.y, x.z});
  return out;
}

class ShexpParity : public softgi::testing::ValidatedParamSuite<ShexpParity> {};

TEST_P(ShexpParity, EveryVulkanPassMatchesTheCpuPass) {
  const std::string name = GetParam();
  const scene::Scene sc = scene::make_builtin(name);
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  std::unique_ptr<render::Technique> tech = sx::create();  // one instance: receivers are clustered once
  std::size_t compared = 0;
  for (int order : {3, 4, 6}) {
    SCOPED_TRACE(name + " at order " + std::to_string(order));
    render::ParamSet params = render::default_params(*tech);
    params.set("order", std::to_string(order));
    std::set<std::string> empty;
    render::PassGraph graph = tech->plan(sc, params, empty);
    const render::CompiledGraph cg = graph.compile({"shexp.vertex_shading"}, empty);
    render::FrameResult result;
    render::FrameContext ctx(sc, posed, params, 8, 8, result);
    ctx.put<std::shared_ptr<backends::vulkan::Context>>(backends::vulkan::kFrameContextResource, ctx_);
    for (int idx : cg.order) {
      const render::PassDesc& pass = graph.passes()[idx];
      ASSERT_TRUE(pass.impl.count("cpu") && pass.impl.count("vulkan")) << "pass '" << pass.name << "' lacks a cpu or vulkan implementation";
      result.passes.push_back(render::PassRecord{pass.name});
      pass.impl.at("cpu")(ctx);
      const std::string out = pass.writes.at(0);
      if (pass.name != "accumulate_log" && pass.name != "exponentiate" && pass.name != "shade") continue;
      // The same pass on Vulkan, from the same inputs; then the CPU output goes back so that the
      // next pass starts from identical inputs again.
      std::vector<float> cpu, gpu;
      std::size_t width = 0;
      double tol = 0.0;
      if (pass.name == "shade") {
        auto cpu_res = ctx.get<std::shared_ptr<const sx::Shading>>(out);
        result.passes.push_back(render::PassRecord{pass.name + "@vulkan"});
        pass.impl.at("vulkan")(ctx);
        auto gpu_res = ctx.get<std::shared_ptr<const sx::Shading>>(out);
        ASSERT_NE(cpu_res, gpu_res);
        cpu = flatten(cpu_res->irradiance);
        gpu = flatten(gpu_res->irradiance);
        width = 3;
        tol = kShadeRelTol;
        ctx.put<std::shared_ptr<const sx::Shading>>(out, cpu_res);
      } else {
        auto cpu_res = ctx.get<std::shared_ptr<const sx::Field>>(out);
        result.passes.push_back(render::PassRecord{pass.name + "@vulkan"});
        pass.impl.at("vulkan")(ctx);
        auto gpu_res = ctx.get<std::shared_ptr<const sx::Field>>(out);
        ASSERT_NE(cpu_res, gpu_res);
        EXPECT_EQ(cpu_res->order, gpu_res->order);
        cpu = cpu_res->v;
        gpu = gpu_res->v;
        width = static_cast<std::size_t>(cpu_res->order) * cpu_res->order;
        tol = pass.name == "accumulate_log" ? kAccumulateRelTol : kExpRelTol;
        ctx.put<std::shared_ptr<const sx::Field>>(out, cpu_res);
      }
      ASSERT_FALSE(cpu.empty());
      // The GPU pass timed itself (timestamps) where the device has them.
      if (ctx_->device_info().timestamp_valid_bits > 0) {
        EXPECT_GE(result.passes.back().counters["kernel_gpu_seconds"], 0.0);
      }
      const Compared c = compare_rows(cpu, gpu, width);
      EXPECT_LE(c.worst, tol) << pass.name << ": receiver " << c.worst_index << " differs by " << c.worst << " of its size";
      std::printf("[parity] %-9s order %d %-15s %zu receivers, worst relative difference %.3g (GPU kernel %.3f ms)\n", name.c_str(),
                  order, pass.name.c_str(), cpu.size() / width, c.worst, result.passes.back().counters["kernel_gpu_seconds"] * 1e3);
      ++compared;
    }
  }
  EXPECT_EQ(compared, 9u) << "accumulate_log, exponentiate and shade at three orders";
}

INSTANTIATE_TEST_SUITE_P(BuiltinScenes, ShexpParity, ::testing::Values("spheres", "cornell", "character", "crowd", "bunny"));

}  // namespace
