// image_splat (paper 000) on the Vulkan backend, second set of GPU passes: accumulate_indirect
// (section 5; the point-sampled eq. 13, averaged_poly and averaged eq. 15, and exact eqs. 16-17
// operators) against the CPU pass. As in test_image_splat_parity.cpp, the CPU graph runs up to the
// pass, the pass runs on both backends from the same inputs and the outputs are compared; every
// built-in scene, shadow orders 3, 4 and 6, indirect orders 3 and 4 where the operator allows (and 6
// for exact). A direct test covers every replacement rule on random receiver-proxy configurations
// (receivers inside, straddling and behind proxies).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "../../techniques/image_splat/image_splat_internal.hpp"
#include "../../techniques/image_splat/image_splat_vulkan_shading.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace is = softgi::techniques::image_splat;

namespace {

// kIndirectRelTol, kOmegaRelTol: vulkan_test_util.hpp (the indirect splats are held to them too).
using softgi::testing::kIndirectRelTol;
using softgi::testing::kOmegaRelTol;
// exact (paper 000 eqs. 16-17): kIndirectRelTol's error sources, plus per pair the rotation
// R = Q Rz(-beta) Q^T Rz(-phi) of L~ (two band-block products of up to 11 terms and the angle
// multiples cos(m a), sin(m a) by recurrence: a few ulps each), H at N' = R N by the recurrence
// basis, and the M blocks interpolated entry by entry (the CPU's formula, summed over up to 6 terms),
// all unfused on lavapipe. They stay at the other operators' level (random receivers with rule off,
// no tangent spheres: <= 4.5e-6 exact, <= 4.7e-6 averaged): the asin conditioning dominates here too,
// so the same bound (observed <= 2.1e-4, crowd at indirect order 6; random receivers <= 3.4e-5).
constexpr double kExactRelTol = kIndirectRelTol;
// Pairs inside the sphere of influence (dist < eta r): the backends may disagree only for pairs
// whose distance lies within a float rounding of eta r. Those read exactly 0 from the smoothly clamped
// table, so they do not change the sums; the count may differ by a few.
constexpr double kPairCountRelTol = 1e-3;
// Display size of the parity frames: small, the suite also runs under ASan. receiver_scale 2: a
// 20 x 15 receiver buffer, tile_size 8: six tiles (six proxy lists).
constexpr int kWidth = 40, kHeight = 30;

// Row-wise relative difference (softgi::testing::compare_rows, floored at its kFloorFraction).
double compare_rows(const std::vector<float>& cpu, const std::vector<float>& gpu, std::size_t width, std::size_t* worst_index = nullptr) {
  const softgi::testing::Compared c = softgi::testing::compare_rows(cpu, gpu, width);
  if (worst_index) *worst_index = c.worst_index;
  return c.worst;
}

class ImageSplatParity2 : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    backends::register_cpu_backend();  // the Embree G-buffer passes
    ctx_ = softgi::testing::validated_context();
    log_ = ctx_->validation_log();
    tech_ = is::create();
  }
  static void TearDownTestSuite() {
    tech_.reset();
    ctx_.reset();
    EXPECT_EQ(log_->problems(), 0u) << log_->summary();
  }

  struct Run {
    std::size_t compared = 0;
    double worst_rgb = 0.0, worst_omega = 0.0;
  };

  // The CPU graph up to and including accumulate_indirect, then accumulate_indirect on Vulkan from
  // the same inputs.
  static Run run(const std::string& scene_name, const scene::Scene& sc, const render::ParamSet& params, const std::string& label,
                 double rgb_tol = kIndirectRelTol) {
    render::RenderRequest req;
    req.width = kWidth;
    req.height = kHeight;
    render::SteppedFrame frame(*tech_, sc, params, req, ctx_.get());
    render::FrameContext& ctx = frame.context();
    render::FrameResult& result = frame.result();
    Run out;
    for (const render::PassDesc* pp : frame.passes()) {
      const render::PassDesc& pass = *pp;
      if (pass.impl.empty()) {
        frame.run(pass, backends::cpu::kBackendName);
        continue;
      }
      EXPECT_TRUE(pass.impl.count(render::kHostImpl)) << "pass '" << pass.name << "' lacks a host implementation";
      if (!pass.impl.count(render::kHostImpl)) return out;
      frame.run(pass, render::kHostImpl);
      if (pass.name != "accumulate_indirect") continue;
      const double cpu_inside = result.passes.back().counters.at("pairs_inside_influence");
      auto cpu_res = ctx.get<std::shared_ptr<const is::IndirectSums>>(pass.writes.at(0));
      result.passes.push_back(render::PassRecord{pass.name + "@vulkan"});
      softgi::testing::impl_on(pass, backends::vulkan::kBackendName)(ctx);
      auto gpu_res = ctx.get<std::shared_ptr<const is::IndirectSums>>(pass.writes.at(0));
      EXPECT_NE(cpu_res, gpu_res);
      EXPECT_GT(cpu_res->omega.size(), 0u) << "the parity frame has no receivers";
      auto& counters = result.passes.back().counters;
      if (counters.count("kernel_gpu_seconds") == 0) {
        ADD_FAILURE() << label << ": accumulate_indirect ran the CPU pass under vulkan (every operator has a GPU path)";
        break;
      }
      EXPECT_EQ(cpu_res->pairs, gpu_res->pairs);
      EXPECT_LE(std::abs(counters.at("pairs_inside_influence") - cpu_inside), kPairCountRelTol * cpu_inside + 2.0)
          << label << ": pairs inside the sphere of influence";
      std::size_t wi = 0;
      out.worst_rgb = compare_rows(cpu_res->rgb, gpu_res->rgb, 3, &wi);
      EXPECT_LE(out.worst_rgb, rgb_tol) << scene_name << " (" << label << "): receiver " << wi << " differs by " << out.worst_rgb
                                                << " of its size";
      out.worst_omega = compare_rows(cpu_res->omega, gpu_res->omega, 1, &wi);
      EXPECT_LE(out.worst_omega, kOmegaRelTol) << scene_name << " (" << label << "): omega of receiver " << wi;
      std::printf("[parity2] %-9s %-28s %4zu receivers, %8.0f pairs (%6.0f inside), worst rgb %.3g, omega %.3g (GPU kernel %.3f ms)\n",
                  scene_name.c_str(), label.c_str(), cpu_res->omega.size(), cpu_res->pairs, cpu_inside, out.worst_rgb, out.worst_omega,
                  counters.at("kernel_gpu_seconds") * 1e3);
      ++out.compared;
      break;  // later passes are not ported here
    }
    return out;
  }

  static render::ParamSet params_for(int order, const std::string& op, int indirect_order) {
    render::ParamSet p = render::default_params(*tech_);
    p.set("order", std::to_string(order));
    p.set("indirect_operator", op);
    p.set("indirect_order", std::to_string(indirect_order));
    p.set("tile_size", "8");
    return p;
  }

  static std::shared_ptr<backends::vulkan::Context> ctx_;
  static std::shared_ptr<backends::vulkan::ValidationLog> log_;
  static std::unique_ptr<render::Technique> tech_;
};
std::shared_ptr<backends::vulkan::Context> ImageSplatParity2::ctx_;
std::shared_ptr<backends::vulkan::ValidationLog> ImageSplatParity2::log_;
std::unique_ptr<render::Technique> ImageSplatParity2::tech_;

