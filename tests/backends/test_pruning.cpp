// Pass pruning through the backends: a tiny technique shaped like the real ones (shared G-buffer,
// per-frame proxy update, shadow, indirect from re-radiating proxies, compose). On a static scene
// without proxies the proxy update and the indirect pass must not run, on the null backend (which
// records what it would run) and on the CPU backend (whose pass bodies would notice).
#include <gtest/gtest.h>

#include <algorithm>

#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"
#include "test_scene_util.hpp"

using namespace softgi;

namespace {

struct Ran {
  int proxy_update = 0, shadow = 0, indirect = 0;
};

class TinyTechnique : public render::Technique {
 public:
  explicit TinyTechnique(Ran* ran) : ran_(ran) {}
  std::string name() const override { return "tiny"; }
  std::string description() const override { return "test technique: albedo-shaded frame"; }
  std::vector<render::ParamDesc> params() const override {
    return {render::ParamDesc::real("gain", 1.0, 0.0, 4.0, "scales the direct image")};
  }
  render::PassGraph plan(const scene::Scene& sc, const render::ParamSet&, std::set<std::string>& empty) override {
    render::PassGraph g;
    render::add_gbuffer_pass(g);
    g.add_input(render::kMovingObjects);
    g.add_input(render::kReradiatingProxies);
    Ran* ran = ran_;
    render::PassDesc update{"proxy_update", {render::kScene, render::kMovingObjects}, {}, {"proxies"}, "move proxies", {}};
    update.impl[render::kHostImpl] = [ran](render::FrameContext& ctx) {
      ++ran->proxy_update;
      ctx.put<int>("proxies", 1);
    };
    g.add(std::move(update));
    render::PassDesc shadow{"shadow", {render::kGBuffer}, {"proxies"}, {render::kDirect}, "albedo * gain", {}};
    shadow.impl[render::kHostImpl] = [ran](render::FrameContext& ctx) {
      ++ran->shadow;
      const auto& gb = ctx.get<render::GBuffer>(render::kGBuffer);
      Image img(gb.width, gb.height);
      const float gain = static_cast<float>(ctx.params.get_float("gain"));
      for (std::size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = gain * gb.albedo[i];
      ctx.record().counters["receivers"] = static_cast<double>(img.rgb.size());
      ctx.put<Image>(render::kDirect, std::move(img));
    };
    g.add(std::move(shadow));
    render::PassDesc indirect{"indirect", {render::kGBuffer, render::kReradiatingProxies}, {}, {render::kIndirect}, "", {}};
    indirect.impl[render::kHostImpl] = [ran](render::FrameContext& ctx) {
      ++ran->indirect;
      const auto& gb = ctx.get<render::GBuffer>(render::kGBuffer);
      ctx.put<Image>(render::kIndirect, Image(gb.width, gb.height, glm::vec3(0.25f)));
    };
    g.add(std::move(indirect));
    render::add_compose_pass(g);
    render::add_scene_facts(sc, empty);
    return g;
  }

 private:
  Ran* ran_;
};

std::vector<std::string> names(const render::FrameResult& r) {
  std::vector<std::string> out;
  for (const auto& p : r.passes) out.push_back(p.name);
  return out;
}
const render::PrunedPass* find_pruned(const render::FrameResult& r, const std::string& name) {
  for (const auto& p : r.pruned)
    if (p.name == name) return &p;
  return nullptr;
}

}  // namespace

TEST(Pruning, StaticSceneLeavesOutProxyUpdateOnNullBackend) {
  Ran ran;
  TinyTechnique t(&ran);
  render::ParamSet params = render::default_params(t);
  render::NullBackend null;
  const scene::Scene sc = softgi::testing::make_plane_sphere_scene(32, 24);
  render::RenderRequest req;
  const render::FrameResult r = null.render(t, sc, params, req);
  EXPECT_EQ(null.executed, (std::vector<std::string>{"gbuffer", "shadow", "compose"}));
  EXPECT_EQ(names(r), null.executed) << "the frame record lists exactly the executed passes";
  const render::PrunedPass* p = find_pruned(r, "proxy_update");
  ASSERT_NE(p, nullptr);
  EXPECT_NE(p->reason.find(render::kMovingObjects), std::string::npos) << p->reason;
  p = find_pruned(r, "indirect");
  ASSERT_NE(p, nullptr);
  EXPECT_NE(p->reason.find(render::kReradiatingProxies), std::string::npos) << p->reason;
  EXPECT_EQ(ran.proxy_update + ran.shadow + ran.indirect, 0) << "the null backend runs no pass body";
}

TEST(Pruning, AnimatedSceneWithProxiesRunsEverything) {
  Ran ran;
  TinyTechnique t(&ran);
  render::NullBackend null;
  const scene::Scene sc = softgi::testing::with_proxies(softgi::testing::animated(softgi::testing::make_plane_sphere_scene(32, 24)));
  render::RenderRequest req;
  req.time = 0.5;
  const render::FrameResult r = null.render(t, sc, render::default_params(t), req);
  EXPECT_EQ(null.executed, (std::vector<std::string>{"gbuffer", "proxy_update", "shadow", "indirect", "compose"}));
  EXPECT_TRUE(r.pruned.empty());
}

TEST(Pruning, CpuBackendRunsOnlyTheNeededPassBodies) {
  Ran ran;
  TinyTechnique t(&ran);
  render::ParamSet params = render::default_params(t);
  params.set("gain", "2");
  backends::CpuBackend cpu;
  const scene::Scene sc = softgi::testing::make_plane_sphere_scene(32, 24);
  render::RenderRequest req;
  const render::FrameResult r = cpu.render(t, sc, params, req);
  EXPECT_EQ(names(r), (std::vector<std::string>{"gbuffer", "shadow", "compose"}));
  EXPECT_EQ(ran.proxy_update, 0);
  EXPECT_EQ(ran.indirect, 0);
  EXPECT_EQ(ran.shadow, 1);
  ASSERT_EQ(r.passes.size(), 3u);
  EXPECT_EQ(r.passes[0].counters.at("rays"), 32.0 * 24.0);
  EXPECT_GT(r.passes[0].bytes, 0u);
  EXPECT_EQ(r.passes[1].counters.at("receivers"), 32.0 * 24.0);
  // The frame's time covers its passes' (each timed inside it).
  double passes = 0.0;
  for (const auto& p : r.passes) passes += p.wall_seconds;
  EXPECT_GT(passes, 0.0);
  EXPECT_GE(r.total_seconds, passes);
  EXPECT_GT(r.peak_rss_bytes, 0u);

  // With motion and proxies, the same technique runs all five bodies once.
  Ran ran2;
  TinyTechnique t2(&ran2);
  const render::FrameResult r2 = cpu.render(t2, softgi::testing::with_proxies(softgi::testing::animated(sc)), params, req);
  EXPECT_EQ(names(r2), (std::vector<std::string>{"gbuffer", "proxy_update", "shadow", "indirect", "compose"}));
  EXPECT_EQ(ran2.proxy_update, 1);
  EXPECT_EQ(ran2.indirect, 1);
}
