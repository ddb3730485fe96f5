// image_splat's binning as a compute pass (shaders/image_splat/bin_proxies.comp) against the host's
// bin_proxies (paper 000 section 4.1): the same lists, in the same order, for random tile boxes and
// spheres, spheres placed a rounding away from the boxes, infinite spheres of influence, and long
// proxy lists binned in chunks under a tight loop limit; whole frames binned on the device give the
// host-binned frames' bits.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "../../techniques/image_splat/image_splat_internal.hpp"
#include "../../techniques/image_splat/image_splat_vulkan_binning.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
namespace is = softgi::techniques::image_splat;

namespace {

constexpr const char* kBinsResource = "test.bins";

struct Flat {
  std::shared_ptr<techniques::common::BlockerList> shadow;
  std::shared_ptr<is::ProxyList> indirect;
};

// Random tile boxes (some flat, one a point) and spheres around them; `near` of the spheres are put
// a float rounding inside or outside a box's face, edge or corner at their influence radius, where
// sphere_meets_box's decision turns on the last bit of the squared distance.
void random_case(std::mt19937& rng, int tiles, int proxies, int near, double alpha, is::ReceiverBuffer& r, Flat& f) {
  std::uniform_real_distribution<float> u(-4.0f, 4.0f), ext(0.0f, 1.5f), rad(0.02f, 0.6f), w(0.1f, 1.0f);
  r.tiles.clear();
  for (int t = 0; t < tiles; ++t) {
    is::ReceiverTile tile;
    tile.lo = glm::vec3(u(rng), u(rng), u(rng));
    glm::vec3 e(ext(rng), ext(rng), ext(rng));
    if (t % 7 == 3) e.y = 0.0f;  // flat
    if (t == 5) e = glm::vec3(0.0f);  // a point
    tile.hi = tile.lo + e;
    r.tiles.push_back(tile);
  }
  f.shadow = std::make_shared<techniques::common::BlockerList>();
  f.shadow->order = 4;
  f.indirect = std::make_shared<is::ProxyList>();
  for (int p = 0; p < proxies; ++p) {
    float radius = rad(rng);
    glm::vec3 c(u(rng), u(rng), u(rng));
    if (p < near) {
      // A point of a tile's box (on a face, an edge or a corner), then outward by the influence radius
      // along an axis or a diagonal, nudged by a few ulps either way.
      const is::ReceiverTile& tile = r.tiles[static_cast<std::size_t>(p) % r.tiles.size()];
      const float R = is::influence_radius(radius, alpha);
      glm::vec3 dir(0.0f);
      const int kind = p % 3;
      if (kind == 0) dir[p % 3 == 0 ? (p / 3) % 3 : 0] = (p & 8) ? 1.0f : -1.0f;
      else if (kind == 1) dir = glm::normalize(glm::vec3((p & 16) ? 1.0f : -1.0f, 1.0f, 0.0f));
      else dir = glm::normalize(glm::vec3(1.0f, (p & 32) ? 1.0f : -1.0f, -1.0f));
      glm::vec3 corner;
      for (int k = 0; k < 3; ++k) corner[k] = dir[k] > 0.0f ? tile.hi[k] : dir[k] < 0.0f ? tile.lo[k] : 0.5f * (tile.lo[k] + tile.hi[k]);
      c = corner + R * dir;
      const int ulps = static_cast<int>(p % 5) - 2;
      for (int k = 0; k < 3; ++k)
        for (int s = 0; s < std::abs(ulps); ++s) c[k] = std::nextafter(c[k], ulps > 0 ? 1e30f : -1e30f);
    }
    const float wt[4] = {w(rng), w(rng), w(rng), w(rng)};
    f.shadow->push(c, radius, wt);
    f.indirect->push(c, radius, glm::vec3(w(rng), w(rng), w(rng)));
  }
}

// The host copy of the device lists (read back through the entry indices) against bin_proxies.
void expect_same_lists(const is::ProxyBins& host, const is::ProxyBins& dev, const is::BinCounts& counts) {
  ASSERT_EQ(host.shadow.size(), dev.shadow.size());
  ASSERT_EQ(host.indirect.size(), dev.indirect.size());
  ASSERT_EQ(counts.shadow_counts.size(), host.shadow.size());
  for (std::size_t t = 0; t < host.shadow.size(); ++t) {
    SCOPED_TRACE("tile " + std::to_string(t));
    const auto &a = host.shadow[t], &b = dev.shadow[t];
    EXPECT_EQ(counts.shadow_counts[t], a.size());
    EXPECT_EQ(a.cx, b.cx);
    EXPECT_EQ(a.cy, b.cy);
    EXPECT_EQ(a.cz, b.cz);
    EXPECT_EQ(a.r, b.r);
    EXPECT_EQ(a.w, b.w);
  }
  for (std::size_t t = 0; t < host.indirect.size(); ++t) {
    SCOPED_TRACE("indirect tile " + std::to_string(t));
    const auto &a = host.indirect[t], &b = dev.indirect[t];
    EXPECT_EQ(counts.indirect_counts[t], a.size());
    EXPECT_EQ(a.cx, b.cx);
    EXPECT_EQ(a.r, b.r);
    ASSERT_EQ(a.albedo.size(), b.albedo.size());
    for (std::size_t j = 0; j < a.albedo.size(); ++j) EXPECT_EQ(a.albedo[j], b.albedo[j]);
  }
  EXPECT_EQ(host.pairs_tested, dev.pairs_tested);
  EXPECT_EQ(host.shadow_tile_pairs, dev.shadow_tile_pairs);
  EXPECT_EQ(host.indirect_tile_pairs, dev.indirect_tile_pairs);
}

class ImageSplatBinning : public softgi::testing::ValidatedTest {};

const render::PassRecord* find_pass(const render::FrameResult& f, const std::string& name) {
  for (const auto& p : f.passes)
    if (p.name == name) return &p;
  return nullptr;
}

is::BinCounts bin_on(backends::vulkan::Context* c, const is::ReceiverBuffer& r, const Flat& f, double as, double ai,
                     std::shared_ptr<const is::ProxyBins>& host_copy) {
  static const scene::Scene sc = scene::make_builtin("spheres");
  static const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  static auto tech = is::create();
  const render::ParamSet params = render::default_params(*tech);
  render::FrameResult result;
  render::FrameContext fc(sc, posed, params, 4, 4, result, c);
  result.passes.push_back(render::PassRecord{"bin_proxies"});
  const is::BinCounts counts = is::vulkan_bin_proxies(fc, r, f.shadow, as, f.indirect, ai, kBinsResource);
  EXPECT_NE(fc.device_copy<std::shared_ptr<const is::DeviceBins>>(kBinsResource), nullptr);
  host_copy = fc.get<std::shared_ptr<const is::ProxyBins>>(kBinsResource);
  return counts;
}

TEST_F(ImageSplatBinning, DeviceListsAreTheHostListsForRandomBoxesAndSpheres) {
  std::mt19937 rng(5);
  backends::vulkan::ContextOptions o;
  o.validation = 1;
  // Budget 1000 iterations (loop_budget halves a limit this small): 166 proxies per dispatch, so
  // 1500 proxies take 10 chunks whose counts carry over.
  o.loop_iteration_limit = 2000;
  auto tight = std::make_shared<backends::vulkan::Context>(o);
  const auto tight_log = tight->validation_log();
  struct Case {
    int tiles, proxies, near;
    double alpha_shadow, alpha_indirect;
  };
  std::size_t inside_near = 0, outside_near = 0;
  for (const Case& k : {Case{37, 300, 150, 0.1, 0.05}, Case{9, 1500, 600, 0.25, 0.0}, Case{1, 0, 0, 0.1, 0.1}, Case{0, 10, 0, 0.1, 0.1},
                        Case{70, 64, 64, 1.0, 0.5}}) {
    SCOPED_TRACE(std::to_string(k.tiles) + " tiles, " + std::to_string(k.proxies) + " proxies");
    is::ReceiverBuffer r;
    Flat f;
    random_case(rng, k.tiles, k.proxies, k.near, k.alpha_shadow, r, f);
    const is::ProxyBins host = is::bin_proxies(r, *f.shadow, k.alpha_shadow, f.indirect.get(), k.alpha_indirect);
    for (int p = 0; p < k.near; ++p) {
      const is::ReceiverTile& tile = r.tiles[static_cast<std::size_t>(p) % r.tiles.size()];
      const glm::vec3 c(f.shadow->cx[p], f.shadow->cy[p], f.shadow->cz[p]);
      (is::sphere_meets_box(c, is::influence_radius(f.shadow->r[p], k.alpha_shadow), tile.lo, tile.hi) ? inside_near : outside_near)++;
    }
    for (backends::vulkan::Context* c : {ctx_.get(), tight.get()}) {
      std::shared_ptr<const is::ProxyBins> dev;
      const is::BinCounts counts = bin_on(c, r, f, k.alpha_shadow, k.alpha_indirect, dev);
      expect_same_lists(host, *dev, counts);
    }
  }
  // The nudged spheres land on both sides of the boundary.
  std::printf("[binning] near-boundary spheres: %zu reach their box, %zu do not\n", inside_near, outside_near);
  EXPECT_GT(inside_near, 100u);
  EXPECT_GT(outside_near, 100u);
  tight.reset();
  EXPECT_EQ(tight_log->problems(), 0u) << tight_log->summary();
}

// Frames of image_splat on Vulkan with binning = device against binning = host: every pass reads
// the same lists, so the images are the same bits; the device-binned accumulation uploads no lists.
TEST_F(ImageSplatBinning, DeviceBinnedFramesAreTheHostBinnedFrames) {
  backends::register_cpu_backend();
  backends::VulkanBackend vk(ctx_);
  auto tech = is::create();
  for (const char* name : {"spheres", "character", "crowd"}) {
    SCOPED_TRACE(name);
    const scene::Scene sc = scene::make_builtin(name);
    render::ParamSet host = render::default_params(*tech), dev = host;
    dev.set("binning", "device");
    render::RenderRequest req;
    req.width = 64;
    req.height = 48;
    req.time = 0.3;
    const render::FrameResult a = vk.render(*tech, sc, host, req);
    const render::FrameResult b = vk.render(*tech, sc, dev, req);
    ASSERT_EQ(a.final_image.rgb.size(), b.final_image.rgb.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < a.final_image.rgb.size(); ++i) differ += a.final_image.rgb[i] != b.final_image.rgb[i];
    EXPECT_EQ(differ, 0u);
    const render::PassRecord* bin_a = find_pass(a, "bin_proxies");
    const render::PassRecord* bin_b = find_pass(b, "bin_proxies");
    ASSERT_TRUE(bin_a && bin_b);
    for (const char* c : {"shadow_tile_pairs", "indirect_tile_pairs", "shadow_proxies_per_tile_max", "pairs_tested", "shadow_receiver_pairs"})
      EXPECT_EQ(bin_a->counters.at(c), bin_b->counters.at(c)) << c;
    EXPECT_GT(bin_b->counters.at("shadow_tile_pairs"), 0.0);
    EXPECT_EQ(bin_a->counters.count("kernel_gpu_seconds"), 0u) << "host binning";
    EXPECT_EQ(bin_b->counters.count("kernel_gpu_seconds"), 1u) << "device binning";
    const render::PassRecord* acc_a = find_pass(a, "accumulate_log");
    const render::PassRecord* acc_b = find_pass(b, "accumulate_log");
    ASSERT_TRUE(acc_a && acc_b);
    EXPECT_EQ(acc_a->counters.at("pairs"), acc_b->counters.at("pairs"));
  }
}

}  // namespace