TEST_P(ImageSplatParity2, AccumulateIndirectMatchesTheCpuPass) {
  const std::string name = GetParam();
  const scene::Scene sc = scene::make_builtin(name);
  std::size_t compared = 0;
  for (int order : {3, 4, 6}) {
    SCOPED_TRACE(name + " at order " + std::to_string(order));
    compared += run(name, sc, params_for(order, "averaged_poly", 3), "order " + std::to_string(order) + " averaged_poly 3").compared;
  }
  for (const char* op : {"point", "averaged"})
    for (int io : {3, 4}) {
      const std::string label = std::string("order 4 ") + op + " " + std::to_string(io);
      SCOPED_TRACE(name + " " + label);
      compared += run(name, sc, params_for(4, op, io), label).compared;
    }
  for (int io : {3, 4, 6}) {
    const std::string label = "order 4 exact " + std::to_string(io);
    SCOPED_TRACE(name + " " + label);
    compared += run(name, sc, params_for(4, "exact", io), label, kExactRelTol).compared;
  }
  EXPECT_EQ(compared, 10u) << "averaged_poly at orders 3, 4, 6; point and averaged at indirect orders 3 and 4; exact at 3, 4, 6";
}

INSTANTIATE_TEST_SUITE_P(BuiltinScenes, ImageSplatParity2, ::testing::Values("spheres", "cornell", "character", "crowd", "bunny"));

// The exact operator's own floats are exposed for the upload, and only by the exact evaluator.
TEST_F(ImageSplatParity2, ExactTablesAreExposedForTheUpload) {
  std::vector<glm::vec3> env(16, glm::vec3(0.1f));
  env[0] = glm::vec3(1.0f);
  for (auto op : {is::IndirectOperator::PointSampled, is::IndirectOperator::AveragedExact, is::IndirectOperator::Exact}) {
    SCOPED_TRACE(is::to_string(op));
    is::IndirectSetup setup;
    setup.order = 4;
    setup.op = op;
    setup.table_resolution = 32;
    const is::IndirectEvaluator ev(setup, is::irradiance_sh(env, 4));
    const is::IndirectEvaluator::TableView tv = ev.tables();
    if (op != is::IndirectOperator::Exact) {
      EXPECT_TRUE(tv.mtab.empty() && tv.moff.empty() && tv.qrot.empty() && tv.qoff.empty() && tv.hc.empty());
      EXPECT_EQ(tv.mrow, 0);
      continue;
    }
    // m-blocks of sizes (4 - |m|)^2, m = -3..3; Q band blocks (2l + 1)^2, l = 0..3.
    EXPECT_EQ(tv.mrow, 1 + 4 + 9 + 16 + 9 + 4 + 1);
    EXPECT_EQ(tv.mtab.size(), static_cast<std::size_t>(32 * tv.mrow));
    ASSERT_EQ(tv.moff.size(), 7u);
    EXPECT_EQ(tv.moff[3], 14);
    ASSERT_EQ(tv.qoff.size(), 4u);
    EXPECT_EQ(tv.qoff[3], 1 + 9 + 25);
    EXPECT_EQ(tv.qrot.size(), static_cast<std::size_t>(1 + 9 + 25 + 49));
    EXPECT_EQ(tv.hc.size(), 4u);
    EXPECT_FLOAT_EQ(tv.qrot[0], 1.0f);  // band 0 is invariant
    // Row 0 is the empty cap: M = 0.
    for (int i = 0; i < tv.mrow; ++i) EXPECT_EQ(tv.mtab[static_cast<std::size_t>(i)], 0.0f) << i;
  }
}

namespace {

// One tile of `count` receivers at uniform positions in [-half, half]^3 with uniform random normals.
is::ReceiverBuffer random_receiver_tile(std::mt19937& rng, int count, float half) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  is::ReceiverBuffer r;
  r.soa.resize(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    glm::vec3 nrm(u(rng), u(rng), u(rng));
    while (glm::length(nrm) < 0.1f) nrm = glm::vec3(u(rng), u(rng), u(rng));
    r.soa.set(static_cast<std::size_t>(i), half * glm::vec3(u(rng), u(rng), u(rng)), glm::normalize(nrm));
  }
  r.tiles.push_back(is::ReceiverTile{0, static_cast<std::size_t>(count), glm::vec3(-half), glm::vec3(half)});
  return r;
}

}  // namespace

// Every replacement rule (the shared GLSL port of techniques::common::apply_replacement_rule), every operator
// and indirect orders 3 and 6, on random receivers around random proxies in one tile: receivers
// inside proxies, proxies straddling and behind the tangent plane, with and without a sphere of
// influence (smooth and hard cut).
TEST_F(ImageSplatParity2, EveryRuleAndOrderMatchesTheEvaluator) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  constexpr int kReceivers = 96, kProxies = 24;
  const is::ReceiverBuffer r = random_receiver_tile(rng, kReceivers, 1.0f);
  is::ProxyBins bins;
  bins.indirect.resize(1);
  for (int j = 0; j < kProxies; ++j)
    bins.indirect[0].push(glm::vec3(u(rng), u(rng), u(rng)), 0.05f + 0.25f * (u(rng) + 1.0f), glm::vec3(0.2f, 0.5f, 0.8f) * (0.6f + 0.4f * u(rng)));
  // An environment with every band present, so every coefficient of L~ matters.
  std::vector<glm::vec3> env(static_cast<std::size_t>(sh::num_coeffs(6)));
  for (auto& c : env) c = glm::vec3(u(rng), u(rng), u(rng));
  env[0] = glm::vec3(3.0f);

  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params = render::default_params(*tech_);
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, 4, 4, result, ctx_.get());
  result.passes.push_back(render::PassRecord{"accumulate_indirect"});
  int cases = 0;
  std::map<std::string, std::pair<double, double>> worst;  // per operator: rgb, omega
  for (auto rule : {techniques::common::ReplacementRule::Off, techniques::common::ReplacementRule::Continuous, techniques::common::ReplacementRule::Clamped, techniques::common::ReplacementRule::Printed, techniques::common::ReplacementRule::InsideOnly})
    for (auto op : {is::IndirectOperator::PointSampled, is::IndirectOperator::AveragedExact, is::IndirectOperator::AveragedPolynomial,
                    is::IndirectOperator::Exact})
      for (int n : {3, 6}) {  // 4 is in the scene test; each order is a pipeline to compile
        if (op == is::IndirectOperator::AveragedPolynomial && n != 3) continue;
        for (const auto& [eta, smooth] : {std::pair<double, bool>{0.0, true}, {4.0, true}, {4.0, false}}) {
          const std::string label = std::string(techniques::common::to_string(rule)) + " " + is::to_string(op) + " n" + std::to_string(n) + " eta " +
                                    std::to_string(eta) + (smooth ? "" : " hard");
          SCOPED_TRACE(label);
          is::IndirectSetup setup;
          setup.order = n;
          setup.op = op;
          setup.eta = eta;
          setup.smooth_clamp = smooth;
          setup.rule = rule;
          const is::IndirectEvaluator ev(setup, is::irradiance_sh(env, n));
          std::vector<float> rgb(kReceivers * 3, 0.0f), omega(kReceivers, 0.0f);
          const long long inside = ev.accumulate(r.soa, 0, kReceivers, bins.indirect[0], rgb.data(), omega.data());
          const auto gpu = is::vulkan_accumulate_indirect(ctx, r, bins, ev);
          const double wr = compare_rows(rgb, gpu->rgb, 3), wo = compare_rows(omega, gpu->omega, 1);
          EXPECT_LE(wr, op == is::IndirectOperator::Exact ? kExactRelTol : kIndirectRelTol);
          EXPECT_LE(wo, kOmegaRelTol);
          EXPECT_LE(std::abs(result.passes.back().counters.at("pairs_inside_influence") - static_cast<double>(inside)),
                    kPairCountRelTol * static_cast<double>(inside) + 2.0);
          if (wr > 1e-4 || wo > 1e-4) std::printf("[parity2] %-40s worst rgb %.3g omega %.3g\n", label.c_str(), wr, wo);
          // Rule off separately: no rule-adjusted tangent spheres, so no ill-conditioned asin.
          for (const std::string& key : {std::string(is::to_string(op)) + (rule == techniques::common::ReplacementRule::Off ? ", rule off" : ""),
                                         std::string(is::to_string(op))}) {
            auto& w = worst[key];
            w = {std::max(w.first, wr), std::max(w.second, wo)};
          }
          ++cases;
        }
      }
  for (const auto& [op, w] : worst)
    std::printf("[parity2] random receivers, %-24s worst rgb %.3g omega %.3g\n", op.c_str(), w.first, w.second);
  EXPECT_EQ(cases, 5 * (2 + 2 + 1 + 2) * 3);
}

// A tile's proxy list longer than llvmpipe's loop budget (65535 iterations per invocation, every
// loop of a proxy's body counted) was cut short silently; the host now sums long lists in chunks,
// one dispatch each, adding to the sums before. 3000 proxies around 64 receivers, with the
// polynomial averaged operator and the exact one (whose nested rotation loops make a proxy costly):
// the CPU evaluator's sums within the tolerances above, and under a tighter limit (more chunks) the
// same sums to the bit (the same float additions in the same order).
TEST_F(ImageSplatParity2, LongProxyListsAreSummedInChunksUnderTheLoopLimit) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  constexpr int kReceivers = 64, kProxies = 3000;
  const is::ReceiverBuffer r = random_receiver_tile(rng, kReceivers, 0.3f);
  is::ProxyBins bins;
  bins.indirect.resize(1);
  for (int j = 0; j < kProxies; ++j) {
    glm::vec3 d(u(rng), u(rng), u(rng));
    while (glm::length(d) < 0.1f) d = glm::vec3(u(rng), u(rng), u(rng));
    bins.indirect[0].push(1.2f * glm::normalize(d), 0.15f, glm::vec3(0.2f, 0.5f, 0.8f));
  }
  std::vector<glm::vec3> env(static_cast<std::size_t>(sh::num_coeffs(4)), glm::vec3(0.1f));
  env[0] = glm::vec3(3.0f);
  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params = render::default_params(*tech_);
  backends::vulkan::ContextOptions o;
  o.validation = 1;
  o.loop_iteration_limit = 20000;
  auto tight = std::make_shared<backends::vulkan::Context>(o);
  const auto tight_log = tight->validation_log();
  for (auto op : {is::IndirectOperator::AveragedPolynomial, is::IndirectOperator::Exact}) {
    SCOPED_TRACE(is::to_string(op));
    is::IndirectSetup setup;
    setup.order = op == is::IndirectOperator::Exact ? 4 : 3;
    setup.op = op;
    setup.rule = techniques::common::ReplacementRule::Off;
    const is::IndirectEvaluator ev(setup, is::irradiance_sh(env, setup.order));
    std::vector<float> rgb(kReceivers * 3, 0.0f), omega(kReceivers, 0.0f);
    ev.accumulate(r.soa, 0, kReceivers, bins.indirect[0], rgb.data(), omega.data());
    auto run = [&](backends::vulkan::Context* c, double& chunks) {
      render::FrameResult result;
      render::FrameContext fc(sc, posed, params, 4, 4, result, c);
      result.passes.push_back(render::PassRecord{"accumulate_indirect"});
      auto sums = is::vulkan_accumulate_indirect(fc, r, bins, ev);
      chunks = result.passes.back().counters.at("proxy_chunks");
      return sums;
    };
    double chunks = 0.0, more = 0.0;
    const auto gpu = run(ctx_.get(), chunks);
    const auto split = run(tight.get(), more);
    float peak = 0.0f;
    for (float v : rgb) peak = std::max(peak, std::abs(v));
    std::printf("[parity2] %d proxies, %s: %g chunks (%g under a limit of 20000), peak %g\n", kProxies, is::to_string(op), chunks, more, peak);
    EXPECT_GT(peak, 0.0f);
    EXPECT_LE(compare_rows(rgb, gpu->rgb, 3), op == is::IndirectOperator::Exact ? kExactRelTol : kIndirectRelTol);
    EXPECT_LE(compare_rows(omega, gpu->omega, 1), kOmegaRelTol);
    if (ctx_->device_info().loop_iteration_limit > 0) {
      EXPECT_GT(chunks, 1.0);
    }
    EXPECT_GT(more, chunks);
    EXPECT_EQ(split->rgb, gpu->rgb);
    EXPECT_EQ(split->omega, gpu->omega);
  }
  tight.reset();
  EXPECT_EQ(tight_log->problems(), 0u) << tight_log->summary();
}

// Bad proxies get the CPU evaluator's message on Vulkan too, for the exact operator as well.
TEST_F(ImageSplatParity2, AccumulateIndirectOnVulkanRejectsBadInput) {
  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  const render::ParamSet params = render::default_params(*tech_);
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, 4, 4, result, ctx_.get());
  result.passes.push_back(render::PassRecord{"accumulate_indirect"});
  is::ReceiverBuffer r;
  r.soa.resize(1);
  r.soa.set(0, glm::vec3(0.0f), glm::vec3(0, 0, 1));
  r.tiles.push_back(is::ReceiverTile{0, 1, glm::vec3(0.0f), glm::vec3(0.0f)});
  is::ProxyBins bins;
  bins.indirect.resize(1);
  bins.indirect[0].push(glm::vec3(0, 0, 2), 1.0f, glm::vec3(0.5f));
  std::vector<glm::vec3> env(9, glm::vec3(0.0f));
  env[0] = glm::vec3(1.0f);
  is::IndirectSetup setup;
  const is::IndirectEvaluator ev(setup, is::irradiance_sh(env, 3));
  is::IndirectSetup exact_setup = setup;
  exact_setup.op = is::IndirectOperator::Exact;
  const is::IndirectEvaluator exact(exact_setup, is::irradiance_sh(env, 3));
  EXPECT_TRUE(is::vulkan_indirect_supported(exact_setup.op));
  // A NaN radius (averaged_poly), an infinite centre (exact): the CPU evaluator's message, then the
  // context still works.
  struct Bad {
    const is::IndirectEvaluator* ev;
    float* field;
    float value;
    const char* what;
  };
  for (const Bad& b : {Bad{&ev, &bins.indirect[0].r[0], std::nanf(""), "a NaN proxy radius"},
                       Bad{&exact, &bins.indirect[0].cx[0], std::numeric_limits<float>::infinity(), "an infinite proxy centre (exact)"}}) {
    const float good = *b.field;
    *b.field = b.value;
    try {
      is::vulkan_accumulate_indirect(ctx, r, bins, *b.ev);
      ADD_FAILURE() << "no error for " << b.what;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("proxy 0 has a non-finite centre, radius or albedo"), std::string::npos) << e.what();
    }
    *b.field = good;
    const auto ok = is::vulkan_accumulate_indirect(ctx, r, bins, *b.ev);
    EXPECT_GT(ok->omega[0], 0.0f) << "the context is usable after " << b.what;
  }
}

}  // namespace
